"""Write a report's files into ``--out`` whole or not at all: into a temporary folder beside it,
then renamed in place. ``--out`` may be new, empty, or an earlier report (replaced); anything
else (a file, a folder of other things) is refused before anything is written."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

from ...atomic import OUTPUT, ensure_dir, place_error
from ...errors import UserError

MARK = b'<meta name="generator" content="assocbench report">'


def is_report(folder: Path) -> bool:
    """Whether ``folder`` holds a report this command wrote (its index.html carries the mark)."""
    index = folder / "index.html"
    return index.is_file() and MARK in index.read_bytes()[:4096]


def check_out(out: Path) -> None:
    """Refuse an ``--out`` that is a file, or a non-empty folder that is not an earlier report."""
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} is a file; choose a folder for the report (new, empty, or an earlier report)")
    if out.is_dir() and any(out.iterdir()) and not is_report(out):
        raise UserError(f"--out {out} is a folder that holds other files, not a report; choose a new or empty "
                        f"folder (an earlier report there would be replaced)")


def write_report(files: dict[str, bytes], out: Path) -> None:
    """Put ``files`` (relative path -> bytes) in ``out``, replacing an earlier report there."""
    out = Path(out)
    check_out(out)
    ensure_dir(out.parent, OUTPUT)
    staging = old = None
    try:
        staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.new.", dir=out.parent))
        for rel, data in files.items():
            path = staging / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
        _publishable(staging)
        if out.exists():   # an earlier report, or an empty folder: moved aside, removed once the new one is in
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old.", dir=out.parent))
            os.replace(out, old / "report")
        os.replace(staging, out)
        staging = None
    except OSError as exc:
        if old is not None and not out.exists():   # put the earlier report back
            os.replace(old / "report", out)
        error = place_error(exc, out, OUTPUT)
        if error is None:
            raise
        raise error from None
    finally:
        for leftover in (staging, old):
            if leftover is not None:
                shutil.rmtree(leftover, ignore_errors=True)


def _publishable(folder: Path) -> None:
    """mkdtemp makes its folder 0700; a report is an ordinary folder that others may read."""
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(folder, 0o777 & ~mask)
