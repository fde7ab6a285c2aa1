"""Extraction quality of the lines track: each extraction method on each shipped lines scene.

Run: python examples/line_extraction_table.py [frames] [seed]   (default 500 frames, seed 0)

Prints a Markdown table (the README's): precision and recall of the true walls, RMS α and r
errors against the true line seen from the true pose, and the mean NEES of the fits' Σ (2 when
Σ describes the error: ``assocbench.tracks.lines.metrics``).
"""

import sys

from assocbench.sim.line_scene import load_line_scene
from assocbench.sim.scenegen.lines import LINE_SCENES
from assocbench.tracks.lines.metrics import extraction_scores
from assocbench.tracks.lines.sequence import LineSequenceSpec, make_line_sequence
from assocbench.tracks.lines.settings import METHODS, LineExtractorConfig


def main(frames: int = 500, seed: int = 0) -> None:
    print("| scene | method | precision | recall | α RMS (deg) | r RMS (mm) | NEES (2 ideal) | lines/frame |")
    print("|---|---|---|---|---|---|---|---|")
    for name in LINE_SCENES:
        scene = load_line_scene(name)
        for method in METHODS:
            spec = LineSequenceSpec(scene=name, frames=frames, seed=seed, lines=LineExtractorConfig(method=method))
            s = extraction_scores(make_line_sequence(spec, scene))
            print(f"| {name} | {method} | {s['precision']:.3f} | {s['recall']:.3f} | {s['alpha_rms_deg']:.3f} | "
                  f"{s['r_rms_mm']:.2f} | {s['nees']:.2f} | {s['lines_per_frame']:.1f} |")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
