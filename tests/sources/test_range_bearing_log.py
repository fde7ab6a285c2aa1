"""The recorded range-bearing log reader (sources/range_bearing_log.py): the Victoria Park format
read right, every kind of bad log refused in one line naming the file, the line and the field,
at the CLI too (exit 2, nothing run)."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
from cli.test_cli import assert_one_line_error

from assocbench.cli.main import main
from assocbench.models.range_bearing import inverse
from assocbench.sources.range_bearing_log import LogError, read_log

GOOD = """# two poses, three sightings
LANDMARK 0 7 3.0 4.0 0.04 0.01 0.09
ODOMETRY 0 1 1.0 0.5 0.1 0.01 0 0 0.02 0 0.001   # a comment after a record
LANDMARK 1 7 2.0 4.0 0.04 0 0.04
LANDMARK 1 - 5.0 -1.0 0.04 0 0.04
"""
ODO = "ODOMETRY 0 1 1.0 0.0 0.0 0.01 0 0 0.01 0 0.001"


def write(tmp_path, text: str):
    path = tmp_path / "my.log"
    path.write_text(text)
    return path


def test_a_log_is_read_as_its_format_says(tmp_path):
    log = read_log(write(tmp_path, GOOD))
    assert list(log.pose_ids) == [0, 1] and np.allclose(log.increments, [[1.0, 0.5, 0.1]])
    assert np.allclose(log.increment_covariances[0], np.diag([0.01, 0.02, 0.001]))
    assert list(log.sighting_pose) == [0, 1, 1] and list(log.sighting_ref) == [7, 7, -1]
    assert np.allclose(log.sighting_covariances[0], [[0.04, 0.01], [0.01, 0.09]])
    z, R = log.range_bearing()
    assert np.allclose(z[0], [5.0, np.arctan2(4.0, 3.0)])
    assert np.allclose(inverse(np.zeros(3), z[0]), [3.0, 4.0])   # (r, φ) places the sighting back
    G = np.array([[0.6, 0.8], [-4 / 25, 3 / 25]])                 # ∂(r, φ)/∂(x, y) at (3, 4)
    assert np.allclose(R[0], G @ log.sighting_covariances[0] @ G.T)


# one bad line, appended to a good log or replacing it: (text, the field named, the words that say why)
BAD = [
    ("ODOM 0 1 1 0 0 0.01 0 0 0.01 0 0.01", "kind", "expected ODOMETRY or LANDMARK"),
    ("ODOMETRY 0 1 1.0 0.0 0.0 0.01 0 0 0.01 0", "cθθ", "cθθ is missing"),
    ("LANDMARK 0 7 3.0 4.0 0.04 0.0 0.04 9", "syy", "1 extra column"),
    ("ODOMETRY 0 1 abc 0.0 0.0 0.01 0 0 0.01 0 0.01", "dx", "expected a number, got 'abc'"),
    ("ODOMETRY 0 1 1.0 nan 0.0 0.01 0 0 0.01 0 0.01", "dy", "must be finite"),
    ("LANDMARK 0 7 3.0 inf 0.04 0.0 0.04", "y", "must be finite"),
    ("ODOMETRY 0 1 1.0 0.0 0.0 -0.01 0 0 0.01 0 0.01", "cxx..cθθ", "not positive definite"),
    ("LANDMARK 0 7 3.0 4.0 0.04 0.05 0.04", "sxx..syy", "not positive definite"),
    ("ODOMETRY 3 2 1.0 0.0 0.0 0.01 0 0 0.01 0 0.01", "j", "must increase"),
    (f"{ODO}\nODOMETRY 2 3 1.0 0.0 0.0 0.01 0 0 0.01 0 0.01", "i", "does not continue the odometry chain"),
    (f"{ODO}\nLANDMARK 0 7 3.0 4.0 0.04 0.0 0.04", "k", "from the pose the robot is at (1)"),
    ("LANDMARK 0 x7 3.0 4.0 0.04 0.0 0.04", "ref", "expected an integer id"),
    ("LANDMARK 0 -3 3.0 4.0 0.04 0.0 0.04", "ref", "non-negative"),
    ("LANDMARK 0 7 3.0 4.0 0.04 0 0.04\nLANDMARK 0 7 3.1 4.0 0.04 0 0.04", "ref", "sighted twice from pose 0"),
    ("LANDMARK 0 7 0.0 0.0 0.04 0.0 0.04", "x, y", "no bearing"),
    ("# nothing but a comment", "kind", "holds no ODOMETRY or LANDMARK line"),
]


@pytest.mark.parametrize("text,field,why", BAD, ids=[f"{k}-{b[1]}" for k, b in enumerate(BAD)])
def test_a_bad_log_is_refused_in_one_line_naming_file_line_and_field(tmp_path, text, field, why):
    path = write(tmp_path, text + "\n")
    with pytest.raises(LogError) as err:
        read_log(path)
    message = str(err.value)
    line = len(text.splitlines())
    assert message.startswith(f"{path} line {line}, field {field}: ") and why in message, message
    assert "\n" not in message


def test_an_unreadable_file_is_refused_in_one_line(tmp_path):
    binary = tmp_path / "b.log"
    binary.write_bytes(b"\xff\xfe\x00ODOMETRY")
    for path, why in ((binary, "cannot be read as a text log"), (tmp_path / "none.log", "no such log file")):
        with pytest.raises(LogError, match=why):
            read_log(path)


@pytest.mark.skipif(importlib.util.find_spec("gtsam") is None, reason="the planar_log track needs gtsam")
@pytest.mark.parametrize("text,field,why", BAD[:10], ids=[b[1] for b in BAD[:10]])
def test_the_cli_refuses_a_bad_log_before_anything_runs(capsys, tmp_path, text, field, why):
    path = write(tmp_path, text + "\n")
    out = tmp_path / "out"
    code = main(["run", "--track", "planar_log", "--scene", str(path), "--method", "jcbb", "--out", str(out)])
    assert_one_line_error(capsys, code, str(path), f"field {field}", why)
    assert not out.exists()


@pytest.mark.skipif(importlib.util.find_spec("gtsam") is None, reason="the planar_log track needs gtsam")
def test_a_run_on_a_log_without_sightings_is_refused_before_anything_runs(capsys, tmp_path):
    """Reproduction: a log of odometry alone ran, cached a reference solution of 0 landmarks
    (chi2/dof nan) and stopped with a ``KeyError`` traceback from the harness."""
    path = write(tmp_path, f"{ODO}\n")
    out = tmp_path / "out"
    code = main(["run", "--track", "planar_log", "--scene", str(path), "--method", "jcbb", "--out", str(out)])
    assert_one_line_error(capsys, code, str(path), "holds no LANDMARK line")
    assert read_log(path).pose_ids.size and not out.exists()   # the reader takes it: a consistency study may


@pytest.mark.skipif(importlib.util.find_spec("gtsam") is None, reason="Victoria Park ships in the gtsam wheel")
def test_victoria_park_is_read_whole():
    from assocbench.tracks.planar_log.track import shipped_log

    log = read_log(shipped_log("victoria_park"))
    assert len(log.pose_ids) == 6969 and len(log.sighting_ref) == 3640 and len(np.unique(log.sighting_ref)) == 151
    assert np.bincount(log.sighting_pose).max() == 2 and (log.sighting_ref >= 0).all()
