"""Stored leaderboard jobs: a job counts as done only when its files are complete and verified.

A job ``<key>`` is stored under ``<out>/jobs/`` as two CSV files named by their content,
``<key>.<sha>.summary.csv`` and ``<key>.<sha>.frames.csv``, and a manifest
``<key>.manifest.json`` written last, atomically, that names both files with their SHA-256,
size and row count. A reader trusts only what the manifest vouches for: a missing manifest
(the process died before it), a damaged one, a missing file or one whose bytes differ
(truncated, edited, zero bytes) means the job is recomputed, with one line on stderr.
Naming the files by content means two sweeps storing the same job at once never mix their
files: each manifest points at a consistent pair.
"""

from __future__ import annotations

import hashlib
import io
import json
import sys
from pathlib import Path

import pandas as pd

from ..atomic import atomic_path
from .suite import Job

FORMAT = 1
PARTS = ("summary", "frames")


def manifest_path(out: Path, job: Job, key: str | None = None) -> Path:
    """Where the manifest of ``job`` lives; it exists only once the job is completely stored."""
    return Path(out) / "jobs" / f"{key or job.key}.manifest.json"


def store_job(out: Path, job: Job, result: tuple[pd.DataFrame, pd.DataFrame]) -> None:
    """Store a job's (summaries, frames) under ``out/jobs``: data files first, the manifest last,
    each written atomically, so a job interrupted at any point is simply not stored."""
    folder, key = Path(out) / "jobs", job.key  # a key hashes the sources: computed once
    entries = {}
    for part, df in zip(PARTS, result):
        data = df.to_csv(index=False).encode()
        sha = hashlib.sha256(data).hexdigest()
        name = f"{key}.{sha[:12]}.{part}.csv"
        with atomic_path(folder / name) as tmp:
            tmp.write_bytes(data)
        entries[part] = {"name": name, "sha256": sha, "bytes": len(data), "rows": len(df)}
    manifest = {"format": FORMAT, "key": key, "scene": job.scene, "seed": job.seed, "files": entries}
    with atomic_path(manifest_path(out, job, key)) as tmp:
        tmp.write_text(json.dumps(manifest, indent=1))
    keep = {e["name"] for e in entries.values()}
    for stale in _data_files(folder, key):  # an older, replaced copy of this job
        if stale.name not in keep:
            stale.unlink(missing_ok=True)


def load_job(out: Path, job: Job) -> tuple[pd.DataFrame, pd.DataFrame] | None:
    """The stored (summaries, frames) of ``job`` if they are complete and verified, else ``None``.

    Damaged files are removed and one line on stderr says so; the caller recomputes the job.
    The frames have the dtypes ``run_suite`` always returned (read back from CSV), with the
    summaries' ``error`` column as str, ``""`` for none."""
    folder, key = Path(out) / "jobs", job.key
    manifest = manifest_path(out, job, key)
    if not manifest.is_file():
        if any(_data_files(folder, key)):
            _note(job, key, "incomplete (no manifest: it was interrupted while being stored)")
        return None
    try:
        return _verified(folder, key, manifest)
    except _Damaged as exc:
        _note(job, key, f"damaged ({exc})")
        _discard(folder, key, manifest)
        return None


class _Damaged(Exception):
    """A stored job whose files cannot be trusted."""


def _verified(folder: Path, key: str, manifest: Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    try:
        info = json.loads(manifest.read_bytes())
        files = [info["files"][part] for part in PARTS]
        if info["format"] != FORMAT or info["key"] != key:
            raise _Damaged(f"{manifest.name} belongs to another job or format")
    except (OSError, ValueError, KeyError, TypeError) as exc:  # ValueError covers JSON and UTF-8 errors
        raise _Damaged(f"unreadable {manifest.name}: {type(exc).__name__}") from None
    frames = []
    for part, entry in zip(PARTS, files):
        frames.append(_read_part(folder, part, entry))
    summaries, per_frame = frames
    summaries["error"] = summaries["error"].fillna("").astype(str)
    return summaries, per_frame


def _read_part(folder: Path, part: str, entry) -> pd.DataFrame:
    try:
        name = str(entry["name"])
        data = (folder / Path(name).name).read_bytes()
    except (OSError, KeyError, TypeError) as exc:
        raise _Damaged(f"{part} file missing: {type(exc).__name__}") from None
    if len(data) != entry.get("bytes") or hashlib.sha256(data).hexdigest() != entry.get("sha256"):
        raise _Damaged(f"{name} does not match its checksum")
    try:
        df = pd.read_csv(io.BytesIO(data), dtype={"error": str} if part == "summary" else None)
    except (ValueError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise _Damaged(f"{name} cannot be parsed: {type(exc).__name__}") from None
    if len(df) != entry.get("rows") or (part == "summary" and "error" not in df):
        raise _Damaged(f"{name} has {len(df)} rows, the manifest says {entry.get('rows')}")
    return df


def _data_files(folder: Path, key: str):
    return (p for part in PARTS for p in folder.glob(f"{key}.*{part}.csv"))


def _discard(folder: Path, key: str, manifest: Path) -> None:
    for path in [manifest, *_data_files(folder, key)]:
        try:
            path.unlink(missing_ok=True)
        except OSError:
            pass  # the job is recomputed and stored over it anyway


def _note(job: Job, key: str, what: str) -> None:
    print(f"assocbench: stored job {job.scene} seed {job.seed} ({key}) is {what}; recomputing it",
          file=sys.stderr)
