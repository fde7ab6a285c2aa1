"""A cached sequence is keyed by the sources it depends on: shared simulation, measurement
models and its own track's folder. Editing a measurement model re-renders; editing another
track does not."""

import shutil

import pytest

from assocbench import fingerprint
from assocbench.tracks.camera import sequence as camera_sequence
from assocbench.tracks.dense import sequence as dense_sequence


@pytest.fixture
def package_copy(tmp_path, monkeypatch):
    root = tmp_path / "assocbench"
    shutil.copytree(fingerprint.PACKAGE_ROOT, root, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(fingerprint, "PACKAGE_ROOT", root)
    return root


def _edit(path):
    path.write_text(path.read_text() + "\n# edited\n")


@pytest.mark.parametrize("code", [camera_sequence.CODE, dense_sequence.CODE], ids=["camera", "dense"])
@pytest.mark.parametrize("edited, changes", [
    ("models/pinhole.py", True),            # a measurement model
    ("models/camera.py", True),             # the intrinsics
    ("sim/render.py", True),                # shared rendering
    ("tracks/planar/ekf.py", False),        # another track
    ("tracks/lines/extract.py", False),
    ("associators/jcbb.py", False),         # association never changes a sequence
])
def test_sequence_code_digest_follows_what_the_sequence_depends_on(package_copy, code, edited, changes):
    before = fingerprint.sources_digest(*code)
    _edit(package_copy / edited)
    assert (fingerprint.sources_digest(*code) != before) == changes


def test_each_track_digest_covers_its_own_folder(package_copy):
    before = {c: fingerprint.sources_digest(*c) for c in (camera_sequence.CODE, dense_sequence.CODE)}
    _edit(package_copy / "tracks/dense/depth_sensor.py")
    assert fingerprint.sources_digest(*camera_sequence.CODE) == before[camera_sequence.CODE]
    assert fingerprint.sources_digest(*dense_sequence.CODE) != before[dense_sequence.CODE]
