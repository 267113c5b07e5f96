"""A still picture of the globe (``select(wait=True)``: what ``render --globe`` draws) is
the converged mesh whatever the payload pool's size: a small pool must not evict the
nodes the view needs (a parent refines only while all four children are ready, so an
evicted culled sibling was requested again on every pass and the mesh never came)."""

from geoterrain.globe import Globe
from geoterrain.globe.pool import PayloadPool


def _still(memory: int):
    g = Globe(model="sphere", base="procedural", node_cells=8, sync=True, memory=memory)
    view = g.camera(10.0, 20.0, 20000.0, 30.0, -25.0, size=(64, 48))
    return g.select(view, 1.0, wait=True)


def test_a_small_pool_gives_the_converged_mesh():
    small = _still(64 * PayloadPool.bytes_per_slot(9 ** 2))  # 64 slots to start with
    large = _still(1 << 30)
    assert small.stats["requested"] == 0 and small.stats["pending"] == 0
    assert small.stats["nodes"] == large.stats["nodes"]
    assert small.stats["triangles"] == large.stats["triangles"]
    assert small.stats["max_depth"] == large.stats["max_depth"]
