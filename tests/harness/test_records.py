"""A run's per-frame records are streamed (issue 26 item 19): the parent writes each record to
disk as its worker sends it and keeps only where it starts, so what it holds does not grow with
the records; the table read back is the one ``pd.DataFrame(records)`` would have made."""

from __future__ import annotations

import errno
import io
import tracemalloc
from collections import deque

import numpy as np
import pandas as pd
import pytest

from assocbench.errors import UserError
from assocbench.harness import records
from assocbench.harness.records import RecordSpool, frame_table
from assocbench.harness.sandbox import Supervisor, _Progress, _Running

FRAMES = 1500
PAYLOAD = 8_000   # bytes a record: a closed loop's ~60 columns held as a dict cost about that


class _Worker:
    """What ``Supervisor._step`` reads of a worker: a pipe whose frames are made as they are read
    (so the test itself holds none), and a process that is alive."""

    def __init__(self, n: int) -> None:
        self.msgs = (("frame", 0, 0, k, {"frame": k, "payload": "x" * PAYLOAD, "error": ""}) for k in range(n))
        self.next = deque([next(self.msgs)])

    def poll(self) -> bool:
        return bool(self.next)

    def recv(self):
        msg = self.next.popleft()
        self.next.extend([m for m in [next(self.msgs, None)] if m is not None])
        return msg

    def is_alive(self) -> bool:
        return True


def test_the_parent_holds_no_record_while_a_run_streams_in():
    worker = _Worker(FRAMES)
    w = _Running(task=None, progress=_Progress(), process=worker, conn=worker)
    tracemalloc.start()
    try:
        assert Supervisor(1)._step(w) is None   # reads every frame sent, the run still going
        held = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert held < 0.1 * FRAMES * PAYLOAD, f"{held} bytes traced for {FRAMES} records"   # held: 12 MB
    spool = w.progress.records[(0, 0)]
    assert len(spool) == FRAMES and [r["frame"] for r in spool] == list(range(FRAMES))
    spool.close()


def test_a_frame_sent_again_counts_once_with_its_last_record():
    spool = RecordSpool()
    for k, err in [(0, ""), (2, ""), (1, "first"), (1, "again")]:
        spool.add(k, {"frame": k, "error": err})
    assert [(r["frame"], r["error"]) for r in spool] == [(0, ""), (1, "again"), (2, "")]
    assert len(spool) == 3
    spool.close()


RECORDS = [   # columns that come and go as a run's do: failed frames, the last frame's map, NaN
    {"frame": 0, "tp": 3, "perfect": True, "nees": np.nan, "error": "", "association": [0, -1]},
    {"frame": 1, "tp": 2, "perfect": False, "nees": 1.5, "error": "", "association": [1], "new_landmarks": 2},
    {"frame": 2, "tp": 0, "error": "TimeLimit: 1 s", "association": []},
    {"frame": 3, "tp": 1, "perfect": True, "nees": 2.0, "error": "", "association": [0], "new_landmarks": 0},
    {"frame": 4, "tp": 1, "perfect": True, "nees": 2.5, "error": "", "association": [0], "final_map": "[[1, 2]]"},
]


@pytest.mark.parametrize("chunk", [1, 2, 3, 256])
def test_the_table_read_in_pieces_is_the_one_table(monkeypatch, chunk):
    monkeypatch.setattr(records, "CHUNK", chunk)
    one, pieces = pd.DataFrame(RECORDS), frame_table(iter(RECORDS))
    assert list(pieces.columns) == list(one.columns) and pieces.dtypes.equals(one.dtypes)
    assert pieces.to_csv(index=False) == one.to_csv(index=False)
    assert "association" not in frame_table(RECORDS, drop=("association",))


def test_a_full_temporary_folder_is_one_line_naming_it(monkeypatch):
    spool = RecordSpool()

    def full(*args, **kwargs):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(records.pickle, "dump", full)
    with pytest.raises(UserError, match=r"^cannot write the run's per-frame records to the temporary folder .*"
                                         r"No space left on device.*TMPDIR"):
        spool.add(0, {"frame": 0})
    assert len(spool) == 0   # nothing half-recorded
    spool.close()


class _FullDisk(io.RawIOBase):
    """A file on a full disk: writes fail with ENOSPC (reads and seeks work)."""

    def readable(self) -> bool:
        return True

    def writable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def seek(self, offset: int, whence: int = 0) -> int:
        return 0

    def write(self, data) -> int:
        raise OSError(errno.ENOSPC, "No space left on device")


def test_a_temporary_folder_that_fills_during_a_run_is_one_line(monkeypatch, tmp_path, capsys):
    """Reproduction: TMPDIR full during `assocbench run --scene park --frames 300`: the spool's add
    raised the one-line UserError, then closing the spool in the supervisor's `finally` flushed its
    buffer, raised ENOSPC again and replaced the error with a traceback."""
    from cli_errors import assert_one_line_error

    from assocbench.cli.main import main

    monkeypatch.setattr(records.tempfile, "TemporaryFile", lambda **kw: io.BufferedRandom(_FullDisk()))
    code = main(["run", "--scene", "park", "--frames", "60", "--method", "mnn", "--out", str(tmp_path / "run")])
    assert_one_line_error(capsys, code, "cannot write the run's per-frame records", "No space left on device", "TMPDIR")
    assert not (tmp_path / "run").exists()
