"""Stored runs: one method on one scene, seed and difficulty, reused only when complete, verified
and made from the same inputs.

A run ``<key>`` (``suite.Run.key``) is stored under ``<out>/runs/`` as ``<key>.<sha>.summary.csv``
and ``<key>.<sha>.frames.csv``, named by content, and a manifest ``<key>.manifest.json`` written
last, atomically, naming both with SHA-256, size and rows, and the run's inputs
(``inputs.RunInputs``). Labels (scenario, method name, seed) are the suite's, so renaming reuses
runs. A missing or damaged manifest or file means the run is recomputed with one line on stderr;
changed inputs too, said once per sweep (``lookup``). Content names keep two sweeps storing one run
at once from mixing files.
"""

from __future__ import annotations

import hashlib
import io
import json
import sys
from pathlib import Path

import pandas as pd

from ..atomic import atomic_path
from .inputs import RunInputs
from .suite import Run

FORMAT = 2
FOLDER = "runs"
PARTS = ("summary", "frames")


def manifest_path(out: Path, key: str) -> Path:
    """Where the manifest of the run ``key`` lives; it exists only once the run is completely stored."""
    return Path(out) / FOLDER / f"{key}.manifest.json"


def store_run(out: Path, run: Run, result: tuple[pd.DataFrame, pd.DataFrame], inputs: RunInputs) -> None:
    """Store a run's (summary, frames) with its ``inputs``: data files first, the manifest last,
    each atomically, so an interrupted run is simply not stored."""
    folder, key = Path(out) / FOLDER, run.key
    entries = {}
    for part, df in zip(PARTS, result):
        data = _encode(df)
        sha = hashlib.sha256(data).hexdigest()
        name = f"{key}.{sha[:12]}.{part}.csv"
        with atomic_path(folder / name) as tmp:
            tmp.write_bytes(data)
        entries[part] = {"name": name, "sha256": sha, "bytes": len(data), "rows": len(df)}
    manifest = {"format": FORMAT, "key": key, "run": run.name, "files": entries, "inputs": inputs.to_json()}
    with atomic_path(manifest_path(out, key)) as tmp:
        tmp.write_text(json.dumps(manifest, indent=1))
    keep = {e["name"] for e in entries.values()}
    for stale in _data_files(folder, key):  # an older, replaced copy of this run
        if stale.name not in keep:
            stale.unlink(missing_ok=True)


def lookup(out: Path, run: Run) -> tuple[tuple[pd.DataFrame, pd.DataFrame] | None, str | None]:
    """The stored (summary, frames) of ``run`` if complete, verified and from today's inputs, else
    ``(None, why)`` (``why``: the changed input, or None); damaged files are removed with one line
    on stderr."""
    folder, key = Path(out) / FOLDER, run.key
    manifest = manifest_path(out, key)
    if not manifest.is_file():
        if any(_data_files(folder, key)):
            _note(run, key, "incomplete (no manifest: it was interrupted while being stored)")
        return None, None
    try:
        result, inputs = _verified(folder, key, manifest)
    except _Damaged as exc:
        _note(run, key, f"damaged ({exc})")
        _discard(folder, key, manifest)
        return None, None
    changed = inputs.changed()
    return (None, changed) if changed else (result, None)


def load_run(out: Path, run: Run) -> tuple[pd.DataFrame, pd.DataFrame] | None:
    """The stored (summary, frames) of ``run`` when ``lookup`` finds it usable, else None."""
    return lookup(out, run)[0]


class _Damaged(Exception):
    """A stored run whose files cannot be trusted."""


def _verified(folder: Path, key: str, manifest: Path) -> tuple[tuple[pd.DataFrame, pd.DataFrame], RunInputs]:
    try:
        info = json.loads(manifest.read_bytes())
        files = [info["files"][part] for part in PARTS]
        if info["format"] != FORMAT or info["key"] != key:
            raise _Damaged(f"{manifest.name} belongs to another run or format")
        inputs = RunInputs.from_json(info["inputs"])
    except (OSError, ValueError, KeyError, TypeError) as exc:  # ValueError covers JSON and UTF-8 errors
        raise _Damaged(f"unreadable {manifest.name}: {type(exc).__name__}") from None
    summary, frames = (_read_part(folder, part, entry) for part, entry in zip(PARTS, files))
    return (summary, frames), inputs


def _encode(df: pd.DataFrame) -> bytes:
    return df.to_csv(index=False).encode()


def _decode(data: bytes, part: str) -> pd.DataFrame:
    """A stored part read back: the summary's ``error`` as str, ``""`` for none."""
    df = pd.read_csv(io.BytesIO(data), dtype={"error": str} if part == "summary" else None)
    if part == "summary" and "error" in df:
        df["error"] = df["error"].fillna("").astype(str)
    return df


def as_read_back(result: tuple[pd.DataFrame, pd.DataFrame]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """A run's (summary, frames) as they read back from the store, so computed and stored runs are
    the same tables."""
    return tuple(_decode(_encode(df), part) for part, df in zip(PARTS, result))


def _read_part(folder: Path, part: str, entry) -> pd.DataFrame:
    try:
        name = str(entry["name"])
        data = (folder / Path(name).name).read_bytes()
    except (OSError, KeyError, TypeError) as exc:
        raise _Damaged(f"{part} file missing: {type(exc).__name__}") from None
    if len(data) != entry.get("bytes") or hashlib.sha256(data).hexdigest() != entry.get("sha256"):
        raise _Damaged(f"{name} does not match its checksum")
    try:
        df = _decode(data, part)
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
            pass  # the run is recomputed and stored over it anyway


def _note(run: Run, key: str, what: str) -> None:
    print(f"assocbench: stored run {run.name} ({key}) is {what}; recomputing it", file=sys.stderr)
