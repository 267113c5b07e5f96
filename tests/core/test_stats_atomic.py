"""`--stats` JSON is written like every other output: a partial file, then a rename."""

from __future__ import annotations

import errno
import json

import pytest

import geoterrain.core.atomicfiles as atomicfiles
from geoterrain.core.atomicfiles import write_atomic
from geoterrain.exceptions import WriteError

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


class _DiskFull:
    """A file whose second write fails with ENOSPC after the first went through."""

    def __init__(self, path, mode):
        self.fh = open(path, mode)  # noqa: SIM115
        self.n = 0

    def write(self, data):
        self.n += 1
        if self.n > 1 or len(data) > 8:
            self.fh.write(data[: len(data) // 2])
            self.fh.flush()
            raise OSError(errno.ENOSPC, "No space left on device")
        return self.fh.write(data)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.fh.close()


def test_a_failed_write_leaves_no_half_written_file(tmp_path, monkeypatch):
    out = tmp_path / "stats.json"
    monkeypatch.setattr(atomicfiles, "open", _DiskFull, raising=False)
    with pytest.raises(WriteError, match="No space left"):
        write_atomic(out, json.dumps({"triangles": list(range(100))}))
    assert list(tmp_path.iterdir()) == []  # neither the file nor its partial


def test_a_failed_publish_keeps_the_old_file(tmp_path, monkeypatch):
    out = tmp_path / "stats.json"
    out.write_text('{"old": 1}')

    def fail(*a, **k):
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(atomicfiles, "publish", fail)
    with pytest.raises(WriteError):
        write_atomic(out, '{"new": 2}')
    assert out.read_text() == '{"old": 1}'
    assert [p.name for p in tmp_path.iterdir()] == ["stats.json"]


def test_render_stats_in_a_missing_folder_is_one_line(tmp_path):
    import geoterrain
    from geoterrain.ingest.synth import generate, write_geotiff
    from tests.test_cli import assert_one_line_error, run

    dem = write_geotiff(tmp_path / "d.tif", generate("fbm", 33, seed=1))
    s = geoterrain.preprocess(dem, tmp_path / "d.geoterrain", tile_size=16)
    res = run("-q", "render", s, "-o", tmp_path / "v.png", "--size", "64x48",
              "--stats", tmp_path / "no" / "s.json")
    assert_one_line_error(res, 2)  # refused before any work: nothing rendered
    assert not (tmp_path / "no").exists() and not (tmp_path / "v.png").exists()
    res = run("-q", "render", s, "-o", tmp_path / "w.png", "--size", "64x48",
              "--stats", tmp_path / "s.json")
    assert res.exit_code == 0, res.output
    assert json.loads((tmp_path / "s.json").read_text())["triangles"] > 0
    assert not [p for p in tmp_path.iterdir() if ".partial" in p.name]
