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
    ("tracks/planar/track.py", False),      # another track
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


def assert_same(made, read) -> None:
    """``read`` is ``made`` field for field, each array with its dtype and shape (lists item by item)."""
    import dataclasses

    import numpy as np

    assert type(read) is type(made)
    for f in dataclasses.fields(made):
        a, b = getattr(made, f.name), getattr(read, f.name)
        if dataclasses.is_dataclass(a):
            assert_same(a, b)
        elif isinstance(a, list) and a and dataclasses.is_dataclass(a[0]):
            assert len(a) == len(b) and all(assert_same(x, y) is None for x, y in zip(a, b))
        elif isinstance(a, (list, np.ndarray, np.generic)) and not (isinstance(a, list) and a and isinstance(a[0], str)):
            assert not isinstance(a, list) or len(a) == len(b), f.name
            pairs = list(zip(a, b)) if isinstance(a, list) else [(a, b)]
            for x, y in pairs:
                x, y = np.asarray(x), np.asarray(y)
                assert x.dtype == y.dtype and x.shape == y.shape and np.array_equal(x, y, equal_nan=True), f.name
        else:
            assert type(a) is type(b) and a == b, f.name


@pytest.mark.parametrize("scene", ["park", "office"])
def test_a_planted_cache_entry_runs_no_code(tmp_path, scene, capsys):
    """Reproduction: the planar and lines sequence caches were pickles, so a file planted at
    ``<cache>/planar/<key>.pkl`` ran its code when read, before the key was checked. Entries are
    NumPy archives read without pickle: a pickle planted at the entry's path (or inside an
    archive's member) is discarded as unusable and runs nothing; the sequence is made again."""
    import pickle

    import numpy as np

    from assocbench.harness.config import load_run_config, run_spec
    from assocbench.sim.cache import spec_key
    from assocbench.tracks.plane_source import maker_of
    from assocbench.tracks.registry import get_track

    def source():   # a fresh source each time: a source keeps what it loaded
        return run_spec(load_run_config(None, [], method="jcbb", scene=scene, frames=3)).source

    spec = source().spec
    track = get_track(source().track)
    made = maker_of(track.maker)(spec)
    marker = tmp_path / "ran"

    class Payload:
        def __reduce__(self):
            return (open, (str(marker), "w"))

    key = spec_key(spec, track.code)
    folder = tmp_path / track.name
    folder.mkdir()
    planted = pickle.dumps({"key": key, "sequence": Payload()})
    for suffix in (".pkl", ".npz"):
        (folder / f"{key}{suffix}").write_bytes(planted)
    assert_same(made, source().load(tmp_path))
    assert not marker.exists()
    with open(folder / f"{key}.npz", "wb") as fh:   # an archive whose member is a pickled object array
        np.savez(fh, __entry__=np.array([Payload()], dtype=object))
    assert_same(made, source().load(tmp_path))
    assert not marker.exists() and "is unusable" in capsys.readouterr().err


@pytest.mark.parametrize("scene", ["park", "office"])
def test_a_stored_sequence_reads_back_as_made_scans_and_all(tmp_path, scene):
    """``save_fields`` / ``load_fields`` give back the sequence as it was made, every array with
    its dtype and shape, the kept scans too (``keep_scans``, for the pictures)."""
    import dataclasses

    from assocbench.harness.config import load_run_config, run_spec
    from assocbench.sim.cache import load_fields, save_fields
    from assocbench.tracks.plane_source import maker_of

    spec = run_spec(load_run_config(None, [], method="jcbb", scene=scene, frames=3))
    made = maker_of(spec.track_impl.maker)(dataclasses.replace(spec.source.spec, keep_scans=True))
    save_fields(made, tmp_path / "entry.npz", "k")
    assert made.scans and made.scans[0] is not None
    assert_same(made, load_fields(tmp_path / "entry.npz", "k"))


def test_the_lidar_tracks_sequences_are_cached_and_heal(tmp_path, capsys):
    """The planar and lines tracks use the one sequence cache: a second load reads the entry (the
    same arrays), a damaged entry is discarded with one line and made again."""
    import numpy as np

    from assocbench.harness.config import load_run_config, run_spec

    for scene in ("park", "office"):
        def load():   # a fresh source each time: a source keeps what it loaded
            return run_spec(load_run_config(None, [], method="jcbb", scene=scene, frames=5)).source.load(tmp_path)

        first = load()
        (entry,) = (tmp_path / run_spec(load_run_config(None, [], scene=scene)).track).glob("*.npz")
        again = load()
        assert_same(first, again)
        entry.write_bytes(entry.read_bytes()[:100])      # truncated
        healed = load()
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
    file = path_csv(tmp_path)
    sets = ["trajectory=waypoints", f"trajectory_params.file={file}"]
    scene = str(room_mjcf(tmp_path, track))

    def source():   # a fresh source each time: its key is taken once, what it loads is kept
        return run_spec(load_run_config(None, sets, method="jcbb", scene=scene, frames=4)).source

    cache = tmp_path / "cache"
    before = source().key
    first = source().load(cache)
    assert source().key == before and first.poses[0, :2].tolist() == list(PATH[0])
    path_csv(tmp_path, [(7.5, 1.3)] + PATH[1:])                 # the first waypoint moved 10 cm
    assert source().key != before
    again = source().load(cache)
    assert again.poses[0, :2].tolist() == [7.5, 1.3] and len(list((cache / track).glob("*.npz"))) == 2
