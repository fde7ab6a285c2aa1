"""Lidar scans per second on one core: scan (``mj_multiRay`` + noise), post detection (segment,
circle fits, range-bearing covariance) and labelling, on the park scene along its loop.

Columns (per second, median over ``--repeats`` runs of ``--frames`` poses each):

* ``scan``: ``lidar.scan`` alone (one ``mj_multiRay`` call for all beams, noise, dropout);
* ``detect``: ``detect_posts`` on stored scans; ``label``: ``label_detections`` on them;
* ``scan+detect``: both in turn, the sensor's rate (target >= 2000 at 360 beams);
* ``frame``: what ``make_planar_sequence`` does per frame (rng, scan, detect, label, visibility);
* ``geometric``: the geometric mode's frame (``geometric_detections``: one ray per post).

Usage: python benchmarks/lidar_rate.py [--repeats 7] [--frames 200] [--beams 360 720]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _util import print_table, run_recorded

from assocbench.sim.lidar import scan
from assocbench.sim.planar_scene import load_planar_scene
from assocbench.sim.planar_trajectory import planar_trajectory
from assocbench.sim.settings import LidarConfig
from assocbench.tracks.planar.geometric_sensor import geometric_detections
from assocbench.tracks.planar.post_detect import detect_posts, label_detections
from assocbench.tracks.planar.sequence import PlanarSequenceSpec, lidar_frame
from assocbench.tracks.planar.settings import PostDetectorConfig


def rate(fn, items) -> float:
    """Calls per second of ``fn`` over ``items``."""
    start = time.perf_counter()
    for it in items:
        fn(it)
    return len(items) / (time.perf_counter() - start)


def run_once(scene, poses, beams: int) -> dict[str, float]:
    cfg, pc = LidarConfig(beams=beams), PostDetectorConfig()
    spec = PlanarSequenceSpec(scene="park", lidar=cfg, posts=pc)
    rngs = [np.random.default_rng([0, k, 21]) for k in range(len(poses))]
    scans = [scan(scene, p, cfg, r) for p, r in zip(poses, rngs)]
    dets = [detect_posts(s, scene.post_radius, cfg.sigma_range, pc) for s in scans]
    out = {
        "scan": rate(lambda k: scan(scene, poses[k], cfg, rngs[k]), range(len(poses))),
        "detect": rate(lambda s: detect_posts(s, scene.post_radius, cfg.sigma_range, pc), scans),
        "label": rate(lambda k: label_detections(dets[k], scans[k], scene.post_geom_ids), range(len(poses))),
        "scan+detect": rate(lambda k: detect_posts(scan(scene, poses[k], cfg, rngs[k]), scene.post_radius,
                                                   cfg.sigma_range, pc), range(len(poses))),
        "frame": rate(lambda k: lidar_frame(scene, poses[k], spec, np.random.default_rng([0, k, 21])),
                      range(len(poses))),
    }
    geo = LidarConfig(mode="geometric")
    out["geometric"] = rate(lambda k: geometric_detections(scene, poses[k], geo, np.random.default_rng([0, k, 21])),
                            range(len(poses)))
    out["detections"] = float(np.mean([len(d) for d in dets]))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--beams", type=int, nargs="+", default=[360, 720])
    args = ap.parse_args()
    scene = load_planar_scene("park")
    poses = planar_trajectory(scene, None, args.frames, 0)
    keys = ["scan", "detect", "label", "scan+detect", "frame", "geometric", "detections"]
    rows = []
    for beams in args.beams:
        runs = [run_once(scene, poses, beams) for _ in range(args.repeats)]
        rows.append([beams] + [float(np.median([r[k] for r in runs])) for k in keys])
    print(f"park, {args.frames} poses along the loop, median of {args.repeats} runs; calls per second, one core")
    print_table(["beams"] + [f"{k}/s" if k != "detections" else "posts/scan" for k in keys],
                [[r[0]] + [f"{v:.0f}" if i < 6 else f"{v:.1f}" for i, v in enumerate(r[1:])] for r in rows])


if __name__ == "__main__":
    run_recorded(main)
