"""The dask executor's set-up errors are one line, exit 2, and leave no output folder: a missing
extra, no scheduler address, an unreachable scheduler (issue 26, items 3 and 4)."""

import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SUITE = "scenes: [room]\nmethods: [mnn]\nseeds: [0]\nbase: {frames: 2}\n"
NO_DASK = "import sys; sys.modules['dask'] = None; sys.modules['dask.distributed'] = None; "


def leaderboard(tmp_path, *args: str, prelude: str = "") -> subprocess.CompletedProcess:
    suite = tmp_path / "suite.yaml"
    suite.write_text(SUITE)
    code = prelude + "from assocbench.cli.main import main; sys.exit(main(sys.argv[1:]))"
    return subprocess.run([sys.executable, "-c", "import sys; " + code, "leaderboard", "--suite", str(suite),
                           "--out", str(tmp_path / "out"), "--executor", "dask", *args],
                          capture_output=True, text=True, env={**os.environ, "PYTHONPATH": ROOT}, timeout=120)


@pytest.mark.parametrize("args, prelude, needle", [
    (["--address", "tcp://127.0.0.1:1"], NO_DASK, "pip install 'assocbench[dask]'"),
    ([], "", "--address"),
    (["--address", "tcp://127.0.0.1:1"], "", "cannot reach dask scheduler"),
])
def test_dask_setup_errors_are_one_line_and_write_nothing(tmp_path, args, prelude, needle):
    out = leaderboard(tmp_path, *args, prelude=prelude)
    assert out.returncode == 2, out.stderr
    lines = [line for line in out.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("assocbench: error:") and needle in lines[0], out.stderr
    assert not (tmp_path / "out").exists()
