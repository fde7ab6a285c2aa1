"""The lines track's own settings section: ``lines`` (how lines are extracted from a scan)."""

from __future__ import annotations

from dataclasses import dataclass, field

from ...validation import in_range, one_of, validate_fields

METHODS = ("polar", "split_merge", "ransac")


@dataclass(frozen=True)
class LineExtractorConfig:
    """Line extractor settings (section ``lines``); null thresholds scale with the range noise σ.

    method: polar | split_merge | ransac.
    min_points: fewest beams of a line (>= 3: two points always fit); the default leaves out short
        lines biased by a neighbouring face's beams (a door jamb, a pillar), which made the
        extraction's NEES too large.
    min_length: shortest segment kept (m).
    breakpoint_distance / breakpoint_angle_deg: the adaptive breakpoint's margin d₀ (m, null 10σ)
        and angle λ (deg).
    split_distance: split-and-merge's chord distance (m, null 6σ).
    max_rms: largest RMS orthogonal residual of a kept fit (m, null 2σ).
    merge_chi2: χ² bound (2 dof) of a collinear merge (13.8: 99.9 %).
    merge_gap: largest gap between merged segments (m).
    ransac_iterations: hypotheses per extracted line.
    inlier_distance: RANSAC inlier band (m, null 3σ).
    max_lines: most lines per scan.
    min_share: share of a line's beams on one map line for it to be labelled with it.
    """

    method: str = field(default="split_merge", metadata=one_of(*METHODS))
    min_points: int = field(default=16, metadata=in_range(3, 100000, unit="beams"))
    min_length: float = field(default=0.3, metadata=in_range(0, 1000, unit="m"))
    breakpoint_distance: float | None = field(default=None, metadata=in_range(0, 100, lo_open=True, unit="m"))
    breakpoint_angle_deg: float = field(default=10.0, metadata=in_range(0, 90, lo_open=True, hi_open=True, unit="deg"))
    split_distance: float | None = field(default=None, metadata=in_range(0, 100, lo_open=True, unit="m"))
    max_rms: float | None = field(default=None, metadata=in_range(0, 100, lo_open=True, unit="m"))
    merge_chi2: float = field(default=13.8, metadata=in_range(0, 1e6, unit="dimensionless"))
    merge_gap: float = field(default=2.0, metadata=in_range(0, 1000, unit="m"))
    ransac_iterations: int = field(default=100, metadata=in_range(1, 100000, unit="hypotheses"))
    inlier_distance: float | None = field(default=None, metadata=in_range(0, 100, lo_open=True, unit="m"))
    max_lines: int = field(default=30, metadata=in_range(1, 10000, unit="lines per scan"))
    min_share: float = field(default=0.8, metadata=in_range(0.5, 1, lo_open=True, unit="dimensionless"))

    def __post_init__(self) -> None:
        validate_fields(self, "lines")
