"""Replay a recorded run in this process, for pictures (``assocbench render``). The open loop's
problems are rebuilt from the belief's seeded errors; in the closed loop the recorded associations
are fed back through ``ClosedLoop.begin``/``finish``, rebuilding each problem and filter without
calling the method (a failed frame replayed as a failure). The filter is deterministic, so a drift
beyond ``REPLAY_TOLERANCE_M`` from the recorded estimate is reported on stderr.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator

import numpy as np
import pandas as pd

from ..tracks.capabilities import RunFrame
from .config import RunSpec
from .loop import ClosedLoop, EstimatorFailed, recorded_answer
from .runner import Problems

REPLAY_TOLERANCE_M = 1e-6   # the replayed filter must put the sensor where the run did
POSITION_COLUMNS = ("est_x", "est_y", "est_z")


def replay_run(spec: RunSpec, records: pd.DataFrame) -> Iterator[RunFrame]:
    """The recorded frames of ``spec``'s run (``records`` with an ``association`` column, from
    ``execute(spec, associations=True)``), in order."""
    rows = {int(r["frame"]): r for r in records.to_dict("records")}
    yield from (_closed_loop if spec.loop else _open_loop)(spec, rows)


def _shown(association, n: int) -> np.ndarray:
    """The recorded association as drawn: all −1 where none was recorded (a failed frame)."""
    if association is None or (not isinstance(association, (list, np.ndarray)) and pd.isna(association)):
        return np.full(n, -1, np.int64)
    return np.asarray(association, np.int64)


def _open_loop(spec: RunSpec, rows: dict) -> Iterator[RunFrame]:
    problems = Problems(spec.track_impl, spec.source, spec)
    for k, row in sorted(rows.items()):
        problem, truth = problems[k]
        yield RunFrame(k, problem, truth, _shown(row.get("association"), problem.n), row.get("error") or "", row)


def _closed_loop(spec: RunSpec, rows: dict) -> Iterator[RunFrame]:
    recorded = {k: (r.get("association"), r.get("error") or "") for k, r in rows.items()}
    try:
        loop = ClosedLoop(spec.source, spec)
    except EstimatorFailed:   # the run's estimator failed at its start: nothing to draw
        return
    warned = False
    for k in range(len(spec.source)):
        try:
            problem, truth = loop.begin(k)
            answer = recorded_answer(recorded, k)
            replayed = loop.finish(*answer)
        except EstimatorFailed:   # where the run's estimator failed too: its later frames have no pose
            return
        if k not in rows:
            continue
        row = rows[k]
        drift = _drift(replayed, row)
        if drift > REPLAY_TOLERANCE_M and not warned:
            print(f"assocbench: warning: the replayed filter is {drift:.3g} m from the run's estimate at frame {k}; "
                  f"the picture shows the replay", file=sys.stderr)
            warned = True
        # the association is drawn even when the frame failed after it (a filter update that failed)
        yield RunFrame(k, problem, truth, _shown(row.get("association"), problem.n), answer[3], row, loop.filter)


def _drift(replayed: dict, recorded: dict) -> float:
    """Distance (m) between the replayed and the recorded estimate of the frame's position."""
    cols = [c for c in POSITION_COLUMNS if c in replayed and c in recorded]
    return float(np.linalg.norm([replayed[c] - recorded[c] for c in cols])) if cols else 0.0
