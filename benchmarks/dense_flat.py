"""Is the dense track's per-frame cost flat as the map grows? A scene's dense path driven there and back.

A run's per-frame cost rises along the 500-frame crates path (27 -> 34 ms a frame in
``dense_rate.py``), and the map grows 2.7x (67k -> 184k points) over it, so the two are easy to
confuse. This script separates them by driving the path out (frames 0 .. N-1) and back (N-2 .. 0):
on the way back the camera sees the same views again with a map that holds the whole path, so a
cost that follows the map would be higher on the way back than on the way out at the same view,
and a cost that follows the view would not.

What it runs. The dense track's own frame loop (``tracks.dense.run.dense_records``, what
``assocbench run --method projective --scene crates`` runs in its worker: depth frame, the model
splatted into the view, ICP frame-to-model, fusion, scoring) on the scene's own dense path at the
default path's speed (``dense_rate.path_settings``: the crates circle, 0.175 turns over 500 frames;
the bays line, 11.25 m of the corridor, its map growing behind the camera) at 320x240 with
``depth.downsample=1``, one core, on a sequence whose frames are the path's frames in the order
out-and-back; frame k of it draws its own noise (``default_rng([seed, k, 17])``), so the way back
is a second pass of the sensor over the same poses, not a replay. Rendering is not timed (the
sequence is cached); the kernels are warmed first. The same loop runs again without the map's
index (``dense.index=false``: the splat and fusion visit every map point, the same numbers bit for
bit): the baseline whose cost does follow the map.

Columns, per ``--band`` frames of the path (medians over the band's frames, each leg):
the map's size on the way out and back, the map points the splat visited a frame (``visited``,
the points in the blocks meeting the view frustum), the map points that landed on a valid pixel
at fusion (``on a pixel``: fusion's ``considered``, the points it merges or tests; against the
70-74k valid pixels of a crates frame, the map's density in view), the frame's stages (depth frame, prediction,
ICP, fusion, scoring; ms), of which the two that read the map (the splat and fusion), and those
two without the index. A line then answers the question: on the way out, from the first band to
the last, the map's growth and the frame's cost with and without the index. Then least-squares
fits over every frame of each loop, ``ms = a + b · visited + c · map`` (the map's size before the
frame): ``c`` is the cost of the map's size at a given view (ms per 100k points), ``b`` the cost
of what is in view. Without the index ``visited`` is the whole map, so there the fit has one
slope (``c`` is not printed). Last, the loop's accuracy:
ATE over every frame, ICP failures and the final map's error (the baseline a change to the map's
density is judged against).

Usage: python benchmarks/dense_flat.py [--frames 500] [--band 100] [--scene crates]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import time

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS"):   # one core: before numpy/numba read them
    os.environ.setdefault(_var, "1")
os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from _util import print_table, run_recorded  # noqa: E402
from dense_rate import load, render_once, settings  # noqa: E402

from assocbench.associators.registry import make_dense_associator  # noqa: E402
from assocbench.errors import UserError  # noqa: E402
from assocbench.harness.config import load_run_config, run_spec  # noqa: E402
from assocbench.harness.runner import GuardedCalls  # noqa: E402
from assocbench.scoring.trajectory import ate_rmse  # noqa: E402
from assocbench.tracks.dense.run import dense_records  # noqa: E402
from assocbench.tracks.dense.summary import poses  # noqa: E402
from assocbench.tracks.dense.track import gate_params  # noqa: E402
from assocbench.tracks.dense.warm import warm_dense  # noqa: E402

STAGES = ("frame_s", "predict_s", "icp_s", "fusion_s", "score_s")


def there_and_back(seq, frames: int):
    """``seq``'s first ``frames`` frames out (0 .. N-1) and back (N-2 .. 0), and the order."""
    order = np.r_[np.arange(frames), np.arange(frames - 2, -1, -1)]
    return dataclasses.replace(seq, depths=seq.depths[order], geoms=seq.geoms[order],
                               rotations=seq.rotations[order], positions=seq.positions[order]), order


def loop_spec(scene: str, frames: int, extra: list[str]):
    """The run's spec for the out-and-back loop of a ``frames``-frame path: 2N - 1 frames of a path
    computed over ``max(N, 200)`` (``dense_rate.settings``), both within ``limits.frames``."""
    sets = settings(scene, frames, ["dense.prediction=view", f"limits.frames={max(2 * frames, 1000)}", *extra])
    return run_spec(load_run_config(None, sets[1::2], method="projective", scene=scene, frames=2 * frames - 1))


def records(seq, scene: str, frames: int, extra: list[str]) -> pd.DataFrame:
    """The dense track's per-frame records of ``seq`` (the projective method, frame-to-model)."""
    spec = loop_spec(scene, frames, extra)
    calls = GuardedCalls(time_limit_s=math.inf, faults={}, on_call=lambda k, limit: None)
    rows = list(dense_records(seq, spec, calls, lambda: make_dense_associator("projective", **gate_params(spec))))
    out = pd.DataFrame(rows)
    failed = out[out["error"].fillna("") != ""] if "error" in out else out.iloc[:0]
    if len(failed):   # held poses and a failed call's time would read as ICP failures and as the loop's cost
        raise SystemExit(f"dense_flat.py: the method failed on {len(failed)} of {len(out)} frames (first, frame "
                         f"{int(failed['frame'].iloc[0])}: {failed['error'].iloc[0]}): the loop was not measured")
    out["stages_ms"] = 1000 * out[list(STAGES)].fillna(0).sum(axis=1)
    out["map_ms"] = 1000 * out[["predict_s", "fusion_s"]].fillna(0).sum(axis=1)   # the stages that read the map
    return out


def fit(rec: pd.DataFrame, column: str) -> tuple[float, float, float | None, float]:
    """Least squares ``column = a + b · visited/1e5 + c · map/1e5`` over the frames after the first
    (the map's size before the frame's fusion): (a ms, b and c ms per 100k points, the residual's
    standard deviation ms). Where the splat visited the whole map (no index) the two columns are
    one: ``c`` is None and ``b`` their one slope (a least-norm split would print it halved twice)."""
    part = rec.iloc[1:]
    visited, before = part["predict_visited"].to_numpy() / 1e5, rec["map_points"].shift(1).iloc[1:].to_numpy() / 1e5
    one = np.array_equal(visited, before)
    A = np.column_stack([np.ones(len(part)), visited] + ([] if one else [before]))
    coef, *_ = np.linalg.lstsq(A, part[column].to_numpy(), rcond=None)
    resid = part[column].to_numpy() - A @ coef
    return float(coef[0]), float(coef[1]), None if one else float(coef[2]), float(np.std(resid))


def signed(value: float, digits: int, gap: str = "") -> str:
    """``value`` to ``digits`` decimals with its sign as a typeset "+" or "−" (``gap`` after it):
    "+ -0.5" and "-58 %" read badly beside each other. A value that rounds to zero is "+"."""
    return f"{'+' if round(value, digits) >= 0 else '−'}{gap}{abs(value):.{digits}f}"


def fit_line(label: str, what: str, rec: pd.DataFrame, column: str) -> str:
    """One fit as a sentence with its units and the ranges it was fitted over (a short run's
    narrow range gives slopes that mean nothing: read the residual beside them)."""
    a, b, c, sd = fit(rec, column)
    fitted, unknowns = len(rec) - 1, 2 if c is None else 3
    if fitted <= unknowns:   # the line passes through every point: residual 0.00, slopes meaningless
        return (f"fit {label}, {what}: not fitted, {fitted} frames after the first for {unknowns} unknowns "
                f"(more --frames)")
    span = (f"over {rec['predict_visited'].iloc[1:].min() / 1000:.0f}k-{rec['predict_visited'].max() / 1000:.0f}k "
            f"visited, map {rec['map_points'].min() / 1000:.0f}k-{rec['map_points'].max() / 1000:.0f}k")
    slopes = (f"{signed(b, 2, ' ')} ms per 100k map points (visited = the whole map)" if c is None else
              f"{signed(b, 2, ' ')} ms per 100k points visited {signed(c, 2, ' ')} ms per 100k map points")
    return f"fit {label}, {what}: ms = {a:.1f} {slopes}; residual sd {sd:.2f} ms, {span}"


def band_rows(order: np.ndarray, frames: int, band: int, ours: pd.DataFrame, whole: pd.DataFrame) -> list[list]:
    """One row per band of path frames: out and back, map size, visited, on a pixel, ms with and
    without the index."""
    leg = np.where(np.arange(len(order)) < frames, "out", "back")
    rows = []
    for lo in range(0, frames, band):
        cells = [f"{lo}-{min(lo + band, frames) - 1}"]
        for name in ("out", "back"):
            pick = (order >= lo) & (order < lo + band) & (leg == name) & (np.arange(len(order)) > 0)
            a, b = ours[pick], whole[pick]
            cells += [f"{a['map_points'].median() / 1000:.0f}k", f"{a['predict_visited'].median() / 1000:.0f}k",
                      f"{a['fusion_considered'].median() / 1000:.0f}k",
                      a["stages_ms"].median(), a["map_ms"].median(), b["map_ms"].median()]
        rows.append(cells)
    return rows


def growth_line(order: np.ndarray, frames: int, band: int, ours: pd.DataFrame, whole: pd.DataFrame) -> str:
    """The question the script asks, in one line: on the way out, from the first band of the path
    (frames 1 .. max(band, 2) - 1, frame 0 left out: it fuses the first map and tracks nothing) to
    its last (frames N - band .. N - 1), medians, how much the map grew and how much a frame's cost
    did, with the index and without it (the baseline whose cost follows the map). Bands that share
    a frame (``2 · band > N``, or N = 2) measure no growth: the line says so, not "x1.0, +0 %"."""
    lo, hi = max(band, 2) - 1, max(frames - band, 1)
    if lo >= hi:
        hint = "more --frames" if frames < 3 else f"--band at most {frames // 2}"
        return (f"growth on the way out: not measured, the first and last bands of {band} path frames share "
                f"frames of the {frames} ({hint})")
    out = (np.arange(len(order)) < frames) & (np.arange(len(order)) > 0)
    first, last = out & (order <= lo), out & (order >= hi)
    med = lambda rec, pick, col: float(rec.loc[pick, col].median())  # noqa: E731
    grow = lambda rec, col: (f"{med(rec, first, col):.1f} -> {med(rec, last, col):.1f} ms "  # noqa: E731
                             f"({signed(100 * (med(rec, last, col) / med(rec, first, col) - 1), 0)} %)")
    m0, m1 = med(ours, first, "map_points"), med(ours, last, "map_points")
    return (f"growth on the way out, path frames 1-{lo} -> {hi}-{frames - 1} (medians): the map {m0 / 1000:.0f}k -> "
            f"{m1 / 1000:.0f}k points (x{m1 / m0:.1f}); with the index, stages {grow(ours, 'stages_ms')}, splat + "
            f"fusion {grow(ours, 'map_ms')}; without it, stages {grow(whole, 'stages_ms')}, splat + fusion "
            f"{grow(whole, 'map_ms')}")


def accuracy_line(rec: pd.DataFrame) -> str:
    """The loop's accuracy, the baseline a change to the map's density is judged against: ATE over
    every frame (frame 0 given; a failed frame's held pose counted), ICP failures, and the map's
    error to the true surfaces at the end (mm). The ATE is a run's ``ate_mm`` over the loop's
    2N-1 frames: over its first N it is what ``assocbench run`` with the same settings reports for
    the path's N frames (1.30 mm both at ``--frames 30``), the way back adds the second pass."""
    _, p_true = poses(rec, "true_")
    _, p_est = poses(rec, "est_")
    last = rec.iloc[-1]
    return (f"accuracy with the index: ATE {1000 * ate_rmse(p_true, p_est):.2f} mm over {len(rec)} frames, "
            f"{int(rec['icp_failed'].sum())} ICP failures, the map {int(last['map_points']):,} points, "
            f"{last['map_median_mm']:.2f} / {last['map_p95_mm']:.2f} mm (median / p95) off the true surfaces")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=500, help="the path's frames (the loop runs 2N-1)")
    ap.add_argument("--band", type=int, default=100, help="path frames a row")
    ap.add_argument("--scene", default="crates")
    args = ap.parse_args()
    if args.frames < 2 or args.band < 1:
        ap.error(f"--frames must be at least 2 and --band at least 1, got {args.frames} and {args.band}")
    try:
        measure(args)
    except UserError as exc:   # a bad --scene: one line, as the CLI says it
        ap.error(str(exc))


def measure(args: argparse.Namespace) -> None:
    """Both loops over the path out and back, the table and the fits."""
    seq, order = there_and_back(render_once(args.scene, args.frames), args.frames)   # a bad --scene fails here
    print(f"load average {load()} on {os.cpu_count()} cores (the machine is shared: timings are noisy)")
    warm_dense()
    start = time.perf_counter()
    ours = records(seq, args.scene, args.frames, [])
    ours_s = time.perf_counter() - start
    start = time.perf_counter()
    whole = records(seq, args.scene, args.frames, ["dense.index=false"])
    whole_s = time.perf_counter() - start
    same = all(np.array_equal(ours[c].to_numpy(), whole[c].to_numpy(), equal_nan=True)
               for c in ("est_x", "est_y", "est_z", "map_points", "pairs"))
    print(f"{len(seq)} frames ({args.frames} out, {args.frames - 1} back): the loop took {ours_s:.1f} s with the "
          f"index, {whole_s:.1f} s without; the same poses, pairs and map sizes: {same}; ICP failures "
          f"{int(ours['icp_failed'].sum())}")
    print_table(["path frames", "out: map (points)", "visited", "on a pixel", "stages (ms)", "splat + fusion (ms)",
                 "no index (ms)", "back: map (points)", "visited", "on a pixel", "stages (ms)", "splat + fusion (ms)",
                 "no index (ms)"], band_rows(order, args.frames, args.band, ours, whole))
    print(growth_line(order, args.frames, args.band, ours, whole))
    print(accuracy_line(ours))
    for label, rec in (("with the index", ours), ("without the index (baseline)", whole)):
        for column, what in (("stages_ms", "stages"), ("map_ms", "splat + fusion")):
            print(fit_line(label, what, rec, column))
    print(f"load after {load()}")


if __name__ == "__main__":
    run_recorded(main)
