"""The planar track's own settings section: ``posts`` (how posts are detected in a scan)."""

from __future__ import annotations

from dataclasses import dataclass, field

from ...validation import in_range, validate_fields


@dataclass(frozen=True)
class PostDetectorConfig:
    """Post detector settings (section ``posts``).

    min_points: fewest hit points a post needs (a 3-point fit of known radius has one redundant
        point, and its covariance made SLAM with the true association overconfident on the park; 4
        does not).
    gap: largest distance between consecutive hit points of one cluster (m; null: the posts'
        diameter).
    max_rms: largest residual RMS of an accepted fit (m; 3 cm is 3σ of the default range noise).
    min_share: share of a detection's beams that must hit one post for it to be labelled with it.
    """

    min_points: int = field(default=4, metadata=in_range(3, 10000, unit="points"))   # 2 points fit any circle: no residual
    gap: float | None = field(default=None, metadata=in_range(0, 100, lo_open=True, unit="m"))
    max_rms: float = field(default=0.03, metadata=in_range(0, 10, lo_open=True, unit="m"))
    min_share: float = field(default=0.8, metadata=in_range(0.5, 1, lo_open=True, unit="dimensionless"))

    def __post_init__(self) -> None:
        validate_fields(self, "posts")
