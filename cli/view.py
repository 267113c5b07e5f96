"""`geoterrain view`: an interactive window whose level of detail follows the camera."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import click
from geoterrain.cli.options import StageBar, parse_size


def cached_store(dem: Path) -> Path:
    """Where the store of a DEM goes: next to it if writable, else ~/.cache/geoterrain."""
    beside = dem.with_suffix(".geoterrain")
    if beside.exists() or os.access(dem.parent, os.W_OK):
        return beside
    digest = hashlib.sha1(str(dem.resolve()).encode()).hexdigest()[:10]
    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "geoterrain"
    return cache / f"{dem.stem}-{digest}.geoterrain"


def is_store(path: Path) -> bool:
    """True if ``path`` looks like a geoterrain store (by suffix or SQLite header)."""
    if path.suffix == ".geoterrain":
        return True
    try:
        with open(path, "rb") as fh:
            return fh.read(16) == b"SQLite format 3\x00"
    except OSError:
        return False


@click.command("view")
@click.argument("source", type=click.Path(exists=True, dir_okay=False))
@click.option("--strategy", type=click.Choice(["rtin", "chunked", "bruteforce"]),
              default="rtin", show_default=True)
@click.option("--pixel-error", type=float, default=1.0, show_default=True,
              help="Screen-space error bound τ in pixels (keys +/- change it).")
@click.option("--shading", type=click.Choice(["normals", "elevation", "plain"]),
              default="normals", show_default=True)
@click.option("--cmap", default="gist_earth", show_default=True, help="Matplotlib colormap.")
@click.option("--size", callback=parse_size, default="1280x720", show_default=True,
              help="Window WIDTHxHEIGHT.")
@click.option("--rebuild", is_flag=True, help="Preprocess the DEM again even if cached.")
@click.pass_context
def command(ctx, source, strategy, pixel_error, shading, cmap, size, rebuild):
    """Open SOURCE (a store or a DEM) in an interactive 3-D window.

    A DEM is preprocessed first into a store next to it (or in
    ~/.cache/geoterrain when its folder is read-only); the path is printed
    and the store is reused next time.

    \b
    Keys:
      m      next LOD strategy (rtin, chunked, bruteforce)
      + / -  τ × 2 / ÷ 2
      x      wireframe
      c      colour by shading / LOD level / tile
      space  freeze the LOD (fly around to inspect culling and refinement)
      h      home view;  q  quit

    \b
    Examples:
      geoterrain view dem.geoterrain
      geoterrain view srtm.tif --strategy chunked --pixel-error 2
    """
    import geoterrain
    from geoterrain.exceptions import GeoterrainError, UsageError
    from geoterrain.viewer import show

    if pixel_error <= 0:
        raise UsageError(f"--pixel-error must be > 0, got {pixel_error}")
    quiet = (ctx.obj or {}).get("quiet", False)
    src = Path(source)
    if is_store(src):
        store = src
    else:
        store = cached_store(src)
        stale = not store.exists() or store.stat().st_mtime < src.stat().st_mtime
        if rebuild or stale:
            store.parent.mkdir(parents=True, exist_ok=True)
            click.echo(f"preprocessing {src} → {store}", err=True)
            bar = StageBar("preprocess", quiet)
            try:
                geoterrain.preprocess(src, store, overwrite=True, progress=bar)
            finally:
                bar.close()
        else:
            click.echo(f"using the cached store {store}", err=True)
    if not has_display():
        raise GeoterrainError(
            "no display to open a window on (DISPLAY is not set); use `geoterrain render` "
            "for pictures, or run under a desktop session or Xvfb")
    with geoterrain.open(store) as t:
        show(t, strategy, pixel_error, shading=shading, cmap=cmap, size=size)


def has_display() -> bool:
    """True where a window can open: any non-Linux desktop, or X11/Wayland on Linux."""
    import os
    import sys

    if not sys.platform.startswith("linux"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
