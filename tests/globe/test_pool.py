"""The payload pool's slots hold exactly what was put in them (one compiled copy)."""

from __future__ import annotations

import numpy as np
import pytest

from geoterrain.globe import Globe
from geoterrain.globe.payload import make_payload
from geoterrain.globe.pool import PayloadPool

pytestmark = pytest.mark.fast


@pytest.mark.parametrize("normals", [True, False])
def test_a_slot_holds_its_payload_and_leaves_the_others(normals):
    with Globe(model="sphere", base="procedural", node_cells=8, sync=True) as g:
        p = make_payload(g.surface, (3, 2, 1, 2), normals=normals)
        q = make_payload(g.surface, (7, 2, 0, 3), normals=True)
    pp = PayloadPool(vertices=len(p.r), capacity=3, normals=True)
    pp.put(0, q)
    before = [a[0].copy() for a in (pp.centre, pp.rel, pp.normals, pp.elev)]
    pp.put(1, p)
    pairs = [(pp.centre, p.centre), (pp.rel, p.rel), (pp.d, p.d), (pp.r, p.r),
             (pp.rT, p.rT), (pp.elev, p.elevation), (pp.elev_t, p.elevation_t)]
    if normals:
        pairs += [(pp.normals, p.normals), (pp.normals_t, p.normals_t)]
    for slab, a in pairs:
        assert np.array_equal(slab[1], np.asarray(a, slab.dtype).reshape(slab[1].shape))
    assert bool(pp.has_normals[1]) == normals and bool(pp.has_normals[0])
    for b, a in zip(before, (pp.centre, pp.rel, pp.normals, pp.elev), strict=True):
        assert np.array_equal(a[0], b)  # the slot beside it untouched
    assert not pp.rel[2].any()
