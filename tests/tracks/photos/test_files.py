"""Readers of a Bundler reconstruction: the bundle (v0.3) and Lowe's key files, on Balbianello as the
gtsam package ships it, and malformed files refused in one line naming the file and the line."""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest

from assocbench.errors import UserError
from assocbench.tracks.photos.files import read_bundle, read_keys

BUNDLE = """# Bundle file v0.3
2 2
500 -0.1 0.02
1 0 0
0 1 0
0 0 1
0 0 0.5
510 0 0
1 0 0
0 1 0
0 0 1
0.1 0 0.5
0.1 0.2 -2
10 20 30
2 0 4 12.5 -3.25 1 7 -40 2
-0.3 0.1 -2.5
200 100 50
1 1 9 5 6
"""


def test_a_small_bundle_reads_as_written(tmp_path):
    path = tmp_path / "b.out"
    path.write_text(BUNDLE)
    b = read_bundle(path)
    assert len(b.cameras) == 2 and b.cameras[0].f == 500 and b.cameras[0].k1 == -0.1
    np.testing.assert_array_equal(b.cameras[1].t, [0.1, 0, 0.5])
    np.testing.assert_array_equal(b.points[1], [-0.3, 0.1, -2.5])
    np.testing.assert_array_equal(b.views[0], [[0, 4, 12.5, -3.25], [1, 7, -40, 2]])
    assert b.observations == 3 and b.colours[0].tolist() == [10, 20, 30]


def test_balbianello_as_gtsam_ships_it():
    data = Path(pytest.importorskip("gtsam").__file__).parent / "Data"
    b = read_bundle(data / "Balbianello.out")
    assert (len(b.cameras), len(b.points), b.observations) == (5, 544, 1417)
    assert {len(v) for v in b.views} == {2, 3, 4, 5}
    keys = [data / "Balbianello" / f"BalbianelloMedium-{c}.key.gz" for c in range(1, 6)]
    assert [len(read_keys(k)) for k in keys] == [2455, 2082, 2184, 2087, 1783]
    keys = read_keys(keys[0])
    assert keys.descriptors.shape == (2455, 128) and keys.descriptors.dtype == np.uint8
    assert (keys.rows[0], keys.cols[0], keys.scales[0], keys.orientations[0]) == (283.77, 96.14, 51.56, 1.742)
    np.testing.assert_array_equal(keys.pixels[0], [96.14, 283.77])


@pytest.mark.parametrize("edit,message", [
    (lambda t: t.replace("# Bundle file v0.3", "# Bundle file v0.2"), "line 1: expected '# Bundle file v0.3'"),
    (lambda t: t.replace("2 2\n", "2 x\n"), "line 2: expected the counts"),
    (lambda t: t.replace("500 -0.1 0.02", "500 -0.1"), "line 3: expected a camera's 'f k1 k2'"),
    (lambda t: t.replace("0.1 0 0.5", "0.1 nan 0.5"), "line 12: expected a camera's translation"),
    (lambda t: t.replace("2 0 4 12.5 -3.25 1 7 -40 2", "2 0 4 12.5 -3.25 1 7 -40"), "line 15: expected a view list"),
    (lambda t: t.replace("1 1 9 5 6", "1 2 9 5 6"), "line 18: a view names a camera outside 0..1"),
    (lambda t: t.rsplit("\n", 2)[0], r"ends before a view list .* \(line 18\): the file is cut short"),
])
def test_a_malformed_bundle_is_one_line_naming_the_file_and_line(tmp_path, edit, message):
    path = tmp_path / "b.out"
    path.write_text(edit(BUNDLE))
    with pytest.raises(UserError, match=message) as err:
        read_bundle(path)
    assert str(path) in str(err.value) and "\n" not in str(err.value)


def write_keys(path, text: str) -> None:
    with gzip.open(path, "wt") as fh:
        fh.write(text)


@pytest.mark.parametrize("text,message", [
    ("2 4\n1 2 3 0.5\n0 1 2 3\n", "expected 2 keypoints of 4 \\+ 4 numbers each, got 8"),
    ("1 4\n1 2 3 0.5\n0 1 2 256\n", "descriptor entries must be integers 0-255"),
    ("1 4\n1 2 3 0.5\n0 1 2.5 3\n", "descriptor entries must be integers 0-255"),
    ("one 4\n", "expected Lowe's key format"),
    ("1 4\n1 2 3 x\n0 1 2 3\n", "expected Lowe's key format"),
])
def test_a_malformed_key_file_is_one_line_naming_it(tmp_path, text, message):
    path = tmp_path / "k.key.gz"
    write_keys(path, text)
    with pytest.raises(UserError, match=message) as err:
        read_keys(path)
    assert str(path) in str(err.value)


def test_plain_and_gzipped_key_files_read_the_same(tmp_path):
    text = "2 3\n10.5 20.25 1.5 0.3\n0 255 7\n11 21 2 -1\n1 2 3\n"
    (tmp_path / "k.key").write_text(text)
    write_keys(tmp_path / "k.key.gz", text)
    a, b = read_keys(tmp_path / "k.key"), read_keys(tmp_path / "k.key.gz")
    np.testing.assert_array_equal(a.descriptors, b.descriptors)
    np.testing.assert_array_equal(a.pixels, [[20.25, 10.5], [21, 11]])
    assert a.descriptors.tolist() == [[0, 255, 7], [1, 2, 3]]
    with pytest.raises(UserError, match="cannot read the key file"):
        read_keys(tmp_path / "missing.key")
