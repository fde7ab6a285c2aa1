"""The dataset: rows written and read back as the same problems and truth, in batches, byte for
byte reproducible; ``assocbench export`` on the camera ci suite and its bad inputs."""

from __future__ import annotations

import hashlib
import importlib.util
import sys

import numpy as np
import pytest
from cli_errors import assert_one_line_error
from problems import random_problem

from assocbench import Problem
from assocbench.association.truth import FrameTruth
from assocbench.cli.main import main
from assocbench.dataset import read_card, read_problems
from assocbench.dataset.reader import count_frames
from assocbench.dataset.schema import ROW_GROUP
from assocbench.dataset.writer import DatasetWriter
from assocbench.errors import UserError


def labelled(rng, count: int) -> list:
    out = []
    for k in range(count):
        angular = (1,) if k % 3 == 0 else ()
        p = random_problem(rng, n=int(rng.integers(0, 6)), m=int(rng.integers(0, 7)), angular=angular)
        assoc = np.full(p.n, -1)
        assoc[: min(p.n, p.m)] = np.arange(min(p.n, p.m))
        labels = np.full(p.m, -1)
        labels[assoc[assoc >= 0]] = p.landmark_ids[assoc >= 0]
        truth = FrameTruth(labels, assoc, assoc >= 0)
        out.append(({"track": "camera", "scene": f"s{k % 2}", "difficulty": "easy", "seed": k % 4, "frame": k}, p, truth))
    return out


def write(folder, rows) -> None:
    with DatasetWriter(folder, {"title": "test"}) as w:
        for labels, p, t in rows:
            w.add(labels, p, t)


def test_round_trip_gives_back_the_same_problems_truth_and_labels_in_batches(tmp_path, rng):
    rows = labelled(rng, 2 * ROW_GROUP + 5)   # two full row groups and a partial one
    write(tmp_path / "d", rows)
    batches = list(read_problems(tmp_path / "d", batch_size=7))
    assert [len(b) for b in batches][:-1] == [7] * (len(batches) - 1)
    got = [item for b in batches for item in b]
    assert len(got) == len(rows) == count_frames(tmp_path / "d")
    for item, (labels, p, t) in zip(got, rows):
        assert item.problem == p and item.problem.angular == p.angular
        assert np.array_equal(item.problem.landmark_ids, p.landmark_ids)
        for name in ("feature_labels", "association", "visible"):
            assert np.array_equal(getattr(item.truth, name), getattr(t, name))
        assert (item.track, item.scene, item.difficulty, item.seed, item.frame) == tuple(labels.values())
    card = read_card(tmp_path / "d")
    assert card["sizes"]["frames"] == len(rows) and {c["name"] for c in card["schema"]} >= {"P", "association"}


def test_the_same_rows_give_the_same_bytes(tmp_path, rng):
    rows = labelled(rng, ROW_GROUP + 3)
    write(tmp_path / "a", rows)
    write(tmp_path / "b", rows)
    for name in ("problems.parquet", "card.yaml"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()


def test_a_failed_write_leaves_nothing(tmp_path, rng):
    rows = labelled(rng, 3)
    with pytest.raises(RuntimeError):
        with DatasetWriter(tmp_path / "d", {}) as w:
            w.add(*rows[0])
            raise RuntimeError("interrupted")
    assert not any(p.name in ("problems.parquet", "card.yaml") for p in (tmp_path / "d").iterdir())


def test_without_pyarrow_export_says_how_to_install_it(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyarrow", None)   # import pyarrow now raises ImportError
    assert_one_line_error(capsys, main(["export", "--suite", "ci", "--out", str(tmp_path / "d")]),
                          "pip install 'assocbench[learn]'")
    assert not (tmp_path / "d").exists()


def test_reading_a_folder_that_is_no_export_is_one_line(tmp_path):
    from assocbench.errors import UserError

    with pytest.raises(UserError, match="is not an assocbench export"):
        next(read_problems(tmp_path))


def test_a_damaged_export_is_one_line_for_the_reader_and_for_train(tmp_path, rng, capsys):
    """A truncated table, a table of other columns and a card that is not YAML are refused in one
    line (pyarrow's and yaml's own errors were tracebacks, exit 1), and train writes no model."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from assocbench.errors import UserError

    write(tmp_path / "ok", labelled(rng, 3))
    table, card = tmp_path / "ok" / "problems.parquet", tmp_path / "ok" / "card.yaml"
    cases = {"truncated": ("not a readable Parquet table", lambda d: (d / "problems.parquet").write_bytes(
                 table.read_bytes()[:5])),
             "foreign": ("lacks the columns", lambda d: pq.write_table(pa.table({"x": [1]}), d / "problems.parquet")),
             "card": ("not a readable dataset card", lambda d: (d / "card.yaml").write_text("a: [1"))}
    for name, (needle, damage) in cases.items():
        folder = tmp_path / name
        folder.mkdir()
        (folder / "problems.parquet").write_bytes(table.read_bytes())
        (folder / "card.yaml").write_text(card.read_text())
        damage(folder)
        with pytest.raises(UserError, match=needle):
            next(read_problems(folder))
        model = tmp_path / f"{name}.json"
        assert_one_line_error(capsys, main(["train", "--data", str(folder), "--out", str(model)]), needle)
        assert not model.exists()


def test_export_refuses_a_non_empty_folder_an_unknown_suite_and_the_dense_track(tmp_path, capsys):
    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "keep.txt").write_text("mine")
    assert_one_line_error(capsys, main(["export", "--suite", "ci", "--out", str(busy)]), "is not empty")
    assert (busy / "keep.txt").read_text() == "mine" and len(list(busy.iterdir())) == 1
    assert_one_line_error(capsys, main(["export", "--suite", "nosuch", "--out", str(tmp_path / "a")]),
                          "neither a file nor a shipped suite")
    assert_one_line_error(capsys, main(["export", "--suite", "dense_ci", "--out", str(tmp_path / "b")]),
                          "dense track", "not Problems")
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


@pytest.mark.slow   # a whole suite: the round trip and the same bytes are the tests above, on small tables
def test_export_of_the_camera_ci_suite_is_reproducible_and_round_trips(tmp_path):
    """Written twice: the same bytes; read back: the very problems the harness scores."""
    from assocbench.harness.config import run_spec
    from assocbench.harness.runner import Problems
    from assocbench.harness.suite import load_suite, resolve_suite

    assert main(["export", "--suite", "ci", "--out", str(tmp_path / "a"), "--quiet"]) == 0
    assert main(["export", "--suite", "ci", "--out", str(tmp_path / "b"), "--quiet"]) == 0
    for name in ("problems.parquet", "card.yaml"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    suite = load_suite(resolve_suite("ci"))
    expected = []
    for cell in suite.cells:
        spec = run_spec(cell.config(suite.methods[0]))
        problems = Problems(spec.track_impl, spec.source, spec)
        expected += [problems[k] for k in range(len(problems))]
    got = [item for batch in read_problems(tmp_path / "a", batch_size=5) for item in batch]
    assert len(got) == len(expected) == read_card(tmp_path / "a")["sizes"]["frames"]
    for item, (problem, truth) in zip(got, expected):
        assert item.problem == problem and np.array_equal(item.truth.association, truth.association)
        assert np.array_equal(item.truth.feature_labels, truth.feature_labels)


def test_a_table_changed_after_export_is_refused_by_the_reader_and_by_train(tmp_path, rng, capsys):
    """Reproduction: an export whose problems.parquet was replaced by one with other truth labels
    (every true pair undone) read and trained silently: the card's recorded SHA-256 was never
    checked. Refused in one line now; so is a card that records no digest."""
    import yaml

    from assocbench.errors import UserError

    rows = labelled(rng, 5)
    write(tmp_path / "ok", rows)
    undone = [(labels, p, FrameTruth(np.full(p.m, -1), np.full(p.n, -1), t.visible)) for labels, p, t in rows]
    write(tmp_path / "other", undone)
    (tmp_path / "ok" / "problems.parquet").write_bytes((tmp_path / "other" / "problems.parquet").read_bytes())
    with pytest.raises(UserError, match="is not the table its card records .* changed after export"):
        next(read_problems(tmp_path / "ok"))
    model = tmp_path / "m.json"
    assert_one_line_error(capsys, main(["train", "--data", str(tmp_path / "ok"), "--out", str(model)]),
                          "is not the table its card records")
    assert not model.exists()
    card = yaml.safe_load((tmp_path / "other" / "card.yaml").read_text())
    del card["files"]
    (tmp_path / "other" / "card.yaml").write_text(yaml.safe_dump(card))
    with pytest.raises(UserError, match="records no sha256 of problems.parquet"):
        next(read_problems(tmp_path / "other"))


def test_a_truth_that_does_not_fit_its_problem_is_refused_on_read(tmp_path, rng):
    """The reader checks each frame's truth against its problem (``FrameTruth.validate``), as the
    harness does: every candidate's true feature 0 is no truth an export can hold."""
    from assocbench.errors import UserError

    rows = [(labels, p, FrameTruth(np.zeros(p.m, np.int64), np.zeros(p.n, np.int64), t.visible))
            for labels, p, t in labelled(rng, 8) if p.n >= 2 and p.m >= 1]
    write(tmp_path / "d", rows)
    with pytest.raises(UserError, match="in the export is invalid: FrameTruth.association pairs feature 0"):
        next(read_problems(tmp_path / "d"))
def with_appearance(rows: list, rng) -> list:
    """The rows with descriptors on every other frame: SIFT-like bytes (D = 128) for the
    measurements, float means for the candidates."""
    out = []
    for k, (labels, p, t) in enumerate(rows):
        if k % 2 == 0:
            p = Problem(p.z, p.R, p.zhat, p.P, p.landmark_ids, p.volume, p.angular,
                        descriptors=rng.integers(0, 256, (p.m, 128)).astype(np.uint8),
                        landmark_descriptors=rng.uniform(0, 255, (p.n, 128)).astype(np.float32))
        out.append((labels, p, t))
    return out


def test_descriptors_round_trip_and_a_problem_without_them_stays_without(tmp_path, rng):
    rows = with_appearance(labelled(rng, ROW_GROUP + 3), rng)
    write(tmp_path / "d", rows)
    got = [item for b in read_problems(tmp_path / "d") for item in b]
    for item, (_, p, _) in zip(got, rows):
        assert item.problem == p
        assert (item.problem.descriptors is None) == (p.descriptors is None)
    card = read_card(tmp_path / "d")
    assert card["schema_version"] == 2 and {"descriptors", "landmark_descriptors"} <= {c["name"] for c in card["schema"]}


def test_a_version_1_export_is_still_read_as_problems_without_descriptors(tmp_path, rng):
    """A table written before the appearance columns existed (schema version 1)."""
    import pyarrow.parquet as pq
    import yaml

    rows = labelled(rng, 4)
    write(tmp_path / "d", rows)
    table = pq.read_table(tmp_path / "d" / "problems.parquet")
    pq.write_table(table.drop_columns(["descriptor_length", "descriptors", "landmark_descriptors"]),
                   tmp_path / "d" / "problems.parquet")
    card = yaml.safe_load((tmp_path / "d" / "card.yaml").read_text())
    table_sha = hashlib.sha256((tmp_path / "d" / "problems.parquet").read_bytes()).hexdigest()
    card["files"]["problems.parquet"]["sha256"] = table_sha   # the card of the table as version 1 wrote it
    (tmp_path / "d" / "card.yaml").write_text(yaml.safe_dump(card | {"schema_version": 1}))
    got = [item for b in read_problems(tmp_path / "d") for item in b]
    assert [item.problem for item in got] == [p for _, p, _ in rows]
    assert all(item.problem.descriptors is None for item in got)
    (tmp_path / "d" / "card.yaml").write_text(yaml.safe_dump(card | {"schema_version": 3}))
    with pytest.raises(UserError, match="reads versions 1, 2"):
        next(read_problems(tmp_path / "d"))


@pytest.mark.skipif(importlib.util.find_spec("gtsam") is None, reason="the photos track reads gtsam's data")
def test_export_of_a_photos_suite_writes_the_sift_descriptors_and_says_reference(tmp_path):
    suite = tmp_path / "photos.yaml"
    suite.write_text("track: photos\nscenes: [balbianello]\nbase: {frames: 2}\ndifficulties: {easy: {}}\n"
                     "methods: [mnn]\nseeds: [0]\n")
    assert main(["export", "--suite", str(suite), "--out", str(tmp_path / "d"), "--quiet"]) == 0
    got = [item for b in read_problems(tmp_path / "d") for item in b]
    assert [g.problem.m for g in got] == [2455, 2082]
    for item in got:
        assert item.problem.descriptors.shape == (item.problem.m, 128)
        assert item.problem.landmark_descriptors.shape == (item.problem.n, 128)
        assert np.array_equal(item.problem.descriptors, np.round(item.problem.descriptors))   # SIFT's bytes, exactly
    card = read_card(tmp_path / "d")
    assert card["labels"] == "reference" and "gtsam" in card["licence"] and card["track"] == "photos"
