"""Fault injection on stored data: damaged caches and stored runs heal, a stored run is used only
while its inputs match, and a full disk or an unusable cache folder is one line."""

from __future__ import annotations

import errno
import importlib
import io
import os
import shutil

import numpy as np
import pandas as pd
import pytest

import assocbench  # noqa: F401  (installs the numba cache guard)
from assocbench import kernels
from assocbench.atomic import CACHE, Role, atomic_path, ensure_dir, write_group
from assocbench.errors import UserError
from assocbench.harness.inputs import RunInputs
from assocbench.harness.runstore import load_run, lookup, store_run
from assocbench.harness.suite import Cell, MethodEntry, Run, load_suite
from assocbench.harness.sweep import run_suite
from assocbench.tracks.camera.sequence import SequenceSpec, load_sequence

SMALL = SequenceSpec(scene="checkerboard", frames=2, width=320, height=240)
OTHER = SequenceSpec(scene="checkerboard", frames=3, width=320, height=240)


def _entry(cache, spec):
    return cache / "sequences" / f"{spec.key()}.npz"


@pytest.fixture(scope="module")
def good_cache(tmp_path_factory):
    """A cache holding SMALL and OTHER, and SMALL as rendered."""
    cache = tmp_path_factory.mktemp("seqcache")
    load_sequence(OTHER, cache)
    return cache, load_sequence(SMALL, cache)


def _flip(data: bytes, at: float) -> bytes:
    b = bytearray(data)
    b[int(len(b) * at)] ^= 0xFF
    return bytes(b)


DAMAGE = {
    "truncated at 10%": lambda d, other: d[: len(d) // 10],
    "truncated at half": lambda d, other: d[: len(d) // 2],
    "truncated by one byte": lambda d, other: d[:-1],
    "zero bytes": lambda d, other: b"",
    "flipped byte at 40%": lambda d, other: _flip(d, 0.4),
    "flipped byte at 60%": lambda d, other: _flip(d, 0.6),
    "garbage": lambda d, other: bytes(np.random.default_rng(0).integers(0, 256, 4000, dtype=np.uint8)),
    "zip-like garbage": lambda d, other: b"PK\x03\x04" + bytes(range(256)) * 8,
    "a valid file of another key": lambda d, other: other,
}


@pytest.mark.parametrize("damage", list(DAMAGE))
def test_a_damaged_cached_sequence_is_rebuilt_with_one_line(damage, good_cache, tmp_path, capsys):
    cache, rendered = good_cache
    shutil.copytree(cache / "sequences", tmp_path / "sequences")
    path = _entry(tmp_path, SMALL)
    path.write_bytes(DAMAGE[damage](path.read_bytes(), _entry(tmp_path, OTHER).read_bytes()))
    seq = load_sequence(SMALL, tmp_path)
    assert len(seq) == SMALL.frames and not seq.from_cache
    np.testing.assert_array_equal(seq.positions, rendered.positions)
    assert all(np.array_equal(a, b) for a, b in zip(seq.features, rendered.features))
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "cached sequence" in lines[0] and "rendering again" in lines[0]
    again = load_sequence(SMALL, tmp_path)   # the rebuilt entry is sound and used
    assert again.from_cache and capsys.readouterr().err == ""


def test_a_cached_sequence_of_another_key_is_not_used(good_cache, tmp_path, capsys):
    """The issue's case: a 3-frame file copied over a 2-frame key must not report 3 frames."""
    cache, _ = good_cache
    shutil.copytree(cache / "sequences", tmp_path / "sequences")
    shutil.copyfile(_entry(tmp_path, OTHER), _entry(tmp_path, SMALL))
    assert len(load_sequence(SMALL, tmp_path)) == 2
    assert "another key" in capsys.readouterr().err


def _run() -> Run:
    return Run(Cell("checkerboard", 0, "hard", {"scene": "checkerboard", "frames": 2}), MethodEntry("enn", "enn"))


NO_INPUTS = RunInputs({}, {})


def _result():
    summary = pd.DataFrame({"scenario": ["checkerboard/hard"] * 4, "method": list("abcd"), "seed": [0, 1, 0, 1],
                            "f1": [0.5, 0.25, 1.0, 0.125], "error": ["", "RuntimeError: boom", "", ""]})
    frames = pd.DataFrame({"method": list("aabbccdd"), "frame": [0, 1] * 4, "n": range(8),
                           "runtime_s": np.linspace(0.001, 0.002, 8)})
    return summary, frames


def _run_files(out, part):
    return sorted((out / "runs").glob(f"*.{part}.csv"))


RUN_DAMAGE = {
    "summary cut to its first lines (head -n 3)":
        lambda out: _run_files(out, "summary")[0].write_text("".join(
            _run_files(out, "summary")[0].read_text().splitlines(keepends=True)[:3])),
    "summary zero bytes": lambda out: _run_files(out, "summary")[0].write_bytes(b""),
    "frames garbage": lambda out: _run_files(out, "frames")[0].write_bytes(b"\x00\xff garbage \x89\n" * 30),
    "frames deleted": lambda out: _run_files(out, "frames")[0].unlink(),
    "manifest zero bytes": lambda out: next((out / "runs").glob("*.manifest.json")).write_bytes(b""),
    "manifest garbage": lambda out: next((out / "runs").glob("*.manifest.json")).write_text("{not json"),
    "manifest missing (killed before it)": lambda out: next((out / "runs").glob("*.manifest.json")).unlink(),
}


@pytest.mark.parametrize("damage", list(RUN_DAMAGE))
def test_a_damaged_stored_run_is_recomputed_never_used(damage, tmp_path, capsys):
    run, (summary, frames) = _run(), _result()
    store_run(tmp_path, run, (summary, frames), NO_INPUTS)
    RUN_DAMAGE[damage](tmp_path)
    assert load_run(tmp_path, run) is None
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "recomputing" in lines[0] and run.name in lines[0]
    store_run(tmp_path, run, (summary, frames), NO_INPUTS)   # what the sweep does next
    loaded = load_run(tmp_path, run)
    pd.testing.assert_frame_equal(loaded[0], summary)
    pd.testing.assert_frame_equal(loaded[1], frames)
    assert len(_run_files(tmp_path, "summary")) == 1   # the damaged copy is gone


def test_a_stored_run_is_used_only_while_its_inputs_match(tmp_path):
    helper = tmp_path / "helper.py"
    helper.write_text("K = 1\n")
    run, result = _run(), _result()
    store_run(tmp_path, run, result, RunInputs({str(helper): "0" * 16}, {}))
    assert lookup(tmp_path, run) == (None, f"{helper} changed")
    from assocbench.harness.inputs import file_digest

    store_run(tmp_path, run, result, RunInputs({str(helper): file_digest(helper)[0]}, {"numpy": f"numpy {np.__version__}"}))
    assert load_run(tmp_path, run) is not None
    store_run(tmp_path, run, result, RunInputs({str(helper): file_digest(helper)[0]}, {"numpy": "numpy 0.0.1"}))
    assert lookup(tmp_path, run) == (None, f"numpy 0.0.1 is now numpy {np.__version__}")
    helper.unlink()
    assert lookup(tmp_path, run)[1] == f"{helper} is gone"


def test_a_stored_run_reads_back_with_the_dtypes_a_sweep_returns(tmp_path, capsys):
    summary, frames = _result()
    summary["error"] = ""
    store_run(tmp_path, _run(), (summary, frames), NO_INPUTS)
    loaded, loaded_frames = load_run(tmp_path, _run())
    assert loaded["error"].tolist() == [""] * 4
    # what run_suite returned before stored jobs were verified: the CSVs read back as they are
    old = pd.read_csv(io.StringIO(summary.to_csv(index=False)), dtype={"error": str}).fillna({"error": ""})
    assert loaded.dtypes.to_dict() == old.dtypes.to_dict()
    assert loaded_frames.dtypes.to_dict() == pd.read_csv(io.StringIO(frames.to_csv(index=False))).dtypes.to_dict()
    assert capsys.readouterr().err == ""


def test_a_truncated_run_file_is_recomputed_by_a_resumed_sweep(tmp_path, capsys):
    """The issue's experiment end to end: ``head -n 1`` of a stored summary, then resume."""

    path = tmp_path / "suite.yaml"
    path.write_text("base: {frames: 2, resolution: [320, 240]}\nscenes: [checkerboard]\n"
                    "difficulties: {easy: {}, hard: {belief: {sigma_rotation: 2.0}}}\nmethods: [enn, mnn]\nseeds: [0]\n")
    suite = load_suite(path)
    first, _ = run_suite(suite, tmp_path / "runs", progress=False)
    stored = sorted((tmp_path / "runs" / "runs").glob("*.summary.csv"))
    assert len(stored) == 4   # one a run: two methods × two difficulties
    stored[0].write_text("".join(stored[0].read_text().splitlines(keepends=True)[:1]))
    capsys.readouterr()
    again, _ = run_suite(suite, tmp_path / "runs", progress=False)
    cols = ["scenario", "method", "precision", "recall", "f1"]
    assert len(again) == 4
    pd.testing.assert_frame_equal(again[cols], first[cols])
    assert "recomputing" in capsys.readouterr().err


def _kernel_module(tmp_path, monkeypatch, name):
    (tmp_path / f"{name}.py").write_text("def twice(x):\n    return 2 * x\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    return importlib.import_module(name)


@pytest.mark.parametrize("damage", ["truncated .nbc", "empty .nbi", "garbage .nbi"])
def test_a_damaged_numba_cache_file_is_recompiled(damage, tmp_path, monkeypatch, capsys):
    """numba loads a kernel's cache at its first call; a damaged file used to raise there on
    every run (UnpicklingError, EOFError) until the folder was deleted by hand."""
    import numba
    from numba.core import config

    monkeypatch.setattr(config, "CACHE_DIR", str(tmp_path / "numba"))
    monkeypatch.setitem(kernels._state, "discarded", False)   # the note is printed once per process
    mod = _kernel_module(tmp_path, monkeypatch, "h4kern_" + damage.replace(" ", "_").replace(".", ""))
    assert numba.njit(cache=True)(mod.twice)(3) == 6          # compiled and cached
    (nbc,) = (tmp_path / "numba").rglob("*.nbc")
    (nbi,) = (tmp_path / "numba").rglob("*.nbi")
    {"truncated .nbc": lambda: nbc.write_bytes(nbc.read_bytes()[:40]),
     "empty .nbi": lambda: nbi.write_bytes(b""),
     "garbage .nbi": lambda: nbi.write_bytes(b"\x80\x05garbage")}[damage]()
    capsys.readouterr()
    assert numba.njit(cache=True)(mod.twice)(4) == 8          # a new process would do the same
    assert "damaged" in capsys.readouterr().err
    assert numba.njit(cache=True)(mod.twice)(5) == 10         # healed: loads from the cache again
    assert capsys.readouterr().err == ""


def test_compiling_is_announced_only_when_it_happens(tmp_path, monkeypatch, capsys):
    import numba
    from numba.core import config

    monkeypatch.setattr(config, "CACHE_DIR", str(tmp_path / "numba"))
    mod = _kernel_module(tmp_path, monkeypatch, "h4kern_note")
    assert kernels.warm([lambda: numba.njit(cache=True)(mod.twice)(1)], "test kernels") is not None
    err = capsys.readouterr().err
    assert err.startswith("assocbench: compiling test kernels") and "done in" in err and err.count("\n") == 1
    assert kernels.warm([lambda: numba.njit(cache=True)(mod.twice)(1)], "test kernels") is None
    assert capsys.readouterr().err == ""


def _full(*args, **kwargs):
    raise OSError(errno.ENOSPC, "No space left on device")


def test_a_full_disk_is_one_line_and_a_group_lands_whole_or_not_at_all(tmp_path):
    (tmp_path / "frames.csv").write_text("old frames\n")

    def summary(tmp):
        tmp.write_text("half a summ")
        _full()

    with pytest.raises(UserError) as err:
        write_group({tmp_path / "frames.csv": lambda tmp: tmp.write_text("new frames\n"),
                     tmp_path / "summary.csv": summary})
    assert "No space left on device" in str(err.value) and "\n" not in str(err.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frames.csv"]   # no temporary files either
    assert (tmp_path / "frames.csv").read_text() == "old frames\n"


def test_a_full_disk_while_writing_a_csv_names_the_file(tmp_path, monkeypatch):
    monkeypatch.setattr(pd.DataFrame, "to_csv", _full)
    with pytest.raises(UserError, match=r"cannot write .*summary\.csv.*No space left.*--out"):
        with atomic_path(tmp_path / "summary.csv") as tmp:
            pd.DataFrame({"a": [1]}).to_csv(tmp)
    assert list(tmp_path.iterdir()) == []


def test_a_run_cut_short_by_a_full_disk_is_not_stored(tmp_path, monkeypatch):
    run, result = _run(), _result()
    real = type(tmp_path).write_bytes
    monkeypatch.setattr(type(tmp_path), "write_bytes",
                        lambda self, data: _full() if "frames" in self.name else real(self, data))
    with pytest.raises(UserError, match="No space left"):
        store_run(tmp_path, run, result, NO_INPUTS)
    monkeypatch.undo()
    assert load_run(tmp_path, run) is None


def test_an_unusable_cache_folder_names_the_cache_not_out(tmp_path, monkeypatch):
    blocker = tmp_path / "cache-is-a-file"
    blocker.write_text("")
    monkeypatch.setenv("ASSOCBENCH_CACHE", str(blocker))
    with pytest.raises(UserError) as err:
        load_sequence(SMALL)
    message = str(err.value)
    assert "cache folder" in message and "ASSOCBENCH_CACHE" in message and "--out" not in message


@pytest.mark.parametrize("command", [["run", "--method", "projective", "--scene", "crates", "--frames", "2"],
                                     ["leaderboard", "--suite", "dense_ci"]])
def test_a_cache_variable_naming_a_file_is_one_line_before_any_work(command, tmp_path, monkeypatch, capsys):
    """ASSOCBENCH_CACHE=<a file>: exit 2 with one line before the run warms kernels or renders (it
    compiled into the temporary folder for minutes, rendered, and failed only when storing)."""
    from assocbench.cli.main import main
    from assocbench.harness import sandbox

    blocker = tmp_path / "cache-is-a-file"
    blocker.write_text("")
    monkeypatch.setenv("ASSOCBENCH_CACHE", str(blocker))
    monkeypatch.setattr(sandbox, "execute", lambda *a, **k: pytest.fail("ran before the error"))
    monkeypatch.setattr("assocbench.cli.run_cmd.execute", lambda *a, **k: pytest.fail("ran before the error"))
    monkeypatch.setattr("assocbench.cli.leaderboard_cmd.run_suite", lambda *a, **k: pytest.fail("ran before the error"))
    assert main([*command, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(blocker) in err[0] and "is a file" in err[0] and "ASSOCBENCH_CACHE" in err[0], err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command, work", [
    (["frame", "--scene", "crates", "-o", "{out}/f.png"], "assocbench.tracks.camera.track.CameraTrack.frame_picture"),
    (["render", "--method", "jcbb", "--scene", "crates", "--frames", "2", "-o", "{out}/r.mp4"],
     "assocbench.cli.render_cmd.execute"),
    (["export", "--suite", "ci", "--out", "{out}/e"], "assocbench.cli.export_cmd.export_suite"),
    (["check", "--suite", "dense_ci"], "assocbench.cli.check_cmd.check_suite"),
])
def test_every_command_that_renders_stops_on_a_cache_file_before_any_work(command, work, tmp_path, monkeypatch,
                                                                           capsys):
    """frame, render, export and check render sequences into the cache too: the same one line and
    exit 2 as run and leaderboard, before they render (they failed only when storing)."""
    from assocbench.cli.main import main

    blocker = tmp_path / "cache-is-a-file"
    blocker.write_text("")
    monkeypatch.setenv("ASSOCBENCH_CACHE", str(blocker))
    monkeypatch.setattr(work, lambda *a, **k: pytest.fail("worked before the error"))
    assert main([a.format(out=tmp_path / "out") for a in command]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(blocker) in err[0] and "is a file" in err[0] and "ASSOCBENCH_CACHE" in err[0], err


@pytest.mark.parametrize("sub, command, work", [
    ("dense", ["run", "--method", "projective", "--scene", "crates", "--frames", "2", "--out", "{out}"],
     "assocbench.cli.run_cmd.execute"),
    ("sequences", ["run", "--method", "mnn", "--frames", "2", "--out", "{out}"], "assocbench.cli.run_cmd.execute"),
    ("planar", ["leaderboard", "--suite", "planar_ci", "--out", "{out}"], "assocbench.cli.leaderboard_cmd.run_suite"),
    ("lines", ["frame", "--scene", "office", "-o", "{out}/f.png"], "assocbench.tracks.plane.LidarTrack.frame_picture"),
])
def test_a_file_where_the_cache_keeps_a_subfolder_is_one_line_before_any_work(sub, command, work, tmp_path,
                                                                               monkeypatch, capsys):
    """$ASSOCBENCH_CACHE/<a track's subfolder> a plain file: exit 2 with one line naming it before the
    command compiles or renders (it compiled for 20 s, rendered, and failed when storing: "File exists")."""
    from assocbench.cli.main import main

    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / sub).write_text("")
    monkeypatch.setenv("ASSOCBENCH_CACHE", str(cache))
    monkeypatch.setattr(work, lambda *a, **k: pytest.fail("worked before the error"))
    assert main([a.format(out=tmp_path / "out") for a in command]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(cache / sub) in err[0] and "is a file" in err[0], err
    assert not (tmp_path / "out").exists()


def test_a_broken_link_where_the_cache_keeps_a_subfolder_is_one_line_before_any_work(tmp_path, monkeypatch, capsys):
    """$ASSOCBENCH_CACHE/planar a dangling symlink: exit 2 with one line naming it before the run
    compiles (``exists()`` is False for it: the kernels compiled for 34 s, then "File exists")."""
    from assocbench.cli.main import main

    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / "planar").symlink_to(tmp_path / "nowhere" / "zz")
    monkeypatch.setenv("ASSOCBENCH_CACHE", str(cache))
    monkeypatch.setattr("assocbench.cli.run_cmd.execute", lambda *a, **k: pytest.fail("worked before the error"))
    out = tmp_path / "out"
    assert main(["run", "--method", "jcbb", "--scene", "post_grid", "--frames", "2", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(cache / "planar") in err[0] and "broken link" in err[0], err
    assert not out.exists()


@pytest.mark.parametrize("command", [["run", "--method", "projective", "--scene", "crates", "--frames", "2"],
                                     ["leaderboard", "--suite", "dense_ci"]])
def test_a_cache_folder_that_cannot_be_created_is_one_line_before_any_work(command, tmp_path, monkeypatch, capsys):
    """ASSOCBENCH_CACHE under a folder where mkdir fails (e.g. /proc/x, or read-only; mkdir is made
    to fail here, as root may write anywhere): exit 2 with one line before the kernels compile
    (they compiled for 18 s into the temporary folder, then the render's store said so)."""
    from assocbench.cli.main import main
    from assocbench.harness import sandbox

    locked = tmp_path / "locked"
    locked.mkdir()
    real_mkdir = os.mkdir

    def mkdir(path, *args, **kwargs):
        if str(path).startswith(str(locked)):
            raise PermissionError(errno.EACCES, "Permission denied", str(path))
        return real_mkdir(path, *args, **kwargs)

    monkeypatch.setattr(os, "mkdir", mkdir)
    monkeypatch.setenv("ASSOCBENCH_CACHE", str(locked / "cache"))
    monkeypatch.setattr(sandbox, "execute", lambda *a, **k: pytest.fail("ran before the error"))
    monkeypatch.setattr("assocbench.cli.run_cmd.execute", lambda *a, **k: pytest.fail("ran before the error"))
    monkeypatch.setattr("assocbench.cli.leaderboard_cmd.run_suite", lambda *a, **k: pytest.fail("ran before the error"))
    assert main([*command, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(locked / "cache") in err[0] and "Permission denied" in err[0], err
    assert "ASSOCBENCH_CACHE" in err[0] and not (tmp_path / "out").exists()


def test_an_unreadable_cache_entry_names_the_cache(good_cache, tmp_path, monkeypatch):
    cache, _ = good_cache
    monkeypatch.setattr(np, "load", lambda *a, **k: (_ for _ in ()).throw(PermissionError(errno.EACCES, "Permission denied")))
    with pytest.raises(UserError, match=r"cache folder .*Permission denied.*ASSOCBENCH_CACHE"):
        load_sequence(SMALL, cache)


def test_folder_errors_name_the_setting_to_change(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    for role, fix in ((Role("baseline", "--baseline"), "choose a writable --baseline"),
                      (CACHE, "set ASSOCBENCH_CACHE to a writable folder")):
        with pytest.raises(UserError, match=fix):
            ensure_dir(blocker / "sub", role)


def test_an_empty_cache_variable_means_unset_and_a_relative_one_is_fixed_once(tmp_path, monkeypatch):
    from assocbench import _runtime

    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv("ASSOCBENCH_CACHE", "")
    assert _runtime.cache_root() == tmp_path / "home" / ".cache" / "assocbench"   # not the current folder
    _runtime._resolve_cache_env()
    assert "ASSOCBENCH_CACHE" not in os.environ and _runtime.cache_root() == tmp_path / "home" / ".cache" / "assocbench"
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("ASSOCBENCH_CACHE", "rel")
    _runtime._resolve_cache_env()
    monkeypatch.chdir(tmp_path / "elsewhere")   # a later chdir (or a worker started elsewhere)
    assert _runtime.cache_root() == tmp_path / "rel"


