"""The first run: which compiled kernels are not cached yet, and a progress bar while
they compile.

geoterrain's kernels are numba functions compiled on first use and cached on disk
(``cache=True``: beside each module, in ``__pycache__``, or under ``NUMBA_CACHE_DIR``).
A fresh install therefore spends its first minute or so compiling. :func:`cold_kernels` finds
the kernels of some stage folders whose cache is missing, from the source files and the
cache folder alone (nothing is imported or compiled: a few tens of milliseconds), and
:class:`CompileWatch` counts the compilations as numba reports them
(``numba.core.event``), so the command line can say "compiling kernels (first run only,
about N s)" and show a bar.

Examples
--------
>>> cold = cold_kernels(["geoterrain.rendering"])
>>> isinstance(cold, list)
True
>>> estimate_seconds(0)
0
"""

from __future__ import annotations

import hashlib
import os
import re
import sys
from collections.abc import Callable, Iterable
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1]
# seconds a counted kernel takes on a 2-core VM: the demo's commands on an empty cache,
# 2026-12-07 (a process each, quiet), took 28 s (preprocess, 100 counted), 15 s (mesh,
# 100), 19 s (render, 120), 7.5 s (export, 90): 70 s for 410 counted, 0.08-0.28 s each
# (a count includes kernels a command never calls; the whole package's ≈ 250 distinct
# kernels, nearly all of which the demo compiles, ≈ 0.28 s each); the estimate is the
# count × this
SECONDS_PER_KERNEL = 0.25
# a cached kernel's decorator (a parallel kernel's: core/threads.py; its serial twin
# compiles in a fork() child only); an inlined one ("always") has no cache of its own
_DECORATOR = re.compile(r"^@(?:(?:numba\.)?njit|parallel_kernel)\((?=[^)]*cache=True)"
                        r"(?![^)]*inline=\"always\")")
_DEF = re.compile(r"^def (\w+)\(")


def _tag() -> str:
    return f"py{sys.version_info.major}{sys.version_info.minor}"


def _cache_dirs(source: Path) -> list[Path]:
    """Where numba keeps ``source``'s cache: under NUMBA_CACHE_DIR when it is set (numba's
    folder name: the source folder's name and its path's SHA-1), else beside it."""
    user = os.environ.get("NUMBA_CACHE_DIR")
    if user:
        sub = str(source.parent.resolve())
        return [Path(user) / f"{Path(sub).name}_{hashlib.sha1(sub.encode()).hexdigest()}"]
    return [source.parent / "__pycache__"]


def kernels(source: Path) -> list[tuple[str, int]]:
    """The cached compiled kernels a module defines: (name, first line of its decorator),
    numba's key for its cache files.

    Examples
    --------
    >>> ks = kernels(PACKAGE / "rendering" / "antialias.py")
    >>> all(isinstance(n, str) and line > 0 for n, line in ks) and len(ks) > 0
    True
    """
    lines = source.read_text().splitlines()
    out = []
    for i, ln in enumerate(lines):
        if not _DECORATOR.match(ln):
            continue
        if i > 0 and lines[i - 1].startswith("@"):
            continue  # not the first decorator: counted from the first
        for ln2 in lines[i:i + 8]:
            m = _DEF.match(ln2)
            if m:
                out.append((m.group(1), i + 1))
                break
    return out


def cold_kernels(modules: Iterable[str]) -> list[str]:
    """The kernels under the given module prefixes (``"geoterrain.lod"``, …) whose cache
    index is missing: "module.function" names.

    Examples
    --------
    >>> all(name.startswith("geoterrain.") for name in cold_kernels(["geoterrain.codec"]))
    True
    """
    prefixes = tuple(modules)
    out = []
    for f in sorted(PACKAGE.rglob("*.py")):
        mod = ".".join(("geoterrain", *f.relative_to(PACKAGE).with_suffix("").parts))
        if not mod.startswith(prefixes):
            continue
        text = f.read_text()
        if "cache=True" not in text:
            continue
        present = set()
        for d in _cache_dirs(f):
            if d.is_dir():
                present |= {p.name for p in d.iterdir() if p.suffix == ".nbi"}
        for name, line in kernels(f):
            if f"{f.stem}.{name}-{line}.{_tag()}.nbi" not in present:
                out.append(f"{mod}.{name}")
    return out


def estimate_seconds(n: int) -> int:
    """About how long ``n`` kernels take to compile (whole seconds, at least 1 when any;
    a multiple of 10 above a minute)."""
    s = n * SECONDS_PER_KERNEL
    if s >= 60:
        return int(round(s / 10.0) * 10)
    return max(int(round(s)), 1) if n else 0


class CompileWatch:
    """Counts numba's compilations while it is active (a context manager), calls
    ``started()`` when the first begins (a kernel loaded from the cache is no compilation)
    and ``progress(done)`` after each; ``depth`` is how many are under way now.

    Examples
    --------
    >>> seen = []
    >>> with CompileWatch(seen.append) as w:
    ...     pass
    >>> w.done
    0
    """

    def __init__(self, progress: Callable[[int], None] | None = None,
                 started: Callable[[], None] | None = None):
        self.progress, self.started = progress, started
        self.done = 0
        self.depth = 0  # compilations under way now (a kernel compiles those it calls)
        self._listener = None

    def __enter__(self) -> CompileWatch:
        from numba.core import event

        watch = self

        class _Listener(event.Listener):
            def on_start(self, ev) -> None:
                watch.depth += 1
                if watch.started is not None:  # the first compilation: say so once
                    started, watch.started = watch.started, None
                    started()

            def on_end(self, ev) -> None:
                watch.depth -= 1
                watch.done += 1
                if watch.progress is not None:
                    watch.progress(watch.done)

        self._listener = _Listener()
        event.register("numba:compile", self._listener)
        return self

    def __exit__(self, *exc) -> None:
        from numba.core import event

        if self._listener is not None:
            event.unregister("numba:compile", self._listener)
            self._listener = None
