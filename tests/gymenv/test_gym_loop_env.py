"""The closed-loop Gymnasium envs (assocbench/<Scene>Loop-v0): checker, the filter follows the
agent's actions (and only valid ones), equivalence with the harness's closed loop, bad settings."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import assocbench.gymenv  # noqa: F401  (registers the envs)
from assocbench.errors import UserError
from assocbench.gymenv import LoopAssociationEnv, classical_action
from assocbench.harness.loop import ClosedLoop, loop_records

FRAMES = 10                  # one 640x480 room sequence per mode, rendered once per session (cache)
SMALL = {"frames": 3, "resolution": (320, 240)}


def episode(env, agent, seed=0) -> list[dict]:
    """Step infos of one episode; ``agent(env, info)`` is the action."""
    _, info = env.reset(seed=seed)
    infos, done = [], False
    while not done:
        _, _, done, _, info = env.step(agent(env, info))
        infos.append(info)
    return infos


def jcbb(env, info):
    return classical_action(info, env.action_space.shape[0], "jcbb")


def truth(env, info):
    return info["truth"]


def nothing(env, info):
    return np.full(env.action_space.shape[0], -1)


def column(infos, key) -> np.ndarray:
    return np.array([i[key] for i in infos], dtype=float)


@pytest.fixture(scope="module")
def runs():
    """jcbb, truth and pairing nothing (dead reckoning) over the same episode, in both modes."""
    out = {}
    for mode in ("localisation", "slam"):
        env = gym.make("assocbench/RoomLoop-v0", frames=FRAMES, mode=mode).unwrapped
        for name, agent in (("jcbb", jcbb), ("truth", truth), ("nothing", nothing)):
            out[mode, name] = episode(env, agent)
        out[mode, "env"] = env
    return out


def test_env_checker_passes_in_slam_mode(monkeypatch):
    """SLAM's first pose is fixed with zero covariance, so the first step's ``nees`` is NaN (as in
    ``run --loop``), and the checker's step-determinism test compares floats with ``==``
    (NaN ≠ NaN): here it compares NaN as equal to NaN, and everything else as it does."""
    from gymnasium.utils import env_checker

    plain = env_checker.data_equivalence

    def nan_equal(a, b, exact=False):
        if isinstance(a, float) and isinstance(b, float) and np.isnan(a) and np.isnan(b):
            return True
        if isinstance(a, dict) and isinstance(b, dict):
            return a.keys() == b.keys() and all(nan_equal(a[k], b[k], exact) for k in a)
        return plain(a, b, exact)

    monkeypatch.setattr(env_checker, "data_equivalence", nan_equal)
    env = gym.make("assocbench/RoomLoop-v0", mode="slam", **SMALL)
    check_env(env.unwrapped)
    _, info = env.reset(seed=0)
    _, _, _, _, info = env.step(info["truth"])
    assert np.isnan(info["nees"]) and info["pos_err"] == 0.0     # the gauge: frame 0 is the true pose
    env.close()


def test_landmark_slots_grow_to_the_map_cap_in_slam():
    scene = LoopAssociationEnv(**SMALL).max_landmarks          # localisation: the scene's landmarks
    assert scene == gym.make("assocbench/Room-v0", **SMALL).unwrapped.max_landmarks
    slam = LoopAssociationEnv(mode="slam", estimator={"max_landmarks": 300}, **SMALL)
    assert slam.max_landmarks == 300 and slam.action_space.shape == (300,)
    assert slam.observation_space["predictions"].shape == (300, 2)
    assert LoopAssociationEnv(mode="slam", estimator={"max_landmarks": 5}, **SMALL).max_landmarks == scene


def test_jcbb_keeps_the_localisation_error_small(runs):
    """Localisation: jcbb's pose error stays below 8 cm and 2 degrees over the episode (measured
    4.3 cm, 1.2 deg), and on average below half of dead reckoning's (pairing nothing: the filter
    only predicts; measured 2.4 cm against 8.3 cm)."""
    infos, dead = runs["localisation", "jcbb"], runs["localisation", "nothing"]
    pos, rot = column(infos, "pos_err"), column(infos, "rot_err_deg")
    assert np.all(np.isfinite(pos)) and np.all(np.isfinite(column(infos, "nees")))
    assert pos.max() < 0.08 and rot.max() < 2.0
    assert pos.mean() < 0.5 * column(dead, "pos_err").mean()
    assert sum(i["step_metrics"]["tp"] for i in infos) > 0.9 * sum(i["step_metrics"]["n_true"] for i in infos)


def test_jcbb_keeps_the_slam_error_small_and_builds_a_map(runs):
    """SLAM from an empty map: pose error finite and below 12 cm and 2 degrees (measured 5.2 cm,
    0.6 deg), and the map grows (measured 30 confirmed entries after 10 frames)."""
    infos = runs["slam", "jcbb"]
    pos, rot = column(infos, "pos_err"), column(infos, "rot_err_deg")
    assert np.all(np.isfinite(pos)) and pos.max() < 0.12 and rot.max() < 2.0
    assert infos[0]["map_size"] == 0 and infos[-1]["map_size"] >= 20


@pytest.mark.parametrize("mode", ["localisation", "slam"])
def test_truth_actions_give_a_finite_nees_and_no_worse_pose(runs, mode):
    """The true association: NEES finite (slam's first frame has zero pose covariance: NaN),
    every pairing right, and a mean pose error within 5 mm of jcbb's (measured 0.8 and 2.4 mm
    below it in localisation and slam)."""
    infos = runs[mode, "truth"]
    nees = column(infos, "nees")[1 if mode == "slam" else 0:]
    assert np.all(np.isfinite(nees)) and np.all(nees >= 0)
    assert all(i["step_metrics"]["fp"] == 0 for i in infos)
    assert column(infos, "pos_err").mean() <= column(runs[mode, "jcbb"], "pos_err").mean() + 0.005


@pytest.mark.parametrize("mode", ["localisation", "slam"])
def test_the_env_is_the_harness_closed_loop(runs, mode):
    """Acting with jcbb or the truth through the env gives the per-frame pose error, NEES and
    map of ``assocbench run --loop`` with jcbb or the oracle (``loop_records``)."""
    env = runs[mode, "env"]
    for agent, method in (("jcbb", "jcbb"), ("truth", "oracle")):
        records = list(loop_records(env._seq, env._spec.with_method(method, {})))
        infos = runs[mode, agent]
        for key in ("pos_err", "rot_err_deg", "nees", "map_size"):
            np.testing.assert_allclose(column(infos, key), [r[key] for r in records], rtol=1e-12, err_msg=key)
        assert [i["step_metrics"]["tp"] for i in infos] == [r["tp"] for r in records]


def test_an_invalid_action_is_a_failed_frame_and_leaves_the_filter_alone():
    """Penalised, the frame fails as in ``--loop``: the filter is not updated, only predicted to
    the next frame (same state as a ClosedLoop whose frame 0 failed), and its pose covariance
    grows; the valid truth action shrinks it instead."""
    env = gym.make("assocbench/RoomLoop-v0", frames=FRAMES).unwrapped
    _, info = env.reset(seed=0)
    prior = np.trace(env.filter.pose_covariance)
    twice = np.where(np.arange(env.max_landmarks) < 2, 0, -1)        # feature 0 given to two candidates
    _, reward, _, _, info = env.step(twice)
    assert "more than once" in info["invalid_action"] and reward == -info["step_metrics"]["n"]
    assert np.isfinite(info["pos_err"])
    reference = ClosedLoop(env._seq, env._spec)
    reference.frame(0, lambda problem, truth: (None, 0.0, {}, "failed"))
    reference.begin(1)
    assert np.array_equal(env.filter.p, reference.filter.p) and np.array_equal(env.filter.R, reference.filter.R)
    assert np.array_equal(env.filter.P, reference.filter.P)
    assert np.trace(env.filter.pose_covariance) > prior
    _, info = env.reset(seed=0)
    env.step(info["truth"])
    assert np.trace(env.filter.pose_covariance) < prior


def test_a_refused_action_raises_and_the_frame_can_be_retried():
    env = gym.make("assocbench/RoomLoop-v0", frames=FRAMES, invalid_action="raise").unwrapped
    _, info = env.reset(seed=0)
    before = env.filter.P.copy()
    with pytest.raises(ValueError, match="more than once"):
        env.step(np.where(np.arange(env.max_landmarks) < 2, 0, -1))
    assert np.array_equal(env.filter.P, before)
    _, reward, _, _, info = env.step(info["truth"])
    assert info["scored_frame"] == 0 and reward == info["step_metrics"]["n_true"]


def test_a_vector_env_stacks_the_loop_entries():
    envs = gym.make_vec("assocbench/RoomLoop-v0", num_envs=2, vectorization_mode="sync", **SMALL)
    _, info = envs.reset(seed=5)
    for _ in range(2):
        _, reward, _, _, info = envs.step(info["truth"])
        for key in ("pos_err", "rot_err_deg", "nees", "map_size"):
            assert info[key].shape == (2,) and np.all(np.isfinite(info[key]))
    assert not np.array_equal(info["pos_err"][0], info["pos_err"][1])     # two seeds, two filters
    envs.close()


@pytest.mark.parametrize("kwargs,msg", [
    ({"mode": "bogus"}, "mode must be one of localisation, slam"),
    ({"estimator": {"odometry_sigma_translation": -0.01}}, "estimator.odometry_sigma_translation"),
    ({"estimator": {"odometry_sigma_rotation": float("nan")}}, "estimator.odometry_sigma_rotation"),
    ({"estimator": {"odometry_sigma": 0.1}}, "unknown key 'estimator.odometry_sigma'"),
    ({"estimator": "slam"}, "estimator must be a mapping"),
    ({"config": {"estimator": {"mode": "mapping"}}}, "estimator.mode"),
    ({"config": {"loop": False}}, "always run the loop"),
    ({"config": {"estimator": 3}}, "config['estimator'] must be a mapping"),
])
def test_bad_settings_are_one_line_user_errors(kwargs, msg):
    with pytest.raises(UserError) as exc:
        LoopAssociationEnv(**{**SMALL, **kwargs})
    assert msg in str(exc.value) and "\n" not in str(exc.value)


def test_the_classical_agent_example_runs_the_loop_env(capsys, monkeypatch):
    import runpy
    import sys
    from pathlib import Path

    example = Path(__file__).resolve().parents[2] / "examples" / "classical_agent.py"
    monkeypatch.setattr(sys, "argv", ["example", "jcbb", "assocbench/RoomLoop-v0"])
    runpy.run_path(str(example), run_name="__main__")
    out = capsys.readouterr().out
    assert "jcbb: return" in out and "final pose error 0.0" in out      # under 10 cm
