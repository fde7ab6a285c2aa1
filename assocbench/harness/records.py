"""Per-frame records on their way from a worker to a run's table, never all held at once. The parent
(``sandbox.Supervisor``) writes each record to a ``RecordSpool`` (an anonymous temporary file, one
pickle a record), keeping only each frame's offset; ``frame_table`` reads them back in frame order,
a chunk at a time, into the same ``DataFrame`` one ``pd.DataFrame(records)`` would make, column for
column and dtype for dtype.
"""

from __future__ import annotations

import pickle
import tempfile
from array import array
from collections.abc import Iterable, Iterator
from itertools import islice

import pandas as pd

from ..errors import UserError

CHUNK = 256   # records read back per piece of the table


class RecordSpool:
    """One run × method's records on disk in arrival order, read back in frame order (a frame sent
    twice counts once: its last record)."""

    def __init__(self) -> None:
        try:
            self._file = tempfile.TemporaryFile(prefix="assocbench-records-")
        except OSError as exc:
            raise _spool_error(exc) from None
        self._frames = array("q")    # frame of each record written
        self._offsets = array("q")   # where it starts in the file

    def add(self, frame: int, record: dict) -> None:
        """Write frame ``frame``'s record at the end of the file."""
        try:
            self._file.seek(0, 2)
            offset = self._file.tell()
            pickle.dump(record, self._file, protocol=pickle.HIGHEST_PROTOCOL)
        except OSError as exc:   # a full or unwritable temporary folder: one line, not a traceback
            raise _spool_error(exc) from None
        self._frames.append(int(frame))
        self._offsets.append(offset)

    def _order(self) -> list[tuple[int, int]]:
        """(frame, offset) of each frame's last record, by frame."""
        return sorted(dict(zip(self._frames, self._offsets)).items())

    def items(self) -> Iterator[tuple[int, dict]]:
        """(frame, record) in frame order, read one at a time."""
        for frame, offset in self._order():
            self._file.seek(offset)
            yield frame, pickle.load(self._file)

    def __iter__(self) -> Iterator[dict]:
        return (record for _, record in self.items())

    def __len__(self) -> int:
        return len(set(self._frames))

    def close(self) -> None:
        """Release the file, ignoring a failed flush of ``add``'s buffer (the error ``add`` already
        raised would be replaced by a traceback)."""
        try:
            self._file.close()
        except OSError:
            pass


def _spool_error(exc: OSError) -> UserError:
    return UserError(f"cannot write the run's per-frame records to the temporary folder {tempfile.gettempdir()} "
                     f"({exc.strerror or exc}): free space there or point TMPDIR at another folder")


def frame_table(records: Iterable[dict], drop: tuple[str, ...] = ()) -> pd.DataFrame:
    """``pd.DataFrame(list(records))`` less ``drop``'s columns, ``CHUNK`` records at a time (columns
    by first appearance, missing ones NaN: one table's dtypes)."""
    it = iter(records)
    pieces = []
    while chunk := list(islice(it, CHUNK)):
        piece = pd.DataFrame(chunk)
        pieces.append(piece.drop(columns=[c for c in drop if c in piece]))
    if not pieces:
        return pd.DataFrame()
    return pieces[0] if len(pieces) == 1 else pd.concat(pieces, ignore_index=True, sort=False)
