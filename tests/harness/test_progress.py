"""``assocbench run``'s progress bar (``harness.progress``): on stderr when it is a terminal (or
``--progress``), through every phase to the last frame; nothing when it is not, and the printed
results are the same either way."""

from __future__ import annotations

import io
import os
import pty
import subprocess
import sys
import types

from assocbench import kernels
from assocbench.cli.main import main
from assocbench.harness.progress import RunProgress
from assocbench.harness.runner import WARM_UP

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def run_args(tmp_path, name: str) -> list[str]:
    return ["run", "--method", "jcbb", "--scene", "post_grid", "--frames", "5", "--out", str(tmp_path / name)]


def metric_names(out: str) -> list[str]:
    return [line.split()[0] for line in out.splitlines() if line.strip()]


def test_the_bar_goes_through_the_phases_to_the_last_frame(tmp_path):
    with open(tmp_path / "bar.txt", "w+") as f:
        bar = RunProgress("jcbb", 3, file=f)
        for event, k in (("start", 0), ("tick", 0), ("call", WARM_UP), ("call", 0), ("frame", 0), ("frame", 2)):
            bar.watch(event, k)
        bar.close()
        f.seek(0)
        text = f.read()
    assert "preparing the sequence" in text and "building and warming up jcbb" in text and "3/3" in text


def test_the_rate_counts_from_the_first_frame_not_from_the_warm_up(tmp_path):
    """A long sequence build and warm-up (100 s here) must not set the frames' rate: a 2 s run
    showed "~2 min left" for its first 40 frames when the clock started at the worker's launch."""
    with open(tmp_path / "bar.txt", "w") as f:
        bar = RunProgress("jcbb", 50, file=f)
        bar.watch("start", 0)
        bar.watch("call", WARM_UP)
        bar.bar.start_t -= 100.0   # as if preparing and warming up had taken 100 s
        bar.watch("call", 0)
        bar.watch("frame", 0)
        elapsed = bar.bar.format_dict["elapsed"]
        bar.close()
    assert elapsed < 50.0, elapsed


def test_forced_bar_on_stderr_and_none_by_default_with_the_same_results(tmp_path, capsys):
    assert main(run_args(tmp_path, "a")) == 0
    plain = capsys.readouterr()
    assert main(run_args(tmp_path, "b") + ["--progress"]) == 0
    barred = capsys.readouterr()
    assert "5/5" not in plain.err and "frame/s" not in plain.err
    assert "5/5" in barred.err and "jcbb" in barred.err
    assert metric_names(plain.out) == metric_names(barred.out)   # the same table (timings aside)


def test_a_terminal_gets_the_bar_without_asking(tmp_path):
    """The CLI under a pseudo-terminal for stderr (stdout a pipe): the bar appears there."""
    master, slave = pty.openpty()
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen([sys.executable, "-m", "assocbench.cli.main", *run_args(tmp_path, "t")],
                            stdout=subprocess.PIPE, stderr=slave, env=env, cwd=tmp_path)
    os.close(slave)
    chunks = []
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:   # the terminal closed: the process ended
            break
        if not chunk:
            break
        chunks.append(chunk)
    out, _ = proc.communicate(timeout=300)
    os.close(master)
    err = b"".join(chunks).decode(errors="replace")
    assert proc.returncode == 0, err
    assert "5/5" in err and "jcbb" in err and b"precision" in out


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_workers_compile_note_on_a_terminal_replaces_the_bars_line(monkeypatch):
    """Numba compiling in the worker prints a note while the bar is shown: on a terminal it first
    erases the bar's line (the bar redraws below), in a log it is a plain line."""
    def kernel():
        return None

    kernel.__module__ = "assocbench.tracks.some_module"
    cache = types.SimpleNamespace(_py_func=kernel)
    for stream, start in ((_Terminal(), "\r\033[Kassocbench: compiling"), (io.StringIO(), "assocbench: compiling")):
        monkeypatch.setattr(sys, "stderr", stream)
        monkeypatch.setitem(kernels._state, "noted", False)
        monkeypatch.setitem(kernels._state, "active", False)
        kernels._compiling(cache)
        assert stream.getvalue().startswith(start), repr(stream.getvalue())
