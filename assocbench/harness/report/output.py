"""Write a report's files into ``--out``, never touching a file the report did not write. ``--out``
may be new, empty, or an earlier report beside the user's own files (``.git/``, ``CNAME``): files
are staged in a hidden folder inside it and each renamed in place, and the earlier report's files
(its marked ``.html`` pages and ``img/``) the new one lacks are removed; the rest is the user's. A
failed write leaves the earlier report as it was; any other ``--out`` is refused before anything is
written."""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from html import unescape
from pathlib import Path

from ...atomic import OUTPUT, ensure_dir, place_error
from ...errors import UserError

MARK = b'<meta name="generator" content="assocbench report">'
PICTURE = re.compile(r'<img src="(img/[^"/]+/[^"/]+\.png)"')   # how pages.suite_body shows a picture


def _is_page(path: Path) -> bool:
    """Whether ``path`` is a page this command wrote (it carries the mark)."""
    if not path.is_file() or path.suffix != ".html":
        return False
    with path.open("rb") as f:
        return MARK in f.read(4096)


def is_report(folder: Path) -> bool:
    """Whether ``folder`` holds a report this command wrote (its index.html carries the mark)."""
    return _is_page(folder / "index.html")


def report_files(folder: Path) -> set[str]:
    """The files of the report in ``folder`` (relative paths): its pages and their pictures."""
    pages = [p for p in folder.glob("*.html") if _is_page(p)]
    pictures = {unescape(src) for p in pages for src in PICTURE.findall(p.read_text(errors="replace"))}
    return {p.name for p in pages} | {src for src in pictures if ".." not in src.split("/")}


def check_out(out: Path) -> None:
    """Refuse an ``--out`` that is a file, or a non-empty folder that is not an earlier report."""
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} is a file; choose a folder for the report (new, empty, or an earlier report)")
    if out.is_dir() and any(out.iterdir()) and not is_report(out):
        raise UserError(f"--out {out} is a folder that holds other files, not a report; choose a new or empty "
                        f"folder (an earlier report there would be replaced)")


def write_report(files: dict[str, bytes], out: Path) -> None:
    """Put ``files`` (relative path -> bytes) in ``out``, replacing an earlier report's files there
    and keeping every other file (module docstring)."""
    out = Path(out)
    check_out(out)
    created = not out.exists()
    ensure_dir(out, OUTPUT)
    staging = None
    try:
        staging = Path(tempfile.mkdtemp(prefix=".report.new.", dir=out))
        for rel, data in files.items():
            path = staging / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
        stale = report_files(out) - set(files)
        for rel in files:
            (out / rel).parent.mkdir(parents=True, exist_ok=True)
            os.replace(staging / rel, out / rel)
        _remove(out, stale)
    except OSError as exc:
        error = place_error(exc, out, OUTPUT)
        if error is None:
            raise
        raise error from None
    finally:
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)
        if created and out.is_dir() and not any(out.iterdir()):   # nothing landed: leave no empty folder
            out.rmdir()


def _remove(out: Path, stale: set[str]) -> None:
    """Remove an earlier report's files the new one does not have, and the picture folders that
    leaves empty; nothing else."""
    for rel in sorted(stale):
        (out / rel).unlink(missing_ok=True)
    for folder in sorted({(out / rel).parent for rel in stale}, reverse=True):
        while folder != out and folder.is_dir() and not any(folder.iterdir()):
            folder.rmdir()
            folder = folder.parent
