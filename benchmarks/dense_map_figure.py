"""The dense run's ``map.png`` (``tracks.dense.plots.map_figure``) against the scatter it replaced,
timed in the same process on the same maps, one core.

The map is a real fused one: the ``map.ply`` of ``--run`` (a run folder; without it the script runs
``assocbench run --method projective --scene crates --frames 200 --set resolution=[320,240]
--set depth.downsample=1`` into a temporary folder first, ~20 s with the sequence cached), with its
``truth.txt`` / ``estimate.txt`` paths. A size below the map's is an even random subsample; a size
above it is the whole map plus a random draw of its points jittered by 2 mm in x and y (synthetic
points on the real surfaces, said in the table).

Tables: per map size the median seconds of a single-panel ``map.png`` (``--runs`` interleaved runs
of each, after one warm-up), the ratio, and the PNG's size; the dense leaderboard's picture (8 panels
of 10 000 points, the runs' ``final_map``, 4 columns); the first picture of a fresh process, as in a
CLI run (matplotlib's import, then the picture: ``--runs`` / 2 processes each, at least 3); where the
new picture's time goes at 100k points. The load average is printed: timings on a shared machine are
noisy.

Usage: python benchmarks/dense_map_figure.py [--run DIR] [--runs 7] [--sizes 20000 100000 200000] [--save DIR]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
from _util import print_table, run_recorded

from assocbench.sim.ply import read_ply
from assocbench.tracks.dense import plots

MAX_DRAWN = 20_000   # the scatter's cap before issue 27
OLD_SCALE_MM = 30.0  # the scatter's fixed colour scale


def scatter_panel(ax, positions, error_mm, p_true, p_est, title):
    """The top view before issue 27 (kept as the baseline): a 1-in-⌈N / 20 000⌉ subsample, scattered
    sorted by error, rasterised by matplotlib."""
    step = max(1, -(-len(positions) // MAX_DRAWN))
    pos, err = positions[::step], error_mm[::step]
    order = np.argsort(err)
    sc = ax.scatter(pos[order, 0], pos[order, 1], c=err[order], s=0.5, cmap="viridis", vmin=0,
                    vmax=OLD_SCALE_MM, linewidths=0, rasterized=True)
    ax.plot(p_true[:, 0], p_true[:, 1], color="black", lw=2.0, label="true path")
    ax.plot(p_est[:, 0], p_est[:, 1], color="#1f77b4", lw=1.0, label="estimate")
    ax.plot(*p_true[0, :2], "o", color="black", ms=4)
    ax.set_aspect("equal")
    drawn = "" if step == 1 else f"; {len(pos):,} of {len(positions):,} map points drawn (1 in {step})"
    ax.set_xlabel(f"x (m){drawn}", fontsize=7)
    ax.set_ylabel("y (m)", fontsize=7)
    ax.set_title(textwrap.fill(title, 48), fontsize=8)
    ax.tick_params(labelsize=6)
    return sc


def scatter_figure(panels, path, columns=3):
    """``map_figure`` before issue 27."""
    from matplotlib.figure import Figure

    cols = min(columns, len(panels))
    rows = -(-len(panels) // cols)
    fig = Figure(figsize=(4.2 * cols, 3.8 * rows))
    axes = fig.subplots(rows, cols, squeeze=False)
    sc = None
    for ax, panel in zip(axes.flat, panels):
        sc = scatter_panel(ax, panel["positions"], panel["error_mm"], panel["p_true"], panel["p_est"], panel["title"])
    for ax in list(axes.flat)[len(panels):]:
        ax.axis("off")
    if sc is not None:
        bar = fig.colorbar(sc, ax=axes, shrink=0.6, fraction=0.03, pad=0.02)
        bar.set_label(f"distance to true surface, mm (clipped at {OLD_SCALE_MM:g})", fontsize=7)
        bar.ax.tick_params(labelsize=6)
        axes.flat[0].legend(fontsize=6, loc="upper right", markerscale=4)
    fig.savefig(path, dpi=110)


def run_folder(given: str | None) -> Path:
    if given:
        return Path(given)
    out = Path(tempfile.mkdtemp(prefix="dense_map_figure_"))
    cmd = [sys.executable, "-m", "assocbench.cli.main", "run", "--method", "projective", "--scene", "crates",
           "--frames", "200", "--set", "resolution=[320,240]", "--set", "depth.downsample=1", "--out", str(out)]
    print("running:", " ".join(cmd[2:]), flush=True)
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return out


def sized(points: np.ndarray, n: int, rng) -> tuple[np.ndarray, str]:
    """``n`` rows of ``points`` (x, y, z, error): a subsample, or all plus jittered repeats."""
    if n <= len(points):
        return points[np.sort(rng.choice(len(points), n, replace=False))], "real"
    extra = points[rng.choice(len(points), n - len(points))].copy()
    extra[:, :2] += rng.normal(0.0, 0.002, (len(extra), 2))
    return np.concatenate([points, extra]), f"real + {n - len(points):,} jittered"


def interleaved(fns: dict, runs: int) -> dict[str, float]:
    """Median seconds of each function, run alternately ``runs`` times after one warm-up each."""
    times = {k: [] for k in fns}
    for fn in fns.values():
        fn()
    for _ in range(runs):
        for k, fn in fns.items():
            start = time.perf_counter()
            fn()
            times[k].append(time.perf_counter() - start)
    return {k: float(np.median(v)) for k, v in times.items()}


def compare(name_panels, columns: int, runs: int, out: Path) -> list[list[object]]:
    rows = []
    for name, panels in name_panels:
        old, new = out / f"scatter_{name}.png", out / f"raster_{name}.png"
        t = interleaved({"old": lambda: scatter_figure(panels, old, columns),
                         "new": lambda: plots.map_figure(panels, new, columns)}, runs)
        rows.append([name, t["old"], t["new"], f"{t['old'] / t['new']:.1f}x",
                     f"{old.stat().st_size // 1024} / {new.stat().st_size // 1024}"])
    return rows


def breakdown(panels, runs: int, out: Path) -> list[list[object]]:
    """Where the new picture's time goes: the canvas (figure, text, colour bar, raster), the raster
    alone, and drawing + PNG encoding at zlib level 1 and 6 (matplotlib's default, used)."""
    p = panels[0]
    box = plots.map_canvas(panels, 1).axes[0].get_window_extent()
    extent = plots.view_limits(p["positions"], p["p_true"], p["p_est"])
    fig = plots.map_canvas(panels, 1)
    t = interleaved({
        "canvas": lambda: plots.map_canvas(panels, 1),
        "raster": lambda: plots.error_colours(plots.worst_error_grid(p["positions"][:, :2], p["error_mm"], extent,
                                                                     int(box.width), int(box.height)),
                                              plots.colour_range(panels)),
        "save1": lambda: fig.savefig(out / "b1.png", dpi=plots.DPI, pil_kwargs={"compress_level": 1}),
        "save6": lambda: fig.savefig(out / "b6.png", dpi=plots.DPI, pil_kwargs={"compress_level": 6})}, runs)
    return [["map_canvas: figure, axes, text, colour bar, raster", t["canvas"]],
            ["  of which the raster (grid + colours)", t["raster"]],
            ["savefig: draw + PNG, zlib level 1", t["save1"]],
            ["savefig: draw + PNG, zlib level 6 (default, used)", t["save6"]]]


COLD = """
import sys, time
sys.path.insert(0, {here!r})
import numpy as np
with np.load({npz!r}) as z:
    panels = [{{k: z[k] for k in ("positions", "error_mm", "p_true", "p_est")}} | {{"title": "cold run"}}]
from dense_map_figure import scatter_figure
from assocbench.tracks.dense.plots import map_figure
assert "matplotlib" not in sys.modules   # its import is part of the first picture's cost
start = time.perf_counter()
import matplotlib.backends.backend_agg, matplotlib.cm, matplotlib.colors, matplotlib.figure
imported = time.perf_counter()
(scatter_figure if {old} else map_figure)(panels, {png!r}, 1)
print(imported - start, time.perf_counter() - imported)
"""


def cold(panels, runs: int, out: Path) -> list[list[object]]:
    """Medians (s) over fresh processes of matplotlib's import and then the first picture (as in a
    CLI run, where nothing else imports matplotlib); interpreter start, assocbench's import and the
    map's load excluded."""
    p = panels[0]
    npz = out / "cold_map.npz"
    np.savez(npz, positions=p["positions"], error_mm=p["error_mm"], p_true=p["p_true"], p_est=p["p_est"])
    times = {"old": [], "new": []}
    for _ in range(runs):
        for kind in times:
            code = COLD.format(here=str(Path(__file__).resolve().parent), npz=str(npz), old=kind == "old",
                               png=str(out / f"cold_{kind}.png"))
            done = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
            times[kind].append([float(v) for v in done.stdout.split()[-2:]])
    rows = []
    for kind, name in (("old", "scatter"), ("new", "raster")):
        imp, draw = np.median(np.array(times[kind]), axis=0)
        rows.append([f"{name}, {len(p['positions']):,} points", float(imp), float(draw), float(imp + draw)])
    return rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--run", help="a dense run's folder (map.ply, truth.txt, estimate.txt)")
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--sizes", type=int, nargs="+", default=[20_000, 100_000, 200_000])
    ap.add_argument("--save", help="folder for the PNGs (default: a temporary one)")
    args = ap.parse_args()
    folder = run_folder(args.run)
    ply = read_ply(folder / "map.ply")
    points = np.column_stack([ply["x"], ply["y"], ply["z"], ply["error_mm"]]).astype(float)
    p_true, p_est = (np.loadtxt(folder / f, usecols=(1, 2, 3)) for f in ("truth.txt", "estimate.txt"))
    out = Path(args.save or tempfile.mkdtemp(prefix="dense_map_png_"))
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    load0 = os.getloadavg()[0]
    print(f"map of {folder}: {len(points):,} points; {os.cpu_count()} CPUs, load {load0:.1f} at the start")

    def panel(pts, title):
        return {"positions": pts[:, :3], "error_mm": pts[:, 3], "p_true": p_true, "p_est": p_est, "title": title}

    single, kinds = [], []
    for n in args.sizes:
        pts, kind = sized(points, n, rng)
        single.append((f"{n // 1000}k", [panel(pts, f"projective on crates, {n:,} points")]))
        kinds.append(kind)
    rows = compare(single, 1, args.runs, out)
    print_table(["points", "scatter s", "raster s", "speed-up", "PNG KiB old / new"], rows)
    print("points: " + "; ".join(f"{r[0]} {k}" for r, k in zip(rows, kinds)) + "\n")
    board = [panel(sized(points, 10_000, rng)[0], f"method {k} on crates, seed 0") for k in range(8)]
    print_table(["leaderboard", "scatter s", "raster s", "speed-up", "PNG KiB old / new"],
                compare([("8 x 10k", board)], 4, max(3, args.runs // 2), out))
    print_table(["first picture of a fresh process", "import s", "picture s", "total s"],
                cold(single[min(1, len(single) - 1)][1], max(3, args.runs // 2), out))
    print_table(["100k points, new picture", "s"], breakdown(single[min(1, len(single) - 1)][1], args.runs, out))
    print(f"load {os.getloadavg()[0]:.1f} at the end; PNGs in {out}")


if __name__ == "__main__":
    run_recorded(main)
