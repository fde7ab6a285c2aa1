"""Every registered track keeps the ``Track`` contract that ``list``, ``check``, the config and
the harness rely on; a scene belongs to one track. Parsing only: nothing renders."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Mapping

import pytest

from assocbench.errors import UserError
from assocbench.harness.config import defaults
from assocbench.harness.suite import load_suite, resolve_suite
from assocbench.tracks.base import Track
from assocbench.tracks.inference import scene_marks, track_for_scene
from assocbench.tracks.registry import iter_tracks

TRACKS = list(iter_tracks())


@pytest.mark.parametrize("track", TRACKS, ids=[t.name for t in TRACKS])
def test_a_registered_track_keeps_the_contract(track):
    assert track.name and track.summary
    sections = track.config_sections()
    assert isinstance(sections, Mapping) and all(isinstance(v, Mapping) for v in sections.values())
    assert all(defaults()[name] == section for name, section in sections.items())   # the schema has them
    picked_by_method = type(track).claims_method is not Track.claims_method
    for scene in track.shipped_scenes():
        marks = scene_marks(scene)   # resolves: a shipped name
        owner = track_for_scene(scene)
        if track.claims_scene(marks):
            assert owner is track, f"{scene} goes to {owner.name}"
        else:   # a track its methods pick (dense): its scenes follow another track's convention
            assert picked_by_method and owner is not track and owner.claims_scene(marks), scene
    assert set(track.ci_suites) <= set(track.suites)
    for suite in track.suites:
        assert resolve_suite(suite).is_file(), suite   # a shipped config, not a path


@pytest.mark.parametrize("track", [t for t in TRACKS if t.ci_suites], ids=lambda t: t.name)
def test_a_tracks_ci_suites_load_and_run_on_it(track):
    for name in track.ci_suites:
        suite = load_suite(resolve_suite(name))
        assert suite.track == track.name, name   # the suite's runs (by scene, or by method: dense) are its


def test_a_scene_two_tracks_claim_is_refused_in_one_line(tmp_path):
    scene = tmp_path / "both.xml"
    scene.write_text('<mujoco><worldbody><site name="lm0" pos="0 0 1"/>'
                     '<geom name="lm1" type="cylinder" size="0.1 0.5" pos="1 0 0"/></worldbody></mujoco>')
    with pytest.raises(UserError) as err:
        track_for_scene(scene)
    message = str(err.value)
    assert "\n" not in message and "camera and planar" in message and "belongs to one track" in message


def test_the_built_ins_come_first_in_their_own_order_whatever_was_imported_first():
    """A built-in track's module imported before the registry is asked (a dense test, then ``check``
    in the same worker) registered first, so ``check`` named the dense suite's missing baseline
    before the camera's: the order must not depend on the imports."""
    code = ("import assocbench.tracks.dense.track, assocbench.tracks.lines.track\n"
            "from assocbench.tracks.base import tracks\n"
            "from assocbench.cli.check_cmd import default_suites\n"
            "print(list(tracks())[:4]); print(default_suites())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    first, suites = out.stdout.strip().splitlines()[-2:]
    assert first == "['camera', 'planar', 'lines', 'dense']"
    assert suites.index("'ci'") < suites.index("'loop_ci'") < suites.index("'lines_ci'") < suites.index("'dense_ci'")
