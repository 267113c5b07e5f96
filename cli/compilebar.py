"""The first run's compile bar of a command (:class:`CompileBar`), apart from
:mod:`geoterrain.cli.options`: the command line enters it for every command, and a command
whose module needs no shared option (``edit``, ``info``) then imports neither the options
nor the LOD registry they list (20-30 ms of a cold ``geoterrain edit``'s CPU at load 11).

Examples
--------
>>> with CompileBar("edit", quiet=False) as bar:
...     bar.compiling()
False
"""

from __future__ import annotations

import sys

import click

# the stage folders whose compiled kernels each command may compile on its first run
COMPILING = {
    "preprocess": ("geoterrain.core", "geoterrain.ingest", "geoterrain.codec",
                   "geoterrain.bounds", "geoterrain.preprocessing.pipeline",
                   "geoterrain.store"),
    "render": ("geoterrain.core", "geoterrain.codec", "geoterrain.bounds.leafbounds",
               "geoterrain.bounds.normals", "geoterrain.lod", "geoterrain.rendering"),
    "mesh": ("geoterrain.core", "geoterrain.codec", "geoterrain.bounds.leafbounds",
             "geoterrain.lod", "geoterrain.export.meshstream"),
    "export": ("geoterrain.core", "geoterrain.codec", "geoterrain.bounds.leafbounds",
               "geoterrain.bounds.normals", "geoterrain.lod", "geoterrain.rendering.tileshade",
               "geoterrain.rendering.shading"),
    "export-raster": ("geoterrain.core", "geoterrain.codec", "geoterrain.bounds.leafbounds",
                      "geoterrain.bounds.normals", "geoterrain.rendering.shading"),
    "tiles": ("geoterrain.core", "geoterrain.codec", "geoterrain.bounds.leafbounds",
              "geoterrain.export.qmesh", "geoterrain.export.qmeshtin",
              "geoterrain.lod.tinseeded", "geoterrain.lod.tincollapse",
              "geoterrain.lod.tinkernels"),
    "bench": ("geoterrain.core", "geoterrain.codec", "geoterrain.bounds", "geoterrain.lod",
              "geoterrain.testing", "geoterrain.rendering"),
    # by tiles (preprocessing/edit/local*.py), or the preprocess's stages over the whole grid
    "edit": ("geoterrain.core", "geoterrain.ingest", "geoterrain.codec", "geoterrain.bounds",
             "geoterrain.preprocessing", "geoterrain.store"),
}
COMPILING["view"] = COMPILING["render"]


class CompileBar:
    """The first run of a command: when numba starts compiling a kernel the cache did not
    hold, says so (once, with an estimate of the time for the command's uncached kernels)
    and shows a bar of the compilations, on stderr, while the command's own progress bars
    wait (:class:`StageBar`); silent with -q, when every kernel the command may need is
    cached (:func:`geoterrain.core.warmup.cold_kernels`), or when the run compiles none of
    the uncached ones (another strategy's kernels, say).
    """

    active: CompileBar | None = None  # the bar shown now, if any

    def __init__(self, command: str, quiet: bool):
        self.command, self.quiet = command, quiet
        self.bar = self.watch = None
        self.total = 0

    def __enter__(self) -> CompileBar:
        if self.quiet or self.command not in COMPILING:
            return self
        from geoterrain.core.warmup import CompileWatch

        # the uncached kernels are counted when numba starts its first compilation, not
        # here: a warm run (every kernel it uses cached) then never scans the sources
        self.watch = CompileWatch(self._step, started=self._show).__enter__()
        return self

    def _show(self) -> None:
        from geoterrain.core import warmup

        self.total = len(warmup.cold_kernels(COMPILING[self.command]))
        if self.total == 0:  # a kernel outside the command's stage folders: nothing said
            return
        click.echo(f"compiling kernels (first run only, about "
                   f"{warmup.estimate_seconds(self.total)} s)", err=True)
        self.bar = click.progressbar(length=self.total, label="compiling", file=sys.stderr,
                                     show_eta=False, show_pos=True)
        self.bar.__enter__()
        CompileBar.active = self

    def compiling(self) -> bool:
        """Whether numba is compiling a kernel now."""
        return self.watch is not None and self.watch.depth > 0

    def _step(self, done: int) -> None:
        if self.bar is not None:
            self.bar.update(min(done, self.total) - self.bar.pos)
            if done >= self.total:
                self.finish()

    def finish(self) -> None:
        """Close the bar (the command's own bars show from now on)."""
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
            self.bar = None
        if CompileBar.active is self:
            CompileBar.active = None

    def __exit__(self, *exc) -> None:
        self.finish()
        if self.watch is not None:
            self.watch.__exit__(*exc)
            self.watch = None
