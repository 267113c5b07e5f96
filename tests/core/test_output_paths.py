"""What a command may replace (geoterrain/core/paths.py): a regular file, with --overwrite,
and nothing else: a device, a FIFO, a symbolic link or a directory given as any command's
output is refused in one line and left as it was; --stats and every sidecar follow
--overwrite; an output that is one of the command's inputs is refused."""

from __future__ import annotations

import os
import stat

import pytest

import geoterrain
from geoterrain.core.paths import check_output
from geoterrain.exceptions import UsageError
from geoterrain.ingest.synth import generate, write_geotiff
from tests.test_cli import assert_one_line_error, run

pytestmark = pytest.mark.fast


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    d = tmp_path_factory.mktemp("paths")
    dem = write_geotiff(d / "dem.tif", generate("fbm", 33, seed=2))
    return geoterrain.preprocess(dem, d / "s.geoterrain", tile_size=16), dem


def _hostile(folder, kind: str, name: str):
    """Make ``name`` in ``folder`` a ``kind`` thing; (its path, a snapshot of it)."""
    p = folder / name
    if kind == "chardev":
        try:
            os.mknod(p, stat.S_IFCHR | 0o666, os.makedev(1, 3))  # /dev/null's numbers
        except PermissionError:
            pytest.skip("making a character device needs root")
    elif kind == "fifo":
        os.mkfifo(p)
    elif kind == "symlink":  # to a file outside the folder
        outside = folder.parent / f"outside-{folder.name}-{name}"
        outside.write_bytes(b"keep me")
        p.symlink_to(outside)
    elif kind == "directory":
        p.mkdir()
        (p / "inside.txt").write_text("keep me")
    elif kind == "file":
        p.write_bytes(b"keep me")
    return p, _snapshot(p)


def _snapshot(p):
    st = os.lstat(p)
    extra = None
    if stat.S_ISLNK(st.st_mode):
        extra = (os.readlink(p), p.resolve().read_bytes())
    elif stat.S_ISDIR(st.st_mode):
        extra = sorted((q.name, q.read_bytes()) for q in p.iterdir())
    elif stat.S_ISREG(st.st_mode):
        extra = p.read_bytes()
    return st.st_mode, st.st_ino, st.st_rdev, extra


# command line given the store, the DEM and the output; which kind of output it writes
COMMANDS = {
    "preprocess": (lambda s, d, o: ["preprocess", d, "-o", o, "--tile-size", "16"], "file"),
    "mesh": (lambda s, d, o: ["mesh", s, "-o", f"{o}.ply"], "file"),
    "export": (lambda s, d, o: ["export", s, "-o", f"{o}.obj", "--texture-size", "16"],
               "file"),
    "export-raster": (lambda s, d, o: ["export-raster", s, "--what", "slope", "-o",
                                       f"{o}.tif"], "file"),
    "render": (lambda s, d, o: ["render", s, "-o", f"{o}.png", "--size", "64x48"], "file"),
    "render-stats": (lambda s, d, o: ["render", s, "-o", "{fresh}.png", "--size", "64x48",
                                      "--stats", f"{o}.json"], "file"),
    "render-frames": (lambda s, d, o: ["render", s, "-o", o, "--orbit", "2", "--size",
                                       "64x48"], "folder"),
    "tiles": (lambda s, d, o: ["tiles", s, "-o", o, "--max-zoom", "3"], "folder"),
    "synth": (lambda s, d, o: ["synth", "fbm", "--size", "17", "-o", f"{o}.tif"], "file"),
}
# the things an output must never replace: for a folder output a regular file instead of
# a directory
KINDS = ["chardev", "fifo", "symlink", "directory"]


@pytest.mark.parametrize("overwrite", [False, True])
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_hostile_output_is_refused_and_left_as_it_was(store, tmp_path, command, kind,
                                                        overwrite):
    s, dem = store
    make, what = COMMANDS[command]
    if what == "folder" and kind == "directory":
        kind = "file"  # a folder output writes into a directory; a file must stay one
    args = make(s, dem, tmp_path / "out")
    target = args[args.index("--stats") + 1] if "--stats" in args else args[args.index("-o")
                                                                            + 1]
    args = [str(a).replace("{fresh}", str(tmp_path / "fresh")) for a in args]
    target = str(target)
    folder, name = os.path.split(target)
    p, before = _hostile(tmp_path, kind, name)
    res = run("-q", *args, *(["--overwrite"] if overwrite else []))
    assert_one_line_error(res, 2)
    assert _snapshot(p) == before
    # nothing else was written: no output, no partial file
    assert sorted(q.name for q in tmp_path.iterdir()) == [name]


@pytest.mark.parametrize("overwrite", [False, True])
def test_an_output_that_is_an_input_is_refused(store, tmp_path, overwrite):
    s, dem = store
    flag = ["--overwrite"] if overwrite else []
    # a store named like a mesh, meshed onto itself; and reached by a hard link
    alias = tmp_path / "s.ply"
    os.link(s, alias)
    before = alias.read_bytes()
    for out in (alias, tmp_path / "link.ply"):
        if not out.exists():
            os.link(s, out)
        res = run("-q", "mesh", alias, "-o", out, *flag)
        assert_one_line_error(res, 2)
        assert "input" in res.stderr
    assert alias.read_bytes() == before
    res = run("-q", "preprocess", dem, "-o", dem, *flag)
    assert_one_line_error(res, 2)
    # an OBJ's texture sidecar t.png would replace the drape image t.png
    drape = tmp_path / "t.png"
    drape.write_bytes(b"an image")
    res = run("-q", "export", s, "-o", tmp_path / "t.obj", "--drape", drape, *flag)
    assert_one_line_error(res, 2)
    assert drape.read_bytes() == b"an image" and not (tmp_path / "t.obj").exists()


def test_sidecars_and_stats_follow_overwrite(store, tmp_path):
    s, _ = store
    (tmp_path / "m.mtl").write_text("mine")
    res = run("-q", "export", s, "-o", tmp_path / "m.obj", "--texture-size", "16")
    assert_one_line_error(res, 2)
    assert "m.mtl" in res.stderr and not (tmp_path / "m.obj").exists()
    assert (tmp_path / "m.mtl").read_text() == "mine"
    res = run("-q", "export", s, "-o", tmp_path / "m.obj", "--texture-size", "16",
              "--overwrite")
    assert res.exit_code == 0, res.output
    assert (tmp_path / "m.mtl").read_text() != "mine"
    (tmp_path / "keep.json").write_text("{}")
    res = run("-q", "render", s, "-o", tmp_path / "v.png", "--size", "64x48", "--stats",
              tmp_path / "keep.json")
    assert_one_line_error(res, 2)
    assert (tmp_path / "keep.json").read_text() == "{}" and not (tmp_path / "v.png").exists()
    res = run("-q", "render", s, "-o", tmp_path / "v.png", "--size", "64x48", "--stats",
              tmp_path / "v.png")
    assert_one_line_error(res, 2)


def test_publish_refuses_what_appeared_since_the_check(tmp_path):
    """The rule holds at the moment of the rename too (a FIFO made after the check)."""
    from geoterrain.core.atomicfiles import partial_path, publish

    dst = tmp_path / "a.json"
    check_output(dst, overwrite=True)
    tmp = partial_path(dst)
    tmp.write_text("x")
    os.mkfifo(dst)
    with pytest.raises(UsageError, match="FIFO"):
        publish(tmp, dst, overwrite=True)
    assert stat.S_ISFIFO(os.lstat(dst).st_mode) and not tmp.exists()
