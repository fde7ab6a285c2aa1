"""The photos track's settings: the belief in the reconstruction's units, and matching views to
keypoints."""

from __future__ import annotations

from dataclasses import dataclass, field

from ...belief.config import BeliefConfig
from ...validation import in_range, validate_fields


@dataclass(frozen=True)
class PhotoBelief(BeliefConfig):
    """Difficulty knobs of the belief: the bundle's camera and map perturbed by an error drawn from
    ``k² Σ`` while Σ is reported. Lengths are in the bundle's own units (Bundler fixes no scale; on
    Balbianello 0.01 unit moves a projection by about 2 px).

    sigma_position: camera centre std (bundle units).
    sigma_rotation: camera orientation std (deg).
    sigma_landmark: independent landmark position std (bundle units).
    sigma_common: std of an error shared by all landmarks (bundle units): correlated map error.
    sigma_pixel: reported keypoint noise std (px); R_i = σ² I. The bundle's projections lie about
        half a pixel RMS from their keypoints on Balbianello.
    miscalibration: k; the actual error is drawn from k²Σ while Σ is reported.
    map_fraction: share of the landmarks that are in the map (the others' keypoints are clutter).
    """

    sigma_position: float = field(default=0.005, metadata=in_range(0))
    sigma_rotation: float = field(default=0.1, metadata=in_range(0, 90))
    sigma_landmark: float = field(default=0.002, metadata=in_range(0))
    sigma_pixel: float = field(default=0.5, metadata=in_range(0, lo_open=True))


@dataclass(frozen=True)
class PhotoSettings:
    """Section ``photos``: how the reference is read from the reconstruction.

    match_radius: a view is paired with the nearest keypoint of its image within this distance (px),
        one-to-one; points whose views agree within it are one landmark.
    """

    match_radius: float = field(default=1.5, metadata=in_range(0, 10, lo_open=True) | {"unit": "px"})

    def __post_init__(self) -> None:
        validate_fields(self, "photos")
