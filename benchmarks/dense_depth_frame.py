"""The dense track's depth frame (``DenseSequence.frame``: noise, drops, vertex map, truth, the
edge-aware smoothing, normals and edge mask) at 320x240 on one core, against the implementation it
replaced, kept in this script as the baseline (the numpy steps, the per-pixel smoothing loop, the
``DepthConfig`` rebuilt per frame) and timed in the same run, frame by frame in alternating order.

Columns (ms per frame, median over the frames of ``--frames`` of each scene, seed 0):
``depth frame`` the whole call; ``draws`` the two RNG calls alone (the same in both; a floor);
``smoothing`` the edge-aware Gaussian alone, on the frame's own noisy depth and gate;
``page faults``: median minor page faults of the timed call (a fresh 4 kB page first written; on
a shared VM about 1 µs each, and their count depends on what the allocator kept from the call before).
``bit-identical`` checks every output (depth, vertices, normals, true_points, geom, valid) of the
two on every frame of seeds 0 and 1 of both scenes (``np.array_equal(..., equal_nan=True)``).

Usage: python benchmarks/dense_depth_frame.py [--frames 40] [--scenes crates bays]
"""

from __future__ import annotations

import argparse
import os
import resource
import time
from dataclasses import replace

for _var in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):   # one core, before numpy/numba
    os.environ.setdefault(_var, "1")
os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
from _util import print_table, run_recorded  # noqa: E402
from numba import njit  # noqa: E402

from assocbench.harness.config import load_run_config, run_spec  # noqa: E402
from assocbench.models.depth_frame import NO_GEOM, DepthFrame, vertex_map  # noqa: E402
from assocbench.tracks.dense.depth_smoothing import depth_gate, edge_aware_smoothed  # noqa: E402
from assocbench.tracks.dense.sequence import load_dense_sequence  # noqa: E402

FIELDS = ("depth", "vertices", "normals", "true_points", "geom", "valid")


# ---- the baseline: the implementation before the compiled passes, as it was ----------------------

@njit(cache=False, error_model="numpy")
def _grazing_kernel(V):
    h, w = V.shape[0], V.shape[1]
    out = np.empty((h, w))
    for v in range(h):
        r = min(v, h - 2)
        for u in range(w):
            c = min(u, w - 2)
            dx0, dx1, dx2 = V[r, c + 1, 0] - V[r, c, 0], V[r, c + 1, 1] - V[r, c, 1], V[r, c + 1, 2] - V[r, c, 2]
            dy0, dy1, dy2 = V[r + 1, c, 0] - V[r, c, 0], V[r + 1, c, 1] - V[r, c, 1], V[r + 1, c, 2] - V[r, c, 2]
            cx = dy1 * dx2 - dy2 * dx1
            cy = dy2 * dx0 - dy0 * dx2
            cz = dy0 * dx1 - dy1 * dx0
            x, y, z = V[v, u, 0], V[v, u, 1], V[v, u, 2]
            out[v, u] = abs(cx * x + cy * y + cz * z) / np.sqrt((cx * cx + cy * cy + cz * cz) * (x * x + y * y + z * z))
    return out


@njit(cache=False)
def _row_pass(depth, gate, taps, radius):
    h, w = depth.shape
    num, den = np.zeros((h, w)), np.zeros((h, w))
    for v in range(h):
        row = depth[v]
        for u in range(w):
            d = row[u]
            if not np.isfinite(d):
                continue
            g = gate[v, u]
            s = t = 0.0
            for b in range(max(-radius, -u), min(radius, w - 1 - u) + 1):
                dj = row[u + b]
                ok = abs(dj - d) <= g
                wt = taps[b + radius] if ok else 0.0
                s += wt * dj if ok else 0.0
                t += wt
            num[v, u], den[v, u] = s, t
    return num, den


@njit(cache=False)
def _gated_gaussian(depth, gate, sigma_px, radius):
    h, w = depth.shape
    taps = np.empty(2 * radius + 1)
    for a in range(-radius, radius + 1):
        taps[a + radius] = np.exp(-(a * a) / (2.0 * sigma_px * sigma_px))
    num, den = _row_pass(depth, gate, taps, radius)
    out = np.full((h, w), np.nan)
    for v in range(h):
        a0, a1 = max(-radius, -v), min(radius, h - 1 - v)
        for u in range(w):
            d = depth[v, u]
            if not np.isfinite(d):
                continue
            g = gate[v, u]
            s = t = 0.0
            for a in range(a0, a1 + 1):
                if abs(depth[v + a, u] - d) <= g:
                    s += taps[a + radius] * num[v + a, u]
                    t += taps[a + radius] * den[v + a, u]
            out[v, u] = s / t
    return out


def baseline_smoothed(depth, sigma_px, gate):
    depth = np.ascontiguousarray(depth, dtype=np.float64)
    gate = np.ascontiguousarray(np.broadcast_to(gate, depth.shape), dtype=np.float64)
    return _gated_gaussian(depth, gate, float(sigma_px), int(np.ceil(2 * sigma_px)))


@njit(cache=False)
def _normals(V, out):
    h, w = V.shape[0], V.shape[1]
    out[:] = np.nan
    for v in range(1, h - 1):
        for u in range(1, w - 1):
            dx0, dx1, dx2 = V[v, u + 1, 0] - V[v, u - 1, 0], V[v, u + 1, 1] - V[v, u - 1, 1], V[v, u + 1, 2] - V[v, u - 1, 2]
            dy0, dy1, dy2 = V[v + 1, u, 0] - V[v - 1, u, 0], V[v + 1, u, 1] - V[v - 1, u, 1], V[v + 1, u, 2] - V[v - 1, u, 2]
            c0 = dy1 * dx2 - dy2 * dx1
            c1 = dy2 * dx0 - dy0 * dx2
            c2 = dy0 * dx1 - dy1 * dx0
            norm = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
            if norm > 0:
                out[v, u, 0], out[v, u, 1], out[v, u, 2] = c0 / norm, c1 / norm, c2 / norm


def baseline_normal_map(vertices):
    V = np.ascontiguousarray(vertices, dtype=np.float64)
    out = np.empty(V.shape)
    _normals(V, out)
    return out


def baseline_edges(depth, gate):
    edge = np.zeros(depth.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        for axis in (0, 1):
            jump = np.abs(np.diff(depth, axis=axis))
            lo, hi = [slice(None)] * 2, [slice(None)] * 2
            lo[axis], hi[axis] = slice(None, -1), slice(1, None)
            edge[tuple(lo)] |= jump > gate[tuple(lo)]
            edge[tuple(hi)] |= jump > gate[tuple(hi)]
    return edge


def baseline_depth_frame(depth_true, seg_geom, R, t, K, cfg, rng):
    """The former ``depth_frame`` at downsample 1 (``cfg`` rebuilt by the caller, as the sequence did)."""
    d_true = depth_true[::1, ::1][:K.height, :K.width].astype(np.float64)
    geom = seg_geom[::1, ::1][:K.height, :K.width].astype(np.int64)
    R, t = np.array(R, dtype=np.float64), np.array(t, dtype=np.float64)
    v_true = vertex_map(d_true, K)
    true_points = v_true @ R.T + t
    geom = np.where(np.isfinite(d_true), geom, NO_GEOM)
    depth = d_true + (cfg.sigma_base + cfg.sigma_quad * np.square(d_true)) * rng.standard_normal(d_true.shape)
    drop = _grazing_kernel(np.ascontiguousarray(v_true)) < np.cos(np.deg2rad(cfg.grazing_deg))
    if cfg.dropout > 0:
        drop |= rng.random(d_true.shape) < cfg.dropout
    with np.errstate(invalid="ignore"):
        drop |= ~((depth >= cfg.min_depth) & (depth <= cfg.max_depth))
    depth[drop] = np.nan
    vertices = vertex_map(depth, K)
    gate = 3.0 * (cfg.sigma_base + cfg.sigma_quad * np.square(depth)) + 0.02 * depth
    smooth = baseline_smoothed(depth, cfg.normal_smooth_px, gate) if cfg.normal_smooth_px > 0 else depth
    normals = baseline_normal_map(vertex_map(smooth, K))
    normals[~np.isfinite(depth) | baseline_edges(depth, gate)] = np.nan
    return DepthFrame(K, depth, vertices, normals, true_points, geom, R, t)


def baseline_frame(seq, k: int) -> DepthFrame:
    """The former ``DenseSequence.frame``."""
    cfg = replace(seq.depth_cfg, downsample=1)
    return baseline_depth_frame(seq.depths[k].astype(np.float64), seq.geoms[k], seq.rotations[k], seq.positions[k],
                                seq.K, cfg, np.random.default_rng([seq.seed, k, 17]))


# ---- the measurement ----------------------------------------------------------------------------

def sequence(scene: str, seed: int, frames: int):
    """The leaderboard's sequence of ``scene`` at 320x240 (rendered and cached when absent, untimed)."""
    sets = ["resolution=[320,240]", "depth.downsample=1", "dense.path_frames=200"]
    cfg = load_run_config(None, sets, method="projective", scene=scene, frames=frames, seed=seed)
    return load_dense_sequence(run_spec(cfg).source.spec)


def clock(fn) -> float:
    start = time.perf_counter()
    fn()
    return 1000 * (time.perf_counter() - start)


def clock_faults(fn) -> tuple[float, int]:
    """Wall time (ms) and minor page faults (fresh pages first written) of one call."""
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    ms = clock(fn)
    return ms, resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before


def timings(seq) -> list[float]:
    """Median ms per frame: new, baseline, draws, new smoothing, baseline smoothing; median page faults
    per frame: new, baseline."""
    cols = [[] for _ in range(7)]
    cfg = seq.depth_cfg
    for k in range(len(seq)):
        pair = [(0, lambda: seq.frame(k)), (1, lambda: baseline_frame(seq, k))]
        for i, fn in pair if k % 2 else pair[::-1]:   # alternate which goes first
            ms, n = clock_faults(fn)
            cols[i].append(ms)
            cols[5 + i].append(n)
        rng = np.random.default_rng([seq.seed, k, 17])
        cols[2].append(clock(lambda: rng.standard_normal(seq.depths[k].shape)))
        depth = seq.frame(k).depth
        gate = depth_gate(depth, cfg.sigma(depth))
        cols[3].append(clock(lambda: edge_aware_smoothed(depth, cfg.normal_smooth_px, gate)))
        cols[4].append(clock(lambda: baseline_smoothed(depth, cfg.normal_smooth_px, gate)))
    return [float(np.median(c)) for c in cols]


def identical(seqs) -> tuple[int, int, float]:
    """(arrays compared, arrays differing, largest |difference| of a differing array)."""
    n = bad = 0
    worst = 0.0
    for seq in seqs:
        for k in range(len(seq)):
            a, b = seq.frame(k), baseline_frame(seq, k)
            for name in FIELDS:
                x, y = np.asarray(getattr(a, name)), np.asarray(getattr(b, name))
                n += 1
                if not (x.dtype == y.dtype and np.array_equal(x, y, equal_nan=True)):
                    bad += 1
                    worst = max(worst, float(np.nanmax(np.abs(x.astype(float) - y.astype(float)))))
    return n, bad, worst


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--scenes", nargs="+", default=["crates", "bays"])
    args = ap.parse_args()
    seqs = {(scene, seed): sequence(scene, seed, args.frames) for scene in args.scenes for seed in (0, 1)}
    for seq in list(seqs.values())[:1]:   # compile (or load) both implementations' kernels, untimed
        seq.frame(0), baseline_frame(seq, 0)
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores before (a shared machine: timings are noisy)")
    rows = []
    for scene in args.scenes:
        new, old, draws, smooth_new, smooth_old, faults_new, faults_old = timings(seqs[scene, 0])
        rows.append([scene, args.frames, new, old, old / new, draws, smooth_new, smooth_old, int(faults_new),
                     int(faults_old)])
    print(f"320x240, one core, ms per frame (median over {args.frames} frames, seed 0)")
    print_table(["scene", "frames", "depth frame", "baseline", "speed-up", "draws", "smoothing", "baseline smoothing",
                 "page faults", "baseline page faults"], rows)
    n, bad, worst = identical(seqs.values())
    print(f"bit-identical: {n - bad} of {n} arrays ({len(seqs)} sequences x {args.frames} frames x {len(FIELDS)} "
          f"outputs){'' if not bad else f'; {bad} differ, by at most {worst:.3g}'}")
    print(f"load average {os.getloadavg()[0]:.1f} after")


if __name__ == "__main__":
    run_recorded(main)
