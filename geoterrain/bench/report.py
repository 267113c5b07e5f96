"""Benchmark reports: tidy CSV, a summary table, and a figure of runtime against error.

Rows come from :func:`geoterrain.bench.harness.run` (one per frame × strategy × τ).

Examples
--------
>>> rows = [{"strategy": "rtin", "tau": 1.0, "select_ms": 2.0, "render_ms": float("nan"),
...          "triangles": 10, "tiles_decoded": 1, "peak_mem_mb": 1.0, "err_max": 0.9,
...          "err_p99": 0.5}]
>>> format_table(summarise(rows)).splitlines()[0].split(" | ")[:3]
['| strategy', 'tau', 'frames']
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from geoterrain.lod.registry import STRATEGIES

COLUMNS = ("source", "frame", "view", "strategy", "tau", "select_ms", "select_cold_ms",
           "render_ms", "anti_aliasing", "triangles", "skirt_triangles", "vertices",
           "tiles_decoded", "normals_decoded", "bounds_decoded", "bytes_read", "textures_built",
           "peak_mem_mb",
           "err_max", "err_p99", "err_mean", "pop_px", "samples_in_view", "uncovered_in_view",
           "preprocess_s", "store_bytes")


def _colors(strategies: Sequence[str]) -> dict[str, str]:
    """A stable colour per strategy (registry order; bruteforce grey)."""
    palette = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown",
               "tab:pink", "tab:olive", "tab:cyan"]
    out, k = {}, 0
    for s in STRATEGIES:
        if s == "bruteforce":
            out[s] = "tab:gray"
        else:
            out[s] = palette[k % len(palette)]
            k += 1
    return {s: out.get(s, "black") for s in strategies}


def write_csv(rows: Sequence[dict], path: str | Path, columns: Sequence[str] = COLUMNS) -> Path:
    """Write tidy rows to a CSV file (one row per frame × strategy × τ).

    Examples
    --------
    >>> import tempfile, os
    >>> p = write_csv([{"frame": 0, "tau": 1.0}], os.path.join(tempfile.mkdtemp(), "b.csv"),
    ...               columns=("frame", "tau"))
    >>> open(p).read().splitlines()
    ['frame,tau', '0,1.0']
    """
    import io

    from geoterrain.core.atomicfiles import write_atomic

    buf = io.StringIO(newline="")
    w = csv.DictWriter(buf, fieldnames=list(columns), extrasaction="ignore")
    w.writeheader()
    w.writerows(rows)
    return write_atomic(path, buf.getvalue())


def _p95(a: np.ndarray) -> float:
    a = a[np.isfinite(a)]
    return float(np.percentile(a, 95)) if a.size else float("nan")


def _med(a: np.ndarray) -> float:
    a = a[np.isfinite(a)]
    return float(np.median(a)) if a.size else float("nan")


def summarise(rows: Sequence[dict]) -> list[dict]:
    """One summary row per (strategy, τ): medians, p95 and the worst measured error.

    Examples
    --------
    >>> rows = [{"strategy": "rtin", "tau": 1.0, "select_ms": 2.0, "render_ms": float("nan"),
    ...          "triangles": 10, "tiles_decoded": 1, "peak_mem_mb": 1.0, "err_max": 0.9,
    ...          "err_p99": 0.5}]
    >>> s = summarise(rows)[0]
    >>> s["strategy"], s["select_ms_med"], s["err_max_worst"]
    ('rtin', 2.0, 0.9)
    """
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["strategy"], float(r["tau"])), []).append(r)
    out = []
    for (s, tau), g in groups.items():
        col = {k: np.array([float(r.get(k, math.nan)) for r in g]) for k in
               ("select_ms", "select_cold_ms", "render_ms", "triangles", "tiles_decoded",
                "peak_mem_mb", "err_max", "err_p99", "pop_px")}
        # frames per second of a warm frame: selection and render, nothing else
        fps = 1000.0 / (col["select_ms"] + col["render_ms"])
        pop = col["pop_px"][np.isfinite(col["pop_px"])]
        out.append({
            "strategy": s, "tau": tau, "frames": len(g),
            "select_ms_med": _med(col["select_ms"]), "select_ms_p95": _p95(col["select_ms"]),
            "select_cold_ms_med": _med(col["select_cold_ms"]),
            "render_ms_med": _med(col["render_ms"]), "render_ms_p95": _p95(col["render_ms"]),
            "fps_med": _med(fps),
            "triangles_med": _med(col["triangles"]), "tiles_decoded_med":
                _med(col["tiles_decoded"]), "peak_mem_mb_med": _med(col["peak_mem_mb"]),
            "err_max_worst": float(np.max(col["err_max"])),
            "err_p99_med": _med(col["err_p99"]),
            "pop_px_max": float(pop.max()) if pop.size else math.nan,
        })
    order = {s: k for k, s in enumerate(STRATEGIES)}
    out.sort(key=lambda r: (order.get(r["strategy"], 99), r["tau"]))
    return out


def _fmt(v) -> str:
    if isinstance(v, str):
        return v
    if isinstance(v, int):
        return str(v)
    v = float(v)
    if not math.isfinite(v):
        return "–"
    if v == 0:
        return "0"
    if abs(v) >= 1e5:
        return f"{v:.3g}"
    if abs(v) >= 100:
        return f"{v:.0f}"
    return f"{v:.3g}"


def format_table(summary: Sequence[dict], markdown: bool = True) -> str:
    """The summary as a (markdown) table.

    Examples
    --------
    >>> print(format_table([{"strategy": "rtin", "tau": 1.0, "frames": 3}]))
    | strategy | tau | frames |
    |---|---|---|
    | rtin | 1 | 3 |
    """
    if not summary:
        return "(no rows)"
    cols = list(summary[0].keys())
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in summary:
        lines.append("| " + " | ".join(_fmt(r[c]) for c in cols) + " |")
    return "\n".join(lines)


def plot(rows: Sequence[dict], path: str | Path, title: str = "") -> Path:
    """Write a figure: runtime against measured error, triangles against τ, a timeline.

    Examples
    --------
    >>> import tempfile, os
    >>> rows = [{"strategy": "rtin", "tau": 1.0, "frame": 0, "view": "overview",
    ...          "select_ms": 2.0, "render_ms": float("nan"), "triangles": 10,
    ...          "tiles_decoded": 1, "peak_mem_mb": 1.0, "err_max": 0.9, "err_p99": 0.5}]
    >>> plot(rows, os.path.join(tempfile.mkdtemp(), "b.png")).suffix
    '.png'
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    summ = summarise(rows)
    strategies = [s for s in STRATEGIES if any(r["strategy"] == s for r in summ)]
    colors = _colors(strategies)
    fig, axes = plt.subplots(2, 2, figsize=(13, 9), layout="constrained")
    ax = axes[0, 0]
    for s in strategies:
        g = [r for r in summ if r["strategy"] == s]
        x = np.array([r["err_max_worst"] for r in g])
        y = np.array([r["select_ms_med"] for r in g])
        ax.plot(np.maximum(x, 1e-3), y, "o-", color=colors.get(s), label=s)
        flat = len({round(v, 9) for v in x}) == 1  # τ-independent (bruteforce): one label
        for r, xi, yi in zip(g, x, y, strict=True):
            if flat and r is not g[-1]:
                continue
            ax.annotate("all τ" if flat else f"τ={r['tau']:g}", (max(xi, 1e-3), yi), fontsize=7,
                        textcoords="offset points", xytext=(4, 3), color=colors.get(s))
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("worst measured screen-space error over the flight (px; 0 drawn at 1e-3)")
    ax.set_ylabel("median selection time (ms)")
    ax.set_title("Runtime against measured error (lower left is better)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()

    ax = axes[0, 1]
    for s in strategies:
        g = [r for r in summ if r["strategy"] == s]
        ax.plot([r["tau"] for r in g], [max(r["triangles_med"], 1) for r in g], "o-",
                color=colors.get(s), label=s)
    taus = sorted({r["tau"] for r in summ})
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xticks(taus)
    ax.set_xticklabels([f"{t:g}" for t in taus])
    ax.set_xlabel("pixel tolerance τ")
    ax.set_ylabel("median triangles per frame")
    ax.set_title("Mesh size against τ")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()

    ax = axes[1, 0]
    tau_mid = min(taus, key=lambda t: abs(math.log(t)))  # τ closest to 1
    for s in strategies:
        g = sorted((r for r in rows if r["strategy"] == s and float(r["tau"]) == tau_mid),
                   key=lambda r: r["frame"])
        ax.plot([r["frame"] for r in g], [max(float(r["select_ms"]), 1e-2) for r in g], "o-",
                color=colors.get(s), label=f"{s} select")
        rms = [float(r["render_ms"]) for r in g]
        if any(math.isfinite(v) for v in rms):
            ax.plot([r["frame"] for r in g], rms, "x--", color=colors.get(s),
                    label=f"{s} render")
    frames = sorted({(r["frame"], r["view"]) for r in rows})
    ax.set_xticks([f for f, _ in frames])
    ax.set_xticklabels([f"{f}\n{v}" for f, v in frames], fontsize=7)
    ax.set_yscale("log")
    ax.set_ylabel("ms")
    ax.set_title(f"Per-frame timeline at τ = {tau_mid:g}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)

    ax = axes[1, 1]
    for s in strategies:
        g = sorted((r for r in rows if r["strategy"] == s and float(r["tau"]) == tau_mid),
                   key=lambda r: r["frame"])
        ax.plot([r["frame"] for r in g], [float(r["err_max"]) for r in g], "o-",
                color=colors.get(s), label=f"{s} max")
        ax.plot([r["frame"] for r in g], [float(r["err_p99"]) for r in g], ".:",
                color=colors.get(s), label=f"{s} p99")
    ax.axhline(tau_mid, color="red", lw=1, ls="--", label=f"τ = {tau_mid:g}")
    ax.set_xticks([f for f, _ in frames])
    ax.set_xticklabels([f"{f}\n{v}" for f, v in frames], fontsize=7)
    ax.set_ylabel("measured screen-space error (px)")
    ax.set_title(f"Per-frame measured error at τ = {tau_mid:g}")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    if title:
        fig.suptitle(title)
    import io

    from geoterrain.core.atomicfiles import write_atomic

    path = Path(path)
    buf = io.BytesIO()
    fig.savefig(buf, dpi=110, format=path.suffix.lstrip(".").lower() or "png")
    write_atomic(path, buf.getvalue())  # never a half-written figure
    plt.close(fig)
    return path
