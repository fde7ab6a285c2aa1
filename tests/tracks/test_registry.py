"""Every registered track keeps the core contract (``tracks.base``) that ``list``, ``check``, the
config and the harness rely on; the registry is lazy; a scene belongs to one track; no track name
is written outside ``tracks/``. Parsing only: nothing renders."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

from assocbench.errors import UserError
from assocbench.harness.config import defaults, run_schema
from assocbench.harness.suite import load_suite, resolve_suite
from assocbench.settings import Schema
from assocbench.tracks.base import Columns, GuardedMetric, SuiteFile, missing_hooks
from assocbench.tracks.capabilities import OwnFrames, SceneConvention, has
from assocbench.tracks.inference import scene_marks, track_for_scene
from assocbench.tracks.registry import BUILTINS, iter_tracks

TRACKS = list(iter_tracks())
PACKAGE = Path(__file__).resolve().parents[2] / "assocbench"


@pytest.mark.parametrize("track", TRACKS, ids=[t.name for t in TRACKS])
def test_a_registered_track_keeps_the_core_contract(track):
    assert track.name and track.summary and not missing_hooks(track)
    assert isinstance(track.settings(), Schema)
    assert defaults(track)["track"] == track.name and run_schema(track).defaults() | {"track": track.name} == \
        defaults(track)
    for loop in (False, True):
        cols = track.columns(loop)
        assert isinstance(cols, Columns) and cols.primary.name in cols.summary and cols.primary.unit
        assert all(isinstance(g, GuardedMetric) and g.name in cols.summary for g in track.guards(loop))
    for name, entry in track.suites().items():
        assert isinstance(entry, SuiteFile) and entry.path.is_file() and resolve_suite(name) == entry.path
    assert all(isinstance(line, str) and line for line in track.scenes().values())


@pytest.mark.parametrize("track", TRACKS, ids=[t.name for t in TRACKS])
def test_a_shipped_scene_goes_to_its_track_unless_its_methods_pick_the_track(track):
    for scene in track.scenes():
        owner = track_for_scene(scene)
        if has(track, OwnFrames):   # a track its methods pick (dense): its scenes follow another track's convention
            assert owner is not track and has(owner, SceneConvention)
            assert owner.claims_scene(scene_marks(resolve_scene(scene)))
        else:
            assert owner is track, f"{scene} goes to {owner.name}"


def resolve_scene(name: str) -> Path:
    from assocbench.sim.scene import resolve_scene_path

    return resolve_scene_path(name)


@pytest.mark.parametrize("track", TRACKS, ids=lambda t: t.name)
def test_a_tracks_ci_suites_load_and_run_on_it(track):
    for name, entry in track.suites().items():
        if entry.ci:
            assert load_suite(entry.path).track == track.name, name


def test_a_scene_two_tracks_claim_is_refused_in_one_line(tmp_path):
    scene = tmp_path / "both.xml"
    scene.write_text('<mujoco><worldbody><site name="lm0" pos="0 0 1"/>'
                     '<geom name="lm1" type="cylinder" size="0.1 0.5" pos="1 0 0"/></worldbody></mujoco>')
    with pytest.raises(UserError) as err:
        track_for_scene(scene)
    message = str(err.value)
    assert "\n" not in message and "camera and planar" in message and "--track" in message


def test_the_built_ins_come_first_in_their_own_order_whatever_was_imported_first():
    """A built-in track's module imported before the registry is asked (a dense test, then ``check``
    in the same worker) registered first, so ``check`` named the dense suite's missing baseline
    before the camera's: the order must not depend on the imports."""
    code = ("import assocbench.tracks.dense.track, assocbench.tracks.lines.track\n"
            "from assocbench.tracks.registry import tracks\n"
            "from assocbench.cli.check_cmd import default_suites\n"
            "print(list(tracks())[:4]); print(default_suites())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    first, suites = out.stdout.strip().splitlines()[-2:]
    assert first == "['camera', 'planar', 'lines', 'dense']"
    assert suites.index("'ci'") < suites.index("'loop_ci'") < suites.index("'lines_ci'") < suites.index("'dense_ci'")


HEAVY = ("cv2", "matplotlib", "gtsam", "pandas", "assocbench.sim.render", "assocbench.sim.lidar")
LIGHT = {"base", "capabilities", "registry", "inference", "plane", "track", "settings", "columns"}


def test_listing_the_tracks_and_resolving_a_method_import_no_tracks_heavy_modules():
    """Asking the registry imports each track's light module (its settings and hooks), never its
    pipeline: rendering, detection, kernels, the back ends."""
    code = ("import sys\nfrom assocbench.tracks.registry import iter_tracks\n"
            "from assocbench.tracks.inference import track_for_method\n"
            "names = [t.name + ': ' + t.summary for t in iter_tracks()]\n"
            "own = track_for_method('projective').name\n"
            f"print(own, [m for m in {HEAVY!r} if m in sys.modules])\n"
            "print(sorted({m.rsplit('.', 1)[1] for m in sys.modules if m.startswith('assocbench.tracks.')}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    lines = out.stdout.strip().splitlines()
    assert lines[-2] == "dense []", out.stdout + out.stderr
    assert set(ast.literal_eval(lines[-1])) - set(BUILTINS) <= LIGHT


def test_asking_for_one_built_in_loads_only_that_track():
    code = ("import sys\nfrom assocbench.tracks.registry import get_track\nget_track('planar')\n"
            "print(sorted(m.split('.')[2] for m in sys.modules if m.startswith('assocbench.tracks.') "
            "and m.count('.') >= 3))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert set(ast.literal_eval(out.stdout.strip().splitlines()[-1])) == {"planar"}


# the built-in tracks' names, as the harness, the CLI, the envs, the scores and the pictures must not
# write them: a word (camera, planar, dense) in any text, or "lines" used as a name
TRACK_WORDS = re.compile(r"\b(camera|planar|dense)\b|[\"']lines[\"']|\blines track\b", re.I)
GENERIC = ("harness", "cli", "gymenv", "scoring", "viz")


def test_no_track_is_named_outside_the_tracks():
    """What differs by track comes from the track: the report's title and primary metric, the
    sweep's columns, the leaderboard's prose, the error texts."""
    assert set(BUILTINS) >= {"camera", "planar", "lines", "dense"}
    found = [f"{path.relative_to(PACKAGE)}:{n}: {line.strip()}"
             for folder in GENERIC for path in sorted((PACKAGE / folder).rglob("*.py"))
             for n, line in enumerate(path.read_text().splitlines(), 1) if TRACK_WORDS.search(line)]
    assert found == []
