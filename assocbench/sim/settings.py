"""Settings several simulated tracks share: the path (``trajectory``, ``trajectory_params``), the
rendered image (``resolution``, ``msaa``) and the 2-D lidar (section ``lidar``)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import UserError
from ..validation import check_number, free_mapping, in_range, one_of, validate_fields

MIN_SIDE, MAX_SIDE = 16, 8192   # frame size in pixels: the smallest we render, the most GL contexts reliably offer
MAX_MSAA = 16
LIDAR_MODES = ("lidar", "geometric")


def check_msaa(msaa: int | None) -> None:
    """Raise a one-line ``UserError`` unless ``msaa`` is None or an integer in 0..16."""
    if msaa is not None and (isinstance(msaa, bool) or not isinstance(msaa, int) or not 0 <= msaa <= MAX_MSAA):
        raise UserError(f"msaa must be null (the scene's own setting) or an integer 0..{MAX_MSAA}, got {msaa!r}")


@dataclass(frozen=True)
class PathKeys:
    """The path through a simulated scene (top-level keys).

    trajectory: the path's name (`assocbench list trajectories`); null: the scene's default.
    trajectory_params: the trajectory's parameters, e.g. {file: path.csv} for waypoints.
    """

    trajectory: str | None = field(default=None, metadata={"accepts": "null or a trajectory of the track "
                                                                    "(assocbench list trajectories)"})
    trajectory_params: dict = field(default_factory=dict, metadata={"accepts": "a mapping (the trajectory's)"})

    def check(self) -> None:
        free_mapping({"trajectory_params": self.trajectory_params}, "trajectory_params")


@dataclass(frozen=True)
class ImageKeys:
    """The rendered image (top-level keys).

    resolution: [width, height] in pixels, each 16..8192 (and within the scene's offscreen buffer).
    msaa: offscreen multisamples, 0..16; null: the scene's own (4 in the shipped scenes); 0 is fastest.
    """

    resolution: list = field(default_factory=lambda: [640, 480],
                             metadata={"accepts": f"[width, height], integers {MIN_SIDE}..{MAX_SIDE}", "unit": "px"})
    msaa: int | None = field(default=None, metadata={"accepts": f"null or an integer 0..{MAX_MSAA}",
                                                     "unit": "samples per pixel"})

    def check(self) -> None:
        res = self.resolution
        if not (isinstance(res, (list, tuple)) and len(res) == 2):
            raise UserError(f"resolution must be [width, height] in pixels, got {res!r}")
        for name, value in zip(("width", "height"), res):
            check_number(value, f"resolution {name}", integer=True, lo=MIN_SIDE, hi=MAX_SIDE)
        check_msaa(self.msaa)


@dataclass(frozen=True)
class LidarConfig:
    """Lidar settings (section ``lidar``).

    mode: ``lidar`` (ray-cast scans and circle fits) or ``geometric`` (true range and bearing of
        every unoccluded post plus noise: fast and idealised).
    beams: beams per scan.
    fov_deg: field of view (deg), centred on the heading.
    max_range: farthest return (m).
    sigma_range: σ of each beam's range noise (m).
    sigma_bearing_deg: σ of the bearing noise in geometric mode (deg).
    dropout: probability that a beam (geometric mode: a post) returns nothing.
    height: height of the scan plane above the floor (m).
    """

    mode: str = field(default="lidar", metadata=one_of(*LIDAR_MODES))
    beams: int = field(default=720, metadata=in_range(1, 100000, unit="beams per scan"))
    fov_deg: float = field(default=360.0, metadata=in_range(0, 360, lo_open=True, unit="deg"))
    max_range: float = field(default=10.0, metadata=in_range(0, 1000, lo_open=True, unit="m"))
    # at least 1e-6 m: a range σ of 1e-300 squares to 0, a singular R (the worker crashed)
    sigma_range: float = field(default=0.01, metadata=in_range(1e-6, 10, unit="m"))
    # at least 1e-6 deg: a bearing σ below it squares to a covariance under numpy's tolerance
    sigma_bearing_deg: float = field(default=0.5, metadata=in_range(1e-6, 180, unit="deg"))
    dropout: float = field(default=0.0, metadata=in_range(0, 1, hi_open=True, unit="dimensionless"))
    height: float = field(default=0.5, metadata=in_range(0, 100, lo_open=True, unit="m"))

    def __post_init__(self) -> None:
        validate_fields(self, "lidar")

    @property
    def fov(self) -> float:
        """Field of view (rad)."""
        return float(np.deg2rad(self.fov_deg))

    @property
    def full_circle(self) -> bool:
        return self.fov_deg >= 360.0

    def angles(self) -> np.ndarray:
        """Beam angles (B,) in the robot frame, wrapped to (−π, π]."""
        if self.full_circle:
            a = 2 * np.pi * np.arange(self.beams) / self.beams
        elif self.beams == 1:
            a = np.zeros(1)
        else:
            a = np.linspace(-self.fov / 2, self.fov / 2, self.beams)
        return np.where(a > np.pi, a - 2 * np.pi, a)


