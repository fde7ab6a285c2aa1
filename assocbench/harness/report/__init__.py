"""``assocbench report``: a static HTML leaderboard across tracks, from the leaderboard folders of
any set of suites. ``build_report`` makes the files (``{relative path: bytes}``: the overview
``index.html`` with its critical-difference diagrams, a page per suite, its pictures);
``write_report`` puts them in a folder at once; the docs site's hook hands the same files to mkdocs."""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

from ...errors import UserError
from .output import write_report
from .pages import document, overview_body, suite_body
from .suites import Suite, read_suite

__all__ = ["build_report", "write_report"]


def build_report(folders: Sequence[Path | str], names: Sequence[str] | None = None) -> dict[str, bytes]:
    """The report's files for the leaderboards in ``folders`` (each a folder with
    ``leaderboard.csv``, or that file), in order; ``names``: how the pages name each source
    (default: as given)."""
    if not folders:
        raise UserError("no leaderboard given: name one or more folders written by `assocbench leaderboard`, "
                        "e.g. results results/loop")
    names = [str(f) for f in folders] if names is None else list(names)
    suites = [read_suite(Path(f), name) for f, name in zip(folders, names, strict=True)]
    _name(suites)
    files: dict[str, bytes] = {}
    for s in suites:
        pictures = [f"img/{s.slug}/{name}" for name, _ in s.pictures]
        files |= {path: data for path, (_, data) in zip(pictures, s.pictures)}
        files[f"{s.slug}.html"] = document(s.title, s.slug, suites, suite_body(s, pictures)).encode()
    body, diagrams = overview_body(suites)
    files |= diagrams
    files["index.html"] = document("assocbench leaderboard", "index", suites, body).encode()
    return dict(sorted(files.items()))


def _name(suites: list[Suite]) -> None:
    """Give each suite its title (track and loop; its folder where two would read alike) and a
    file name unique in the report."""
    base = [", ".join(filter(None, [s.track.replace("_", " ").capitalize(), s.loop_words])) for s in suites]
    taken = {"index"}
    for s, title in zip(suites, base):
        s.title = title if base.count(title) == 1 else f"{title} ({s.source})"
        slug = re.sub(r"[^a-z0-9]+", "-", s.title.lower()).strip("-") or "suite"
        k = 2
        while slug in taken:
            slug, k = f"{slug.rstrip('0123456789-')}-{k}", k + 1
        taken.add(slug)
        s.slug = slug
