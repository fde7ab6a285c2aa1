"""Atomic file writes: write a temporary file next to the target, then rename it in place.

A write that fails (disk full, read-only file system, no permission) leaves the target as it
was and raises a one-line ``UserError`` naming the file, the cause and what to change; the
``Role`` of a path says what that is (``--out``, ``-o``, ``--baseline``, ``$ASSOCBENCH_CACHE``).
``atomic_paths`` / ``write_group`` write several files as a group: all land or none do.
"""

from __future__ import annotations

import errno
import glob
import os
import tempfile
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from .errors import UserError


@dataclass(frozen=True)
class Role:
    """What a path is for, so that an error names the setting to change.

    ``option`` is a command-line option (``"--out"``) or, with a leading ``$``, an environment
    variable (``"$ASSOCBENCH_CACHE"``)."""

    what: str
    option: str

    def fix(self) -> str:
        """The advice that ends an error message about this path."""
        if self.option.startswith("$"):
            return f"set {self.option[1:]} to a writable folder"
        return f"choose a writable {self.option}"


OUTPUT = Role("output folder", "--out")
CACHE = Role("cache folder", "$ASSOCBENCH_CACHE")
OUTPUT_FILE = Role("output file", "-o")

# errors that mean "this place cannot take the file"; anything else is a bug and propagates
_PLACE_ERRORS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EFBIG,
                 errno.ENOTDIR, errno.EISDIR, errno.ENAMETOOLONG, errno.EIO, errno.ENOENT}


def check_cache_folder(*subfolders: str) -> None:
    """A one-line ``UserError`` when the cache folder cannot be a folder (it, or the nearest of its
    parents that exists, is a file) or cannot be created or written (created here if absent), or
    one of its ``subfolders`` (where the tracks store their sequences: ``Track.cache_folder``) is
    a file; checked before a run compiles or renders: otherwise kernels compiled for 20 s, the
    sequence rendered, and only storing it said so."""
    from ._runtime import cache_root

    root = cache_root()
    for place in (root, *root.parents):
        if place.exists():
            if not place.is_dir():
                raise UserError(f"cannot create {CACHE.what} {root}: {place} is a file; {CACHE.fix()}")
            break
    ensure_dir(root, CACHE)
    for sub in subfolders:
        place = root / sub
        if place.is_symlink() and not place.exists():  # a dangling link: mkdir says "File exists" late
            raise UserError(f"cannot use {CACHE.what} {root}: {place} is a broken link where the cache keeps a "
                            f"folder; remove it, or {CACHE.fix()}")
        if place.exists() and not place.is_dir():
            raise UserError(f"cannot use {CACHE.what} {root}: {place} is a file where the cache keeps a "
                            f"folder; remove or rename it, or {CACHE.fix()}")


def ensure_dir(path: Path, role: Role = OUTPUT) -> Path:
    """Create ``path`` (and parents) or raise a one-line ``UserError`` if that is impossible."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create {role.what} {path}: {_cause(exc)}; {role.fix()}") from None
    if not os.access(path, os.W_OK):
        raise UserError(f"{role.what} {path} is not writable; {role.fix()}")
    return path


def place_error(exc: OSError, target: Path | str, role: Role = OUTPUT, written: Sequence[Path] = ()) -> UserError | None:
    """The one-line ``UserError`` for an ``OSError`` that says ``target`` cannot be written
    there (disk full, read-only, no permission...); ``None`` for any other error."""
    if exc.errno not in _PLACE_ERRORS:
        return None
    fix = role.fix()
    if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
        fix = f"free some space there or {fix}"
    done = f"only {', '.join(map(str, written))} written" if written else "nothing was written"
    return UserError(f"cannot write {target} ({role.what}): {_cause(exc)}; {done}; {fix}")


@contextmanager
def atomic_path(target: Path, suffix: str = "", role: Role = OUTPUT) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; rename it onto ``target`` on success.

    On failure the temporary file is removed and ``target`` is untouched; an ``OSError`` that
    means the place cannot take the file becomes a one-line ``UserError``."""
    with atomic_paths([target], suffix, role) as (tmp,):
        yield tmp


@contextmanager
def atomic_paths(targets: Sequence[Path], suffix: str = "", role: Role = OUTPUT) -> Iterator[list[Path]]:
    """Yield one temporary path per target; only when the block succeeds for all of them are
    they renamed onto their targets, so a group of files lands whole or not at all.

    The renames come last and need no space; a failure there (the folder changed under us)
    can leave the earlier targets renamed, and the error says which."""
    targets = [Path(t) for t in targets]
    temps: list[str] = []
    renamed: list[Path] = []
    try:
        for target in targets:
            ensure_dir(target.parent, role)
            fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.{os.getpid()}.", suffix=suffix or target.suffix,
                                       dir=target.parent)
            os.close(fd)
            temps.append(tmp)
        yield [Path(t) for t in temps]
        for tmp in temps:
            os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; results are ordinary files
        for tmp, target in zip(temps, targets):
            os.replace(tmp, target)
            renamed.append(target)
        for target in targets:
            remove_orphans(target)
    except OSError as exc:
        target = _culprit(exc, targets)
        error = place_error(exc, target, role, renamed) if target else None
        if error is None:
            raise
        raise error from None
    finally:
        for tmp in temps:
            if os.path.exists(tmp):
                os.unlink(tmp)


def remove_orphans(target: Path) -> None:
    """Delete the temporary files of ``target`` left by a writer that died before renaming them
    (kill -9): each names its writer's process id, and only those of processes that are gone go,
    so a concurrent writer's file in progress is left alone."""
    prefix = f".{target.name}."
    for leftover in target.parent.glob(glob.escape(prefix) + "*"):
        pid = leftover.name[len(prefix):].split(".", 1)[0]
        if pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid)):
            try:
                leftover.unlink()
            except OSError:
                pass   # another writer cleaned it first


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True   # exists, owned by someone else
    return True


def _culprit(exc: OSError, targets: list[Path]) -> Path | str | None:
    """Which target an error is about: the one its file name points at (the target, its
    folder or its temporary file), all of them when it names no file (a full disk on write),
    ``None`` when it is about some other file."""
    if exc.filename is None:
        return targets[0] if len(targets) == 1 else ", ".join(map(str, targets))
    name = Path(os.fsdecode(exc.filename))
    for target in targets:
        temp = name.parent == target.parent and name.name.startswith(f".{target.name}.")
        if temp or name in (target, target.parent):
            return target
    return None


def write_group(writers: dict[Path, Callable[[Path], None]], role: Role = OUTPUT) -> None:
    """Write several files as a group: ``writers[path](tmp)`` writes each to a temporary file,
    and only when every one succeeded are they all renamed in place (see ``atomic_paths``)."""
    targets = list(writers)
    with atomic_paths(targets, role=role) as temps:
        for target, tmp in zip(targets, temps):
            writers[target](tmp)


def _cause(exc: OSError) -> str:
    return exc.strerror or type(exc).__name__


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_text(target: Path, text: str, role: Role = OUTPUT) -> None:
    """Write ``text`` to ``target`` atomically."""
    with atomic_path(target, role=role) as tmp:
        tmp.write_text(text)
