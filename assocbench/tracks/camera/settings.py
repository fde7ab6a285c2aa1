"""The camera track's own settings sections: ``detector`` (which corners are found) and ``truth``
(how a feature is labelled with a landmark). Both enter the sequence cache key."""

from __future__ import annotations

from dataclasses import dataclass, field

from ...validation import in_range, one_of, validate_fields

DETECTORS = ("shi-tomasi", "fast", "orb")


@dataclass(frozen=True)
class DetectorConfig:
    """Detector settings; all of them enter the sequence cache key.

    method: ``shi-tomasi`` | ``fast`` | ``orb``.
    max_features: most features kept per frame (strongest first).
    quality: Shi-Tomasi quality level relative to the best corner.
    min_distance: smallest distance between two kept corners (px).
    subpix_window: half size of the ``cornerSubPix`` search window (px); 0 turns refinement off.
    noise_px: standard deviation of Gaussian pixel noise added after refinement (px).
    """

    method: str = field(default="shi-tomasi", metadata=one_of(*DETECTORS))
    max_features: int = field(default=400, metadata=in_range(1, 5000, unit="features per frame"))
    quality: float = field(default=0.02, metadata=in_range(0, 1, lo_open=True, unit="dimensionless"))
    min_distance: float = field(default=6.0, metadata=in_range(0, unit="px"))
    subpix_window: int = field(default=4, metadata=in_range(0, 32, unit="px"))
    noise_px: float = field(default=0.0, metadata=in_range(0, unit="px"))

    def __post_init__(self) -> None:
        validate_fields(self, "detector")


@dataclass(frozen=True)
class TruthConfig:
    """Settings of the truth labelling; all enter the sequence cache key.

    gate_px: a feature is labelled with a landmark when each is the other's nearest and
        they are closer than this (px).
    occlusion: ``ray`` (``mj_multiRay`` towards each landmark) or ``depth`` (rendered z-depth
        at the projection; one extra render pass).
    """

    gate_px: float = field(default=2.0, metadata=in_range(0, 50, lo_open=True, unit="px"))
    occlusion: str = field(default="ray", metadata=one_of("ray", "depth"))

    def __post_init__(self) -> None:
        validate_fields(self, "truth")
