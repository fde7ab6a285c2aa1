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
    ("tracks/planar/belief.py", False),     # another track
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


def test_the_lidar_tracks_sequences_are_cached_and_heal(tmp_path, capsys):
    """The planar and lines tracks use the one sequence cache: a second load reads the entry (the
    same arrays), a damaged entry is discarded with one line and made again."""
    import numpy as np

    from assocbench.harness.config import load_run_config, run_spec

    for scene in ("park", "office"):
        spec = run_spec(load_run_config(None, [], method="jcbb", scene=scene, frames=5))
        track = spec.track_impl
        first = track.load_sequence(spec.sequence, tmp_path)
        (entry,) = (tmp_path / track.name).glob("*.pkl")
        again = track.load_sequence(spec.sequence, tmp_path)
        assert all(np.array_equal(a, b) for a, b in zip(first.z, again.z)) and np.array_equal(first.poses, again.poses)
        entry.write_bytes(entry.read_bytes()[:100])      # truncated
        healed = track.load_sequence(spec.sequence, tmp_path)
        assert np.array_equal(healed.poses, first.poses)
        err = capsys.readouterr().err
        assert "is unusable" in err and "rendering again" in err


@pytest.mark.parametrize("track", ["planar", "lines"])
def test_a_lidar_tracks_key_follows_its_models_not_another_track(package_copy, track):
    from assocbench.tracks.registry import get_track
    code = __import__(f"assocbench.tracks.{track}.track", fromlist=["CODE"]).CODE
    before = fingerprint.sources_digest(*code)
    _edit(package_copy / "tracks/camera/detect.py")
    assert fingerprint.sources_digest(*code) == before
    _edit(package_copy / "models/range_bearing.py")
    assert fingerprint.sources_digest(*code) != before
    assert get_track(track).name == track


@pytest.mark.parametrize("track", ["planar", "lines"])
def test_editing_a_waypoint_file_drives_the_path_again(tmp_path, track):
    """The key holds the waypoint file's content, not only its name: the same spec after the
    file was edited is another entry, and the robot drives the new path."""
    from user_room import PATH, path_csv, room_mjcf

    from assocbench.harness.config import load_run_config, run_spec
    from assocbench.sim.cache import spec_key

    file = path_csv(tmp_path)
    sets = ["trajectory=waypoints", f"trajectory_params.file={file}"]
    spec = run_spec(load_run_config(None, sets, method="jcbb", scene=str(room_mjcf(tmp_path, track)), frames=4))
    impl, cache = spec.track_impl, tmp_path / "cache"
    before = spec_key(spec.sequence, impl.code)
    first = impl.load_sequence(spec.sequence, cache)
    assert spec_key(spec.sequence, impl.code) == before and first.poses[0, :2].tolist() == list(PATH[0])
    path_csv(tmp_path, [(7.5, 1.3)] + PATH[1:])                 # the first waypoint moved 10 cm
    assert spec_key(spec.sequence, impl.code) != before
    again = impl.load_sequence(spec.sequence, cache)
    assert again.poses[0, :2].tolist() == [7.5, 1.3] and len(list((cache / track).glob("*.pkl"))) == 2
