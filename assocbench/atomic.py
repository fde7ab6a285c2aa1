"""Atomic file writes: a temporary file beside the target, renamed in place. A failed write (disk
full, read-only, no permission) leaves the target as it was and raises a one-line ``UserError``
naming the file, the cause and the setting to change (its ``Role``). ``atomic_paths`` /
``write_group`` write several files that all land or none do.
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
    """What a path is for, so an error names the setting to change: ``option`` is a command-line
    option (``"--out"``) or, with ``$``, an environment variable."""

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
    """One-line ``UserError`` when the cache folder (or a ``subfolders`` entry, where tracks store
    sequences) is a file or cannot be created or written; checked before anything compiles or
    renders, not after."""
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
    """The one-line ``UserError`` for an ``OSError`` meaning ``target`` cannot be written there;
    ``None`` for any other error."""
    if exc.errno not in _PLACE_ERRORS:
        return None
    fix = role.fix()
    if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
        fix = f"free some space there or {fix}"
    done = f"only {', '.join(map(str, written))} written" if written else "nothing was written"
    return UserError(f"cannot write {target} ({role.what}): {_cause(exc)}; {done}; {fix}")


@contextmanager
def atomic_path(target: Path, suffix: str = "", role: Role = OUTPUT) -> Iterator[Path]:
    """Yield a temporary path in the target's folder, renamed onto ``target`` on success; on failure
    it is removed and ``target`` untouched."""
    with atomic_paths([target], suffix, role) as (tmp,):
        yield tmp


@contextmanager
def atomic_paths(targets: Sequence[Path], suffix: str = "", role: Role = OUTPUT) -> Iterator[list[Path]]:
    """Yield one temporary path per target, all renamed only when the block succeeds for all. The
    renames come last and need no space; one failing there can leave earlier targets renamed, and
    the error says which."""
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
    """Delete temporary files of ``target`` left by a writer killed before renaming: each names its
    writer's process id, and only those of dead processes go."""
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
    """Which target an error is about: the one its file name points at, all when it names none (a
    full disk), ``None`` for another file."""
    if exc.filename is None:
        return targets[0] if len(targets) == 1 else ", ".join(map(str, targets))
    name = Path(os.fsdecode(exc.filename))
    for target in targets:
        temp = name.parent == target.parent and name.name.startswith(f".{target.name}.")
        if temp or name in (target, target.parent):
            return target
    return None


def write_group(writers: dict[Path, Callable[[Path], None]], role: Role = OUTPUT) -> None:
    """Write several files as a group: ``writers[path](tmp)`` each, all renamed only when every one
    succeeded."""
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
