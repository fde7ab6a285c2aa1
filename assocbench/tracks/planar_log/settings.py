"""The recorded range-bearing track's own settings section: ``log`` (how a log is read)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from ...validation import in_range, validate_fields

# the covariance factor that makes a shipped dataset's odometry consistent (docs/tracks/planar_log.md:
# python benchmarks/planar_log_odometry.py): Victoria Park's file covariance is right for one step, too tight over many
SHIPPED_ODOMETRY_SCALES = {"victoria_park": 11.0}


@dataclass(frozen=True)
class LogConfig:
    """Recorded log settings (section ``log``).

    odometry_scale: every odometry covariance is multiplied by this before the closed loop's
        estimator is told it (a variance factor); null: the shipped dataset's value, 1 for your own
        log. Victoria Park's file covariance fits one step but is too small over many (successive
        steps' errors are correlated), so its value makes 50-pose windows (the revisit gap)
        consistent (``benchmarks/planar_log_odometry.py``). The reference solution uses the file's
        own covariance.
    max_range: the sensor's range (m): candidates are the landmarks predicted within it; null: the
        log's farthest sighting.
    fov_deg: the sensor's field of view (deg), centred on the heading; null: twice the log's widest
        bearing plus 10 (at most 360).
    """

    odometry_scale: float | None = field(default=None, metadata=in_range(0, 1e6, lo_open=True, unit="dimensionless"))
    max_range: float | None = field(default=None, metadata=in_range(0, 1e4, lo_open=True, unit="m"))
    fov_deg: float | None = field(default=None, metadata=in_range(0, 360, lo_open=True, unit="deg"))

    def __post_init__(self) -> None:
        validate_fields(self, "log")

    def for_scene(self, scene: str) -> LogConfig:
        """These settings with ``odometry_scale`` resolved for ``scene`` (its shipped value, else 1)."""
        scale = self.odometry_scale if self.odometry_scale is not None else SHIPPED_ODOMETRY_SCALES.get(scene, 1.0)
        return replace(self, odometry_scale=scale)
