"""Making a lidar sequence holds no per-frame scan (issue 26 item 19): a 720-beam scan is ~23 KB,
and holding every one made a long lines or planar run's memory grow by that much a frame. The
peak traced while making a sequence of 4N frames exceeds that of N frames by little more than the
sequence itself (its lines or posts, a few hundred bytes to ~1 KB a frame)."""

from __future__ import annotations

import tracemalloc

import pytest

from assocbench.tracks.lines.sequence import LineSequenceSpec, make_line_sequence, warm_extraction
from assocbench.tracks.lines.settings import LineExtractorConfig
from assocbench.tracks.planar.sequence import PlanarSequenceSpec, make_planar_sequence

SHORT, LONG = 20, 80
BOUND = 4_000   # bytes a frame the peak may grow by (the sequence keeps ~1 KB; every scan held was ~24 KB)


def traced_peak(make, spec) -> int:
    """Peak bytes traced while ``make(spec)`` runs."""
    tracemalloc.start()
    try:
        make(spec)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("make,spec", [
    (make_line_sequence, lambda n: LineSequenceSpec(scene="hallway", frames=n,
                                                    lines=LineExtractorConfig(method="split_merge"))),
    (make_planar_sequence, lambda n: PlanarSequenceSpec(scene="park", frames=n)),
], ids=["lines", "planar"])
def test_the_peak_while_making_a_sequence_grows_by_its_content_not_its_scans(make, spec):
    warm_extraction()   # kernels loaded outside the traced part
    make(spec(2))
    short, long = traced_peak(make, spec(SHORT)), traced_peak(make, spec(LONG))
    per_frame = (long - short) / (LONG - SHORT)
    assert per_frame < BOUND, f"peak grows {per_frame:.0f} B a frame"


def test_a_kept_scan_sequence_still_keeps_them():
    seq = make_line_sequence(LineSequenceSpec(scene="hallway", frames=3, keep_scans=True))
    assert len(seq.scans) == 3 and seq.final_points.shape == (len(seq.scans[-1].angles), 2)
