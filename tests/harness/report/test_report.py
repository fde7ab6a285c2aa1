"""``assocbench report``: the pages from the committed leaderboards, a plugin beside the built-ins,
units in the headers, the same bytes from the same inputs, and bad input refused in one line with
nothing half-written."""

from __future__ import annotations

import errno
import os
import re
from pathlib import Path

import pandas as pd
import pytest
from report_inputs import PLUGIN, RESULTS, copy_leaderboard, tiny_leaderboard, with_plugin

from assocbench.cli.main import main
from assocbench.errors import UserError
from assocbench.harness.report import build_report, write_report


def _tree(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _one_line_error(capsys, code: int, *needles: str) -> None:
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and err.startswith("assocbench: error:"), err
    for needle in needles:
        assert needle in err, err


def test_the_committed_leaderboards_make_an_overview_and_a_page_per_suite(tmp_path, capsys):
    out = tmp_path / "report"
    folders = [str(RESULTS / name) for name in ("", "loop", "planar", "lines")]
    assert main(["report", *folders, "--out", str(out)]) == 0
    assert "wrote" in capsys.readouterr().out
    files = _tree(out)
    assert {"index.html", "camera-open-loop.html", "camera-closed-loop.html", "planar-closed-loop.html",
            "lines-closed-loop.html"} <= set(files)
    assert files["img/planar-closed-loop/leaderboard_map_park.png"] == (RESULTS / "planar/leaderboard_map_park.png").read_bytes()
    planar = files["planar-closed-loop.html"].decode()
    assert 'src="img/planar-closed-loop/leaderboard_map_park.png"' in planar
    # every metric header carries its unit: ATE in m, runtime in ms, rotation in deg
    for label, unit in (("ATE", "m"), ("runtime median", "ms"), ("rotation RMSE", "deg"), ("ANEES", "NEES")):
        assert re.search(rf">{re.escape(label)}<span class=\"unit\">{re.escape(unit)}</span></th>", planar), label
    park = pd.read_csv(RESULTS / "planar/leaderboard.csv")["scenario"].str.startswith("park/").sum()
    assert planar.count('data-scene="park"') == park > 0 and 'data-backend="isam2"' in planar
    index = files["index.html"].decode()
    assert "place (mean rank)" in index and "Friedman (Iman-Davenport)" in index
    for slug in ("camera-open-loop", "planar-closed-loop", "overall-feature"):   # each ranking's CD diagram
        assert f'src="img/ranks/{slug}.png"' in index and files[f"img/ranks/{slug}.png"].startswith(b"\x89PNG")
    assert "http://" not in index + planar and "https://" not in index + planar   # nothing fetched at view time


def test_a_plugin_is_ranked_beside_the_builtins(tmp_path):
    planar = with_plugin(copy_leaderboard(RESULTS / "planar", tmp_path / "planar"))
    camera = with_plugin(copy_leaderboard(RESULTS, tmp_path / "camera"), best=False)
    files = build_report([camera, planar])
    index = files["index.html"].decode()
    rows = re.findall(r'<tr><td class="text" data-v="([^"]+)">', index)
    assert PLUGIN in rows and "jcbb" in rows
    # last of the committed methods + 1 in each of the 9 camera scenarios, first in each of the 12 planar ones
    # (nothing can be better: 1st place); overall, among the 5 methods of both suites, last in 9 blocks, first in 12
    last = pd.read_csv(RESULTS / "leaderboard.csv")["method"].nunique() + 1
    plugin_row = index[index.index(f'data-v="{PLUGIN}"'):].split("</tr>")[0]
    cells = re.findall(r'<td data-v="([^"]*)"><b>(\d+)</b>', plugin_row)
    assert [float(v) for v, _ in cells] == [last, 1.0, pytest.approx((9 * 5 + 12 * 1) / 21)]
    assert int(cells[0][1]) > 1 and cells[1][1] == "1"
    assert f'data-method="{PLUGIN}"' in files["planar-closed-loop.html"].decode()


def test_same_inputs_same_bytes(tmp_path):
    folders = [RESULTS / "lines", RESULTS]
    first, second = tmp_path / "a", tmp_path / "b"
    write_report(build_report(folders, names=["lines", "camera"]), first)
    write_report(build_report(folders, names=["lines", "camera"]), second)
    assert _tree(first) == _tree(second)


def test_dense_runs_are_averaged_over_seeds(tmp_path):
    # as the dense track writes them: one row per run, with its labels and its error text
    rows = [{"scenario": "crates/easy-model", "scene": "crates", "difficulty": "easy-model", "method": m, "seed": s,
             "status": "ok", "frames": 10, "ate_mm": a, "precision": 0.9, "error": "", "note": "x"}
            for m, s, a in (("projective", 0, 1.0), ("projective", 1, 3.0), ("kdtree", 0, 5.0))]
    page = build_report([tiny_leaderboard(tmp_path / "dense", rows)])
    name = next(n for n in page if n.endswith(".html") and n != "index.html")
    html = page[name].decode()
    assert 'data-v="2">2.0 <span class="std">&plusmn; 1.0</span>' in html   # mean and std of 1 and 3 mm
    assert "The dense track's methods" in page["index.html"].decode()


def test_every_share_column_of_the_dense_page_says_share(tmp_path):
    # precision and recall at ICP's first iteration are shares like precision and recall (they had no unit)
    rows = [{"scenario": "crates/easy-model", "method": "kdtree", "seed": 0, "status": "ok", "frames": 10,
             "ate_mm": 1.0, "precision": 0.9, "precision_start": 0.4, "recall_start": 0.5}]
    page = build_report([tiny_leaderboard(tmp_path / "dense", rows)])
    html = next(v for n, v in page.items() if n.endswith(".html") and n != "index.html").decode()
    for label in ("precision at start", "recall at start"):
        assert re.search(rf">{label}<span class=\"unit\">share</span></th>", html), label


def test_a_method_that_spent_its_budget_gets_a_badge_beside_its_name_and_stays_ok(tmp_path):
    # the committed camera page: JCBB timed out on 54 of 90 frames of checkerboard/hard with status ok,
    # shown only as a number in a column far to the right
    rows = [{"scenario": "checkerboard/hard", "method": m, "status": "ok", "seeds": 3, "frames": 90, "f1": 0.9,
             "timed_out": t, "failures": 0} for m, t in (("jcbb", 54), ("mnn", 0))]
    page = build_report([tiny_leaderboard(tmp_path / "camera", rows)])
    html = next(v for n, v in page.items() if n.endswith(".html") and n != "index.html").decode()
    jcbb, mnn = (html[html.index(f'data-method="{m}"'):].split("</tr>")[0] for m in ("jcbb", "mnn"))
    assert '<span class="badge"' in jcbb and "54 timed out</span>" in jcbb and 'class="more counted"' in jcbb
    name_cell = jcbb[jcbb.index('data-v="jcbb">'):].split("</td>")[0]
    assert "54 timed out" in name_cell   # beside the name: the status column is off-screen on wide pages
    assert 'data-v="ok"' in jcbb   # still ok: the harness measured it, the method failed at its job
    assert "badge" not in mnn and "counted" not in mnn


@pytest.mark.parametrize("text,needles", [
    (None, ["holds no leaderboard.csv", "assocbench leaderboard --out"]),
    (b"\xff\xfe\x00garbage", ["is not a readable CSV"]),
    (b"a,b\n1,2\n", ["no scenario or method column"]),
    (b"scenario,method,precision\nroom/easy,jcbb,0.9\n", ["has no column f1, the metric its track ranks by"]),
    (b"scenario,method,f1\nroom/easy,jcbb,high\n", ["column f1 holds text"]),
    (b"scenario,method,f1\n", ["has no rows"]),
    (b"scenario,method,f1\nroom/easy,jcbb,0.9\nroom/easy,jcbb,0.8\n", ["two rows for method jcbb on room/easy"]),
])
def test_a_folder_that_is_no_leaderboard_is_refused(tmp_path, capsys, text, needles):
    folder = tmp_path / "lb"
    folder.mkdir()
    if text is not None:
        (folder / "leaderboard.csv").write_bytes(text)
    out = tmp_path / "out"
    _one_line_error(capsys, main(["report", str(folder), "--out", str(out)]), *needles)
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["lb"]


def test_a_folder_that_does_not_exist_is_named_so(tmp_path, capsys):
    out = tmp_path / "out"
    _one_line_error(capsys, main(["report", str(tmp_path / "nowhere"), "--out", str(out)]), "does not exist")
    assert not out.exists()


def test_an_out_that_is_a_file_or_holds_other_things_is_refused(tmp_path, capsys):
    afile = tmp_path / "notes.txt"
    afile.write_text("mine")
    _one_line_error(capsys, main(["report", str(RESULTS), "--out", str(afile)]), "is a file")
    other = tmp_path / "other"
    other.mkdir()
    (other / "keep.txt").write_text("mine")
    _one_line_error(capsys, main(["report", str(RESULTS), "--out", str(other)]), "holds other files")
    assert afile.read_text() == "mine" and _tree(other) == {"keep.txt": b"mine"}


def test_an_earlier_report_is_replaced_whole_or_kept(tmp_path, monkeypatch):
    out = tmp_path / "report"
    write_report(build_report([RESULTS / "lines"]), out)
    assert "lines-closed-loop.html" in _tree(out) and any(name.startswith("img/lines") for name in _tree(out))
    write_report(build_report([RESULTS]), out)
    assert _tree(out) == build_report([RESULTS])   # the lines page and its pictures are gone
    before = _tree(out)

    def full_disk(self, data):
        raise OSError(errno.ENOSPC, "No space left on device", str(self))

    monkeypatch.setattr(Path, "write_bytes", full_disk)
    with pytest.raises(UserError, match="No space left on device"):
        write_report(build_report([RESULTS / "planar"]), out)
    monkeypatch.undo()
    assert _tree(out) == before and sorted(p.name for p in tmp_path.iterdir()) == ["report"]   # no temporary left


USER_FILES = {".git/HEAD": b"ref: refs/heads/main\n", ".git/objects/ab/cdef": b"blob", "CNAME": b"bench.example.org\n",
              "notes.md": b"my notes", "img/logo.png": b"my logo", "about.html": b"<html>my page</html>"}


def test_a_report_over_an_earlier_one_keeps_the_users_files(tmp_path):
    """Reproduction: `assocbench report results/lines --out site`, then the user adds `.git/`,
    `CNAME`, notes (a published site), then `assocbench report results --out site`: the folder was
    replaced whole and every file of the user's was deleted. Only the report's files change now."""
    out = tmp_path / "site"
    write_report(build_report([RESULTS / "lines"]), out)
    for rel, data in USER_FILES.items():
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        (out / rel).write_bytes(data)
    assert main(["report", str(RESULTS), "--out", str(out)]) == 0
    assert _tree(out) == build_report([RESULTS]) | USER_FILES


def test_a_report_into_an_empty_mount_point_is_written_into_it(tmp_path, monkeypatch):
    """Reproduction: `assocbench report results --out /mnt/empty-volume` failed with `OSError [Errno
    16] Device or resource busy`: the folder was renamed aside, and a mount point cannot be. The
    report is written into the folder; renaming the folder itself fails here as on a mount point."""
    out = tmp_path / "volume"
    out.mkdir()
    replace = os.replace

    def busy(src, dst):
        if Path(src) == out or Path(dst) == out:
            raise OSError(errno.EBUSY, "Device or resource busy", str(src))
        return replace(src, dst)

    monkeypatch.setattr(os, "replace", busy)
    assert main(["report", str(RESULTS), "--out", str(out)]) == 0
    assert _tree(out) == build_report([RESULTS]) and sorted(p.name for p in tmp_path.iterdir()) == ["volume"]


def test_a_dense_count_of_frames_prints_whole_when_it_is(tmp_path):
    # ICP failures of one run are frames: "3", not "3.0"; a mean over seeds keeps its fraction
    rows = [{"scenario": "crates/easy-model", "method": m, "seed": s, "status": "ok", "frames": 10, "ate_mm": 1.0,
             "precision": 0.9, "icp_failures": lost, "wrong_steps": 0}
            for m, s, lost in (("projective", 0, 3), ("kdtree", 0, 3), ("kdtree", 1, 0))]
    page = build_report([tiny_leaderboard(tmp_path / "dense", rows)])
    html = next(v for n, v in page.items() if n.endswith(".html") and n != "index.html").decode()
    assert 'data-v="3">3 <span class="std">&plusmn; 0</span>' in html            # projective, one seed
    assert 'data-v="1.5">1.5 <span class="std">&plusmn; 1.5</span>' in html      # kdtree, 3 and 0


def test_failed_frames_of_dense_runs_are_summed_over_seeds_as_their_frames_are(tmp_path):
    # shown as "k / frames" with frames summed over seeds: k must be the sum too (the mean read 2 / 20 for 3 + 0)
    rows = [{"scenario": "crates/easy-model", "method": "kdtree", "seed": s, "status": "ok", "frames": 10,
             "ate_mm": 1.0, "precision": 0.9, "failures": failed} for s, failed in ((0, 3), (1, 0))]
    page = build_report([tiny_leaderboard(tmp_path / "dense", rows)])
    html = next(v for n, v in page.items() if n.endswith(".html") and n != "index.html").decode()
    assert 'data-v="3">3 / 20</td>' in html


def _edited(folder: Path, key: str, value) -> Path:
    """``folder``'s leaderboard with column ``key`` of its second row (line 3) set to ``value``."""
    table = pd.read_csv(folder / "leaderboard.csv")
    table[key] = table[key].astype(object)
    table.loc[1, key] = value
    table.to_csv(folder / "leaderboard.csv", index=False)
    return folder


@pytest.mark.parametrize("suite,key,value,needle", [
    ("planar", "f1", float("inf"), "column f1: inf is not a finite number in [0, 1]"),
    ("planar", "f1", -5, "column f1: -5 is not a finite number in [0, 1]"),
    ("planar", "recall", 1e308, "column recall: 1e+308 is not a finite number in [0, 1]"),
    ("planar", "ate_rmse", -0.1, "column ate_rmse: -0.1 is not a finite number in [0, inf]"),
    ("planar", "seeds", 2.5, "column seeds: 2.5 is not a whole number in [1, inf]"),
    ("planar", "f1_std", -1, "column f1_std: -1 is not a finite number in [0, inf]"),
    ("planar", "status", "", "has no status"),
    ("dense", "ate_mm", float("-inf"), "column ate_mm: -inf is not a finite number in [0, inf]"),
])
def test_a_value_outside_its_column_is_refused_naming_file_line_and_column(tmp_path, capsys, suite, key, value, needle):
    """Reproduction: `assocbench report` of results/planar with one row's f1 set to inf ranked it
    first; f1=-5 and recall=1e308 were ranked too (1e308 printed with 309 digits)."""
    folder = _edited(copy_leaderboard(RESULTS / suite, tmp_path / suite), key, value)
    row = pd.read_csv(RESULTS / suite / "leaderboard.csv").iloc[1]
    out = tmp_path / "out"
    _one_line_error(capsys, main(["report", str(folder), "--out", str(out)]),
                    f"{folder}/leaderboard.csv line 3 ({row['scenario']}, {row['method']})", needle)
    assert not out.exists()


def test_a_leaderboard_cut_mid_row_is_refused_in_one_line(tmp_path, capsys):
    """Reproduction: results/planar/leaderboard.csv without its last 40 bytes (the last row lost its
    status, seeds and frames) was shown as ok and ranked; results/lines cut inside its seeds column
    failed with `ValueError: cannot convert float NaN to integer` (pages.py)."""
    out = tmp_path / "out"
    for suite in ("planar", "lines"):
        folder = copy_leaderboard(RESULTS / suite, tmp_path / suite)
        data = (folder / "leaderboard.csv").read_bytes()
        end = len(data) - 40 if suite == "planar" else data.rindex(b",ok,") + len(b",ok,")   # lines: before seeds
        (folder / "leaderboard.csv").write_bytes(data[:end])
        lines = data.count(b"\n")
        _one_line_error(capsys, main(["report", str(folder), "--out", str(out)]), f"line {lines} (",
                        "the file is cut or damaged")
    assert not out.exists()
