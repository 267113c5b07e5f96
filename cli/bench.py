"""`geoterrain bench`: runtime against measured error across LOD strategies."""

from __future__ import annotations

import sys

import click
from geoterrain.cli.options import parse_size


def _floats(ctx, param, value):
    if value is None:
        return None
    try:
        out = tuple(float(v) for v in value.split(",") if v.strip())
    except ValueError:
        raise click.BadParameter(f"expected comma-separated numbers, got {value!r}") from None
    if not out:
        raise click.BadParameter("expected at least one number")
    return out


def _names(ctx, param, value):
    out = tuple(v.strip() for v in value.split(",") if v.strip())
    bad = [v for v in out if v not in ("rtin", "chunked", "bruteforce")]
    if bad or not out:
        raise click.BadParameter(f"unknown strategy {', '.join(bad) or value!r}; "
                                 "use rtin, chunked, bruteforce")
    return out


@click.command("bench")
@click.argument("source", required=False, type=click.Path(dir_okay=False))
@click.option("--synthetic", type=click.IntRange(3, 16385), metavar="N",
              help="Benchmark a synthetic N×N fbm DEM instead of SOURCE.")
@click.option("--seed", default=1, show_default=True, help="Seed of the synthetic DEM.")
@click.option("--strategies", default="rtin,chunked,bruteforce", show_default=True,
              callback=_names, help="Comma-separated strategies.")
@click.option("--tau", "taus", default="0.5,1,2,4,8", show_default=True, callback=_floats,
              help="Comma-separated pixel tolerances τ.")
@click.option("--views", "n_views", default=8, show_default=True, type=click.IntRange(1, 1000),
              help="Length of the built-in flight.")
@click.option("--path", "cameras", type=click.Path(dir_okay=False),
              help="Cameras JSON: a list of {look_from, look_at, up?, fov?} in scene metres.")
@click.option("--size", default="1280x720", show_default=True, callback=parse_size,
              help="Image size WxH the pixel error refers to.")
@click.option("--render", is_flag=True, help="Also render every frame offscreen and time it.")
@click.option("--peers", is_flag=True,
              help="Also compare static rtin with pymartini and pydelatin at matched error.")
@click.option("--peer-errors", default=None, callback=_floats,
              help="Vertical errors (m) for --peers; default: 0.5,1,2,4,8 × max(codec step, "
                   "0.1 % of the height range).")
@click.option("-o", "--output", type=click.Path(dir_okay=False), help="Tidy CSV of every frame.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), help="Figure (PNG).")
@click.option("--cache-dir", type=click.Path(file_okay=False),
              help="Where a DEM's store is written (default: a temporary directory).")
@click.pass_context
def command(ctx, source, synthetic, seed, strategies, taus, n_views, cameras, size, render,
            peers, peer_errors, output, plot_path, cache_dir):
    """Benchmark the LOD strategies on SOURCE (a store or a DEM) or a synthetic DEM.

    Runs every strategy at every τ over a camera path (a built-in flight of
    overview, low oblique, grazing and looking-away views, or --path), and
    measures each frame: selection (and --render) time, triangles, vertices,
    tiles decoded, peak memory, and the measured screen-space error (max, p99)
    of the mesh against the full-resolution heights. A DEM is preprocessed
    first (its time and store size are recorded). Prints a summary table.

    \b
    Examples:
      geoterrain bench --synthetic 1025 --plot b.png -o b.csv
      geoterrain bench dem.geoterrain --tau 1,2 --strategies rtin,chunked
      geoterrain bench dem.tif --path cameras.json --render --peers -o dem.csv
    """
    import json
    import math
    import os
    import tempfile
    import time
    from pathlib import Path

    import geoterrain
    from geoterrain import bench
    from geoterrain.exceptions import UsageError

    quiet = bool((ctx.obj or {}).get("quiet"))
    if (source is None) == (synthetic is None):
        raise UsageError("give SOURCE (a store or a DEM) or --synthetic N, not both or neither")
    if cameras is not None and n_views != 8:
        raise UsageError("--views applies to the built-in flight; not with --path")
    for p in (output, plot_path):
        if p is not None and not Path(p).parent.exists():
            raise UsageError(f"{p}: the directory does not exist")
    if plot_path is not None and Path(plot_path).suffix.lower() not in (".png", ".svg", ".pdf"):
        raise UsageError(f"{plot_path}: the plot must be .png, .svg or .pdf")
    if synthetic is not None and synthetic < 3:
        raise UsageError("--synthetic needs N ≥ 3")
    t_wall = time.perf_counter()
    tmp = tempfile.TemporaryDirectory(prefix="geoterrain-bench-")
    work = Path(cache_dir) if cache_dir else Path(tmp.name)
    work.mkdir(parents=True, exist_ok=True)
    preprocess_s = store_bytes = None
    try:
        if synthetic is not None:
            from geoterrain.synth import generate, write_geotiff

            source = str(write_geotiff(Path(tmp.name) / f"fbm_{synthetic}.tif",
                                       generate("fbm", synthetic, seed=seed)))
            label = f"synthetic fbm {synthetic}² (seed {seed})"
        else:
            label = Path(source).name
            if not Path(source).is_file():
                raise UsageError(f"{source}: no such file")
        store = Path(source)
        if not _is_store(store):
            store = work / (Path(source).stem + ".geoterrain")
            t0 = time.perf_counter()
            geoterrain.preprocess(source, store, overwrite=True)
            preprocess_s = round(time.perf_counter() - t0, 3)
        store_bytes = os.path.getsize(store)
        with geoterrain.open(store) as t:
            views = bench.load_path(cameras, size, frame=t.frame) if cameras else None
            n_frames = (len(views) if views else n_views) * len(strategies) * len(taus)
            bar = None
            if not quiet:
                bar = click.progressbar(length=n_frames, label="bench", file=sys.stderr,
                                        show_eta=True)
                bar.__enter__()
            try:
                if views is None:
                    X, Y, Z = t.scene_xyz()
                    views = bench.flight(*bench._extent(X, Y, Z), n_views=n_views, size=size)
                    del X, Y, Z
                res = bench.run(t, views, strategies=strategies, taus=taus, render=render,
                                source=label, preprocess_s=preprocess_s,
                                store_bytes=store_bytes,
                                progress=bar.update if bar is not None else None)
            finally:
                if bar is not None:
                    bar.__exit__(None, None, None)
            peer_rows, peer_notes = [], []
            if peers:
                errs = peer_errors
                if errs is None:
                    step = float(getattr(t.quantizer, "step", 0.0) or 0.0)
                    lo_h, hi_h = t.meta["height_range"]
                    base = max(step, 1e-3 * float(hi_h - lo_h), 1e-6)
                    errs = tuple(base * k for k in (0.5, 1, 2, 4, 8))
                if any(not (math.isfinite(e) and e >= 0) for e in errs):
                    raise UsageError("--peer-errors must be finite and ≥ 0")
                peer_rows, peer_notes = bench.peers(t, errs)
        if output:
            bench.write_csv(res.rows, output)
        if plot_path:
            bench.plot(res.rows, plot_path, title=f"geoterrain bench: {label}")
        summ = bench.summarise(res.rows)
        wall = time.perf_counter() - t_wall
        click.echo(f"# {label}: {len(res.views)} views × {len(strategies)} strategies × "
                   f"{len(taus)} τ = {len(res.rows)} frames, {wall:.1f} s wall"
                   + (f"; preprocess {preprocess_s:.2f} s" if preprocess_s is not None else "")
                   + f"; store {store_bytes / 2**20:.2f} MiB")
        click.echo(bench.format_table(summ))
        if peer_rows:
            click.echo("\n# static meshes at matched vertical error (m)")
            click.echo(bench.format_table(peer_rows))
        for n in res.notes + peer_notes:
            click.echo(f"note: {n}", err=True)
        if output and not quiet:
            click.echo(f"wrote {output}", err=True)
        if plot_path and not quiet:
            click.echo(f"wrote {plot_path}", err=True)
        if (ctx.obj or {}).get("verbose"):
            click.echo(json.dumps({"wall_s": round(wall, 2)}), err=True)
    finally:
        tmp.cleanup()


def _is_store(path) -> bool:
    """True when ``path`` is a geoterrain store (by suffix, or by its first bytes)."""
    if str(path).endswith(".geoterrain"):
        return True
    try:
        with open(path, "rb") as fh:
            head = fh.read(16)
    except OSError:
        return False
    return head.startswith(b"SQLite format 3")
