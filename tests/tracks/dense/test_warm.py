"""The dense kernels are warmed before a run is timed: after ``warm_dense`` a short run (every
prediction and tracking mode) compiles no new version of any dense kernel (a first frame that
compiles is slow, and its time would be counted as the method's)."""

from __future__ import annotations

import pytest

from assocbench.associators.dense import make_dense_associator, projective
from assocbench.harness.config import load_run_config, run_spec
from assocbench.harness.runner import GuardedCalls
from assocbench.models import depth_frame
from assocbench.tracks.dense import (
    depth_sensor,
    depth_smoothing,
    fusion,
    icp,
    metrics,
    prediction,
    sensor_passes,
    surface,
)
from assocbench.tracks.dense.run import dense_records
from assocbench.tracks.dense.sequence import load_dense_sequence
from assocbench.tracks.dense.warm import warm_dense

MODULES = (depth_frame, depth_sensor, depth_smoothing, sensor_passes, fusion, icp, metrics, prediction, surface,
           projective)


def versions() -> dict:
    """Compiled versions (signatures) of every numba kernel of the dense modules."""
    return {(m.__name__, name): len(k.signatures) for m in MODULES for name, k in vars(m).items()
            if hasattr(k, "signatures")}


@pytest.mark.parametrize("sets", [["dense.prediction=view"], ["dense.prediction=map"], ["dense.tracking=frame"],
                                  ["dense.prediction=view", "dense.index=false"]])
def test_a_run_after_warm_up_compiles_nothing(sets):
    warm_dense()
    cfg = load_run_config(None, ["resolution=[320,240]", "depth.downsample=1", *sets], method="projective",
                          scene="crates", frames=4)
    spec = run_spec(cfg)
    seq = load_dense_sequence(spec.source.spec)
    before = versions()
    records = list(dense_records(seq, spec, GuardedCalls(spec.time_limit_s, {}, lambda k, limit: None),
                                 lambda: make_dense_associator("projective"), 0, None))
    assert len(records) == 4 and not any(r["error"] for r in records)
    grown = {key: n for key, n in versions().items() if n != before.get(key)}
    assert not grown, f"compiled during the run, not in warm_dense: {grown}"
