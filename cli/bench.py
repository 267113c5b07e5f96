"""`geoterrain bench`: runtime against measured error across LOD strategies."""

from __future__ import annotations

import math
import sys

import click

from geoterrain.cli.globe import flyover_options, globe_flag
from geoterrain.cli.options import (
    SIZE,
    anti_aliasing_option,
    morph_option,
    occlusion_option,
    pixel_errors_option,
    strategies_option,
)

#: the options `bench --globe` takes
GLOBE_BENCH_OPTIONS = {"globe", "flight_fps", "frame_budget", "measure_every", "size",
                       "pixel_errors", "render", "output", "overwrite"}


def _floats(ctx, param, value):
    if value is None:
        return None
    try:
        out = tuple(float(v) for v in value.split(",") if v.strip())
    except ValueError:
        raise click.BadParameter(f"expected comma-separated numbers, got {value!r}") from None
    if not out or not all(math.isfinite(v) and v > 0 for v in out):
        raise click.BadParameter(f"expected finite numbers > 0, got {value!r}")
    return out


@click.command("bench")
@click.argument("source", required=False, type=click.Path(dir_okay=False))
@globe_flag
@flyover_options
@click.option("--synthetic", type=click.IntRange(3, 16385), metavar="N",
              help="Benchmark a synthetic N×N fbm DEM instead of SOURCE.")
@click.option("--seed", default=1, show_default=True, help="Seed of the synthetic DEM.")
@strategies_option
@occlusion_option
@morph_option
@anti_aliasing_option
@pixel_errors_option
@click.option("--views", "n_views", default=8, show_default=True, type=click.IntRange(1, 1000),
              help="Length of the built-in flight.")
@click.option("--path", "cameras", type=click.Path(dir_okay=False),
              help="Cameras JSON: a list of {look_from, look_at, up?, fov?} in scene metres.")
@click.option("--size", default="1280x720", show_default=True, type=SIZE,
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
              help="Where a DEM's store is written (default: a temporary directory); with "
                   "--experiment, where the stand-in terrains and their stores are kept.")
@click.option("--experiment", metavar="NAME",
              help="Re-run one of the LOD thesis's experiments (its Tables 6-3 … 6-20) "
                   "instead: tile-size, cull-mode, lod-error, spatial-coherence, "
                   "temporal-coherence, resolution, algorithm; 'list' describes them.")
@click.option("--terrains", default="Valley,Desert,Terrace,Highland", show_default=True,
              help="With --experiment: the thesis's terrains to run on (stand-ins of 257², "
                   "513², 1025², 2049²).")
@click.option("--frames", default=6, show_default=True, type=click.IntRange(1, 60),
              help="With --experiment: frames timed over the one-minute flight.")
@click.option("--overwrite", is_flag=True, help="Replace the CSV and the figure if they exist.")
@click.pass_context
def command(ctx, source, globe, flight_fps, frame_budget, measure_every, synthetic, seed,
            strategies, occlusion, morph, anti_aliasing,
            pixel_errors, n_views, cameras, size, render, peers, peer_errors, output, plot_path,
            cache_dir, experiment, terrains, frames, overwrite):
    """Benchmark the LOD strategies on SOURCE (a store or a DEM) or a synthetic DEM.

    Runs every strategy at every --pixel-error over a camera path (a built-in flight of
    overview, low oblique, grazing and looking-away views, or --path), and
    measures each frame: selection (and --render) time, triangles, vertices,
    tiles decoded, peak memory, and the measured screen-space error (max, p99)
    of the mesh against the full-resolution heights. A DEM is preprocessed
    first (its time and store size are recorded). Prints a summary table.

    With --experiment NAME it re-runs one of the LOD thesis's experiments instead (its
    Tables 6-3 … 6-20: BF, GMM and GTR over a one-minute flight on stand-ins of its four
    terrains, every frame selected and drawn) and prints each row's frame rate beside the
    thesis's four machines. Every row is drawn with one anti-aliasing mode (msaa unless
    --anti-aliasing names another; auto, which chooses per frame, is refused).

    \b
    Examples:
      geoterrain bench --synthetic 1025 --plot b.png -o b.csv
      geoterrain bench dem.geoterrain --pixel-error 1,2 --strategies rtin,chunked
      geoterrain bench dem.tif --path cameras.json --render --peers -o dem.csv
      geoterrain bench --experiment list
      geoterrain bench --experiment algorithm --terrains Valley,Terrace -o t620.csv
      geoterrain bench --globe japan.geoterrain --render --size 640x360 -o flyover.csv

    With --globe it flies the planetary flyover on the globe (from outside the
    atmosphere down to the ground and away again; over the store, or the procedural
    planet without one) with the asynchronous payload queue, and reports the
    frame-time distribution, the selection's share of the frame, the frames that stalled
    on generation, pop and (over a store) the measured screen-space error.
    """
    import json
    from pathlib import Path

    from geoterrain.bench import harness as bench
    from geoterrain.bench.report import format_table, plot, summarise, write_csv
    from geoterrain.core.paths import check_output, input_problem
    from geoterrain.exceptions import UsageError

    quiet = bool((ctx.obj or {}).get("quiet"))
    if globe:
        from geoterrain.cli import globe as G

        G.refuse_options(ctx, GLOBE_BENCH_OPTIONS, "bench --globe")
        if ctx.get_parameter_source("pixel_errors").name == "DEFAULT":
            pixel_errors = (1.0,)  # the flyover flies at one τ
        return G.bench(ctx, source, size, pixel_errors, render, flight_fps, frame_budget,
                       measure_every, output, overwrite)
    if experiment is not None:
        return _experiment(ctx, experiment, source, synthetic, anti_aliasing, terrains, frames,
                           output, cache_dir, quiet, overwrite)
    if cameras is not None and n_views != 8:
        raise UsageError("--views applies to the built-in flight; not with --path")
    inputs = [source, cameras]
    for p, what in ((None if synthetic else source, "give a DEM or a store"),
                    (cameras, "give a cameras JSON file")):
        # before any work: a FIFO would block the read, an over-long name fail in it
        if p is not None and (why := input_problem(p)) is not None:
            raise UsageError(f"{p}: {why}; {what}")
    for p, opt in ((output, "-o"), (plot_path, "--plot")):
        if p is not None:
            check_output(p, overwrite, inputs=inputs, option=opt)
    if output is not None and plot_path is not None and Path(output).absolute() == \
            Path(plot_path).absolute():
        raise UsageError("-o and --plot name the same file; choose another --plot path")
    if cache_dir is not None:  # an existing folder or a new one in an existing folder
        check_output(cache_dir, True, folder=True, inputs=inputs, option="--cache-dir")
    if plot_path is not None and Path(plot_path).suffix.lower() not in (".png", ".svg", ".pdf"):
        raise UsageError(f"{plot_path}: the plot must be .png, .svg or .pdf")
    bar = None

    def progress(n: int, total: int) -> None:
        nonlocal bar
        if quiet:
            return
        if bar is None:
            bar = click.progressbar(length=total, label="bench", file=sys.stderr, show_eta=True)
            bar.__enter__()
        bar.update(n)

    try:
        res = bench.benchmark(source, synthetic=synthetic, seed=seed, strategies=strategies,
                              taus=pixel_errors, n_views=n_views, cameras=cameras, size=size,
                              render=render, peer_errors=(peer_errors or True) if peers
                              else False, work_dir=cache_dir, progress=progress,
                              occlusion=occlusion, morph=morph, anti_aliasing=anti_aliasing)
    finally:
        if bar is not None:
            bar.__exit__(None, None, None)
    if output:
        write_csv(res.rows, output)
    if plot_path:
        plot(res.rows, plot_path, title=f"geoterrain bench: {res.label}")
    click.echo(f"# {res.label}: {len(res.views)} views × {len(strategies)} strategies × "
               f"{len(pixel_errors)} τ = {len(res.rows)} frames, {res.wall_s:.1f} s wall"
               + (f"; preprocess {res.preprocess_s:.2f} s" if res.preprocess_s is not None
                  else "") + f"; store {res.store_bytes / 2**20:.2f} MiB"
               + (f"; rendered with {anti_aliasing} anti-aliasing" if render else ""))
    click.echo(format_table(summarise(res.rows)))
    if res.peers:
        click.echo("\n# static meshes at matched vertical error (m)")
        click.echo(format_table(res.peers))
    for n in res.notes:
        click.echo(f"note: {n}", err=True)
    if output and not quiet:
        click.echo(f"wrote {output}", err=True)
    if plot_path and not quiet:
        click.echo(f"wrote {plot_path}", err=True)
    if (ctx.obj or {}).get("verbose"):
        click.echo(json.dumps({"wall_s": round(res.wall_s, 2)}), err=True)


def _experiment(ctx, name, source, synthetic, anti_aliasing, terrains, frames, output,
                cache_dir, quiet, overwrite):
    """``--experiment``: seed 000's tables re-run (:mod:`geoterrain.bench.experiments`)."""
    from click.core import ParameterSource

    from geoterrain.bench import experiments as ex
    from geoterrain.core.paths import check_output
    from geoterrain.exceptions import UsageError

    if name == "list":
        click.echo(ex.describe())
        return
    if source is not None or synthetic is not None:
        raise UsageError("--experiment runs on the thesis's stand-in terrains: give no SOURCE "
                         "or --synthetic (choose them with --terrains)")
    if ctx.get_parameter_source("anti_aliasing") is ParameterSource.DEFAULT:
        anti_aliasing = "msaa"  # one mode for every strategy (auto chooses per frame)
    if output is not None:  # core/paths.py: what -o may replace
        check_output(output, overwrite, option="-o")
    if cache_dir is not None:
        check_output(cache_dir, True, folder=True, option="--cache-dir")
    names = tuple(t.strip() for t in terrains.split(",") if t.strip())
    ex.configs(name, names)  # unknown names: a one-line error before any work
    bar = None

    def progress(n: int, total: int) -> None:
        nonlocal bar
        if quiet:
            return
        if bar is None:
            bar = click.progressbar(length=total, label=name, file=sys.stderr, show_eta=True)
            bar.__enter__()
        bar.update(n)

    try:
        res = ex.run_experiment(name, terrains=names, frames=frames, anti_aliasing=anti_aliasing,
                                work_dir=cache_dir, progress=progress)
    finally:
        if bar is not None:
            bar.__exit__(None, None, None)
    click.echo(ex.format_result(res))
    for n in res.notes:
        click.echo(f"note: {n}", err=True)
    if output:
        ex.write_result_csv(res, output)
        if not quiet:
            click.echo(f"wrote {output}", err=True)
