"""A fuzzer over every command's options: whatever a user types, the command succeeds or
fails in one line (at most one more with a hint) with exit 1 or 2, never an internal
error, a traceback or a hang, and a store it writes is one every reader accepts.

The options are read from the commands themselves (``geoterrain.cli.main.COMMANDS``), so a
new command or option is fuzzed without editing this file. Each value is either a valid
one of the option's type (kept small: a 33² DEM, pictures of 64×48, a frame or two) or a
hostile one: NaN, ±inf, 0, −1, 1e308, 1e-300, an empty or over-long word, control
characters, a name that is not UTF-8; paths are the inputs, a missing folder, a folder, a
FIFO, a symbolic link, an existing file or the command's own input. A third of the cases
are calm (valid-looking values only, a new output), so that whole commands run and their
outputs are checked. What C libraries print on the process's stderr counts too. ``view`` opens a
window and ``serve`` serves until Ctrl-C: both are left out.

The default suite runs a short sample; the seeded 2 000-case run is marked slow::

    pytest -q -m slow tests/test_cli_fuzz.py
"""

from __future__ import annotations

import os
import shutil
import signal
import tempfile
from pathlib import Path

import click
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, Phase, given, seed, settings
from hypothesis import strategies as st

pytestmark = pytest.mark.fast

SKIP = {"view", "serve"}  # interactive: a window, or a server running until Ctrl-C
CASE_SECONDS = 60  # a case running longer is a hang

HOSTILE_NUMBERS = ["nan", "inf", "-inf", "0", "-1", "1e308", "-1e308", "1e-300", "", "abc",
                   "1,2", " 7 ", "0x10", "1e", "--", "9" * 400]
HOSTILE_WORDS = ["", " ", "nan", "a\x1b[31mred", "x" * 5000, "\udcff\udcfe", "1,2,3,4",
                 "nan,nan", "inf,0", "0,0", "-1,-1", "1e308,1e308", "../../x", "%s%n",
                 "dask:tcp://127.0.0.1:1", "0x0", "100000x100000", "16x16"]
# valid words for options whose type is a plain string or a callback
WORDS = {
    "cmap": ["terrain", "viridis", "no-such-map"],
    "clim": ["0,100", "100,0", "0,0"],
    "sun": ["315,45", "0,90", "400,50", "315"],
    "memory_limit": ["64M", "2G", "1T", "1k"],
    "scheduler": ["sync", "threads", "threads:2", "processes:1", "bogus"],
    "tile": ["0/0/0", "12/3000/1500", "30/0/0", "a/b/c"],
    "strategies": ["rtin", "rtin,chunked", "nope"],
    "pixel_errors": ["1", "1,2", "0"],
    "peer_errors": ["1", "0.5,1"],
    "crs": ["EPSG:32633", "EPSG:4326", "EPSG:999999", "+proj=nope"],
    "title": ["Fuji", "a\tb"],
    "look_from": ["0,-500,300", "0,0,0", "1e9,0,0"],
    "look_at": ["0,0,0", "160,160,0"],
    "origin": ["500000,5000000", "0,0", "1e20,0"],
    "size": ["64x48", "16x16", "15x15"],
    "old_max_error": ["1"],
}
# valid integers kept small: work grows with them
SMALL_INTS = {"size": (2, 65), "synthetic": (3, 65), "n_views": (1, 2), "orbit": (1, 2),
              "frames_between": (0, 1), "texture_size": (2, 128), "tile_size": (2, 64),
              "max_zoom": (0, 22), "min_zoom": (0, 22), "level": (0, 8), "band": (1, 4)}


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """A 33² DEM, its store and a text file: copied into every case's folder."""
    import geoterrain
    from geoterrain.ingest.synth import generate, write_geotiff

    d = tmp_path_factory.mktemp("fuzz-inputs")
    dem = write_geotiff(d / "dem.tif", generate("fbm", 33, seed=3))
    geoterrain.preprocess(dem, d / "s.geoterrain", tile_size=16)
    (d / "notes.txt").write_text("not a raster\n")
    (d / "cams.json").write_text('[{"look_from": [0, -500, 300], "look_at": [0, 0, 0]}]')
    return d


def _case_dir(base: Path, inputs: Path) -> Path:
    d = Path(tempfile.mkdtemp(dir=base))
    for f in inputs.iterdir():
        shutil.copy(f, d / f.name)
    (d / "exists.png").write_bytes(b"keep me")
    (d / "folder").mkdir()
    os.mkfifo(d / "fifo")
    os.symlink(d / "exists.png", d / "link")
    return d


def _paths(d: Path):
    outs = [d / f"out{ext}" for ext in (".geoterrain", ".ply", ".vtp", ".glb", ".obj",
                                        ".stl", ".png", ".gif", ".json", ".tif", ".csv", "")]
    odd = [d / "exists.png", d / "folder", d / "fifo", d / "link", d / "missing" / "x.png",
           d / ("n" * 300 + ".png"), os.fsdecode(os.fsencode(str(d)) + b"/\xff.png"),
           d / "s.geoterrain", d / "dem.tif", d / "notes.txt", d / "cams.json", d / "nope"]
    return st.sampled_from([str(p) for p in outs + odd])


def _number(p: click.Parameter):
    t = p.type
    lo, hi = getattr(t, "lo", None), getattr(t, "hi", None)
    valid = st.floats(max(lo, -1e4) if lo is not None else -1e4,
                      min(hi, 1e4) if hi is not None else 1e4,
                      allow_nan=False).map(repr)
    return st.one_of(valid, st.sampled_from(HOSTILE_NUMBERS))


# a calm case's output for each command: a new file of a kind it writes
CALM_OUTPUTS = {"preprocess": "out.geoterrain", "mesh": "out.ply", "export": "out.glb",
                "export-raster": "out.tif", "tiles": "tiles", "render": "out.png",
                "synth": "out.tif", "bench": "out.csv", "query": "out.csv",
                "profile": "out.csv", "viewshed": "out.tif", "contours": "out.gpkg"}


def _value(p: click.Parameter, d: Path, calm: bool = False, command: str = ""):
    """A strategy of command-line words for ``p``; ``calm``: only valid-looking ones (so
    that whole commands succeed and their outputs are checked)."""
    t = p.type
    if isinstance(t, click.Choice):
        return st.sampled_from(list(t.choices) if calm else [*t.choices, "bogus", ""])
    if isinstance(t, click.Path):
        if calm and p.name in ("output", "out"):
            return st.just(str(d / CALM_OUTPUTS.get(command, "out.png")))
        return _paths(d)
    if isinstance(t, click.types.IntParamType):  # IntRange included
        lo, hi = SMALL_INTS.get(p.name, (0, 3))
        if calm:
            return st.integers(lo, hi).map(str)
        return st.one_of(st.integers(lo, hi).map(str),
                         st.sampled_from(["-1", "0", "99999999999", "1.5", "nan", ""]))
    if type(t).__name__ == "Number":
        if calm:
            lo, hi = max(t.lo, -1e4), min(t.hi, 1e4)
            return st.floats(lo, hi, exclude_min=t.lo_open, exclude_max=t.hi_open,
                             allow_nan=False).map(repr)
        return _number(p)
    if calm:
        return st.sampled_from(WORDS.get(p.name, ["x"])[:1])
    return st.one_of(st.sampled_from(WORDS.get(p.name, ["x"])),
                     st.sampled_from(HOSTILE_WORDS))


@st.composite
def command_lines(draw, d: Path):
    """(command, argv) for one case: every option present or not, valid or hostile."""
    from geoterrain.cli.main import COMMANDS, cli

    name = draw(st.sampled_from(sorted(set(COMMANDS) - SKIP)))
    calm = draw(st.integers(0, 2)) == 0  # a third of the cases: valid-looking values only
    cmd = cli.get_command(None, name)
    argv = ["-q", name]
    for p in cmd.params:
        if isinstance(p, click.Argument):
            good = {"dem": d / "dem.tif", "store": d / "s.geoterrain",
                    "stores": d / "s.geoterrain", "sources": d / "s.geoterrain",
                    "source": d / "s.geoterrain"}.get(p.name)
            if good is not None:
                argv.append(draw(st.one_of(st.just(str(good)), _paths(d))) if not calm
                            and draw(st.booleans()) else str(good))
            else:
                argv.append(draw(_value(p, d, calm, name)))
            continue
        if not draw(st.integers(0, 3)) == 0 and not p.required:  # each option: 1 in 4
            continue
        opt = p.opts[-1]
        if p.is_flag:
            argv.append(opt if not p.secondary_opts or draw(st.booleans())
                        else p.secondary_opts[0])
        else:
            argv += [opt, draw(_value(p, d, calm, name))]
    if name == "bench" and "--cache-dir" not in argv:
        argv += ["--cache-dir", str(d / "cache")]  # not the user's cache folder
    if name == "bench" and "--globe" in argv:  # the flyover: a few small frames (the
        argv += ["--flight-fps", "0.5", "--size", "64x48"]  # last value of an option wins)
    return name, argv


EXITS: dict = {}  # (command, exit code) → cases, for the slow run's summary


class Hang(BaseException):
    """A case ran past CASE_SECONDS (BaseException: no handler in the CLI catches it)."""


def _alarm(signum, frame):
    raise Hang


def problems_of(argv: list[str], d: Path) -> list[str]:
    """What is wrong with running ``argv`` (empty: nothing)."""
    from geoterrain.cli.main import cli

    before = {n: os.lstat(d / n).st_mode for n in ("folder", "fifo", "link")}
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(CASE_SECONDS)
    # what C libraries (GDAL, PROJ, VTK) print on the process's stderr, which Click's runner
    # does not see: a user does
    c_err, saved = tempfile.TemporaryFile(), os.dup(2)
    os.dup2(c_err.fileno(), 2)
    try:
        res = CliRunner().invoke(cli, argv, catch_exceptions=True)
    except Hang:
        return ["hang"]
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
        os.dup2(saved, 2)
        os.close(saved)
    c_err.seek(0)
    c_lines = c_err.read().decode("utf-8", "replace").splitlines()
    c_err.close()
    out = []
    if isinstance(res.exception, Hang):
        return ["hang"]
    EXITS[argv[1], res.exit_code] = EXITS.get((argv[1], res.exit_code), 0) + 1
    if res.exception is not None and not isinstance(res.exception, SystemExit):
        out.append(f"exception {type(res.exception).__name__}: {res.exception}")
    err = [ln for ln in c_lines + res.stderr.splitlines() if ln.strip()]
    if c_lines and res.exit_code == 0:
        out.append(f"library output on stderr: {c_lines[:2]}")
    if "internal error" in res.stderr:
        out.append("internal error")
    if "Traceback" in res.output:
        out.append("traceback")
    if res.exit_code not in (0, 1, 2):
        out.append(f"exit {res.exit_code}")
    if res.exit_code != 0:
        errors = [ln for ln in err if not ln.startswith("warning:")]
        if not errors or not errors[0].startswith("Error:") or len(err) > 2:
            out.append(f"not one line: {err[:4]}")
    for n, mode in before.items():  # a folder, a FIFO and a link stay as they were
        if os.lstat(d / n).st_mode != mode:
            out.append(f"{n} was replaced")
    if (d / "exists.png").read_bytes() != b"keep me" and "--overwrite" not in argv:
        out.append("exists.png was overwritten without --overwrite")
    if res.exit_code == 0 and argv[1] == "preprocess":
        store = argv[argv.index("--output") + 1] if "--output" in argv else None
        if store is not None and os.path.isfile(store):
            info = CliRunner().invoke(cli, ["info", store])
            if info.exit_code != 0:
                out.append(f"a store no reader accepts: {info.stderr.strip()}")
    return out


def _fuzz(tmp_path, inputs, n: int, survey: list | None):
    base = tmp_path / "cases"
    base.mkdir()

    @settings(max_examples=n, deadline=None, database=None,
              phases=[Phase.generate] if survey is not None else list(Phase),
              suppress_health_check=list(HealthCheck))
    @given(data=st.data())
    def case(data):
        d = _case_dir(base, inputs)
        try:
            name, argv = data.draw(command_lines(d))
            found = problems_of(argv, d)
            if survey is not None:
                survey.append((argv, found))
            else:
                assert not found, (argv, found)
        finally:
            for p in d.iterdir():  # the FIFO and the link: removed, never opened
                if p.is_dir() and not p.is_symlink():
                    shutil.rmtree(p, ignore_errors=True)
                else:
                    p.unlink()
            d.rmdir()

    return case


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_cli_fuzz_short(tmp_path, inputs):
    _fuzz(tmp_path, inputs, 25, None)()


@pytest.mark.slow
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_cli_fuzz_2000(tmp_path, inputs, capsys):
    """The seeded 2 000-case run: every problem is collected, counted and printed."""
    survey: list = []
    seed(49)(_fuzz(tmp_path, inputs, 2000, survey))()
    bad = [(argv, found) for argv, found in survey if found]
    with capsys.disabled():
        kinds: dict = {}
        for _, found in bad:
            for f in found:
                k = f.split(":")[0]
                kinds[k] = kinds.get(k, 0) + 1
        print(f"\nCLI fuzzer: {len(survey)} cases, {len(bad)} with problems {kinds}")
        print("  exit codes by command:", dict(sorted(EXITS.items())))
        for argv, found in bad[:30]:
            print("  ", found, argv)
    assert len(survey) >= 2000 and not bad

