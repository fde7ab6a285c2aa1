"""The Gymnasium environment: checker, determinism, equivalence with `assocbench run`, pictures."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import assocbench  # noqa: F401
from assocbench.gymenv import ENV_IDS, classical_action
from assocbench.harness.config import DEFAULTS, merge, run_spec
from assocbench.harness.runner import execute
from assocbench.harness.suite import shipped_difficulties
from assocbench.viz import draw


@pytest.mark.parametrize("name", sorted(ENV_IDS))
def test_env_checker_passes_on_every_registered_id(name):
    env = gym.make(f"assocbench/{name}-v0", frames=3, render_mode="rgb_array")
    check_env(env.unwrapped, skip_render_check=False)
    env.close()


def rollout(env, seed, method="jcbb"):
    obs, info = env.reset(seed=seed)
    observations, rewards, done = [obs], [], False
    while not done:
        obs, reward, done, _, info = env.step(classical_action(info, env.action_space.shape[0], method))
        observations.append(obs)
        rewards.append(reward)
    return observations, rewards


def test_same_reset_seed_same_episode():
    env = gym.make("assocbench/Checkerboard-v0", frames=4, difficulty="medium")
    a_obs, a_rew = rollout(env, seed=7)
    b_obs, b_rew = rollout(env, seed=7)
    c_obs, _ = rollout(env, seed=8)
    assert a_rew == b_rew
    for x, y in zip(a_obs, b_obs):
        for key in x:
            assert np.array_equal(x[key], y[key])
    assert not all(np.array_equal(x["predictions"], y["predictions"]) for x, y in zip(a_obs, c_obs))


def test_jcbb_through_the_env_matches_assocbench_run():
    env = gym.make("assocbench/Room-v0", frames=6, difficulty="medium").unwrapped
    obs, info = env.reset(seed=0)
    totals, done = {"tp": 0, "fp": 0, "fn": 0, "perfect": 0}, False
    while not done:
        obs, _, done, _, info = env.step(classical_action(info, env.action_space.shape[0], "jcbb"))
        for k in totals:
            totals[k] += info["step_metrics"][k]
    cfg = merge(merge(DEFAULTS, shipped_difficulties()["medium"], "t"), {"frames": 6, "seed": 0, "method": "jcbb"}, "t")
    frames, summary = execute(run_spec(cfg))
    assert totals["tp"] == frames["tp"].sum() and totals["fp"] == frames["fp"].sum()
    assert totals["fn"] == frames["fn"].sum() and totals["perfect"] == frames["perfect"].sum()
    assert totals["tp"] / (totals["tp"] + totals["fp"]) == pytest.approx(summary["precision"])


def colour_count(img, rgb, tol=40):
    return int(np.sum(np.all(np.abs(img.astype(int) - np.array(rgb)) <= tol, axis=2)))


def test_rendered_frame_shows_the_association_colours():
    env = gym.make("assocbench/Room-v0", frames=2, difficulty="easy", render_mode="rgb_array").unwrapped
    obs, info = env.reset(seed=0)
    problem = info["problem"]
    action = classical_action(info, env.action_space.shape[0], "jcbb")
    assert (action[: problem.n] >= 0).sum() >= 4
    action[: problem.n][1::2] = -1          # leave every other candidate unassociated
    env.step(action)
    img = env.render()
    assert img.shape == (480, 640, 3) and img.dtype == np.uint8
    blank = env.unwrapped._renderer.render(env._seq.rotations[0], env._seq.positions[0])["rgb"]
    for j in range(problem.n):
        u, v = np.rint(problem.zhat[j]).astype(int)
        if not (3 <= u < 637 and 3 <= v < 477):
            continue
        patch = img[v - 1:v + 2, u - 1:u + 2]      # the '+' marker's centre
        expected = draw.BLUE if action[j] >= 0 else draw.RED
        assert colour_count(patch, expected) >= 3, (j, patch)
    for i in action[: problem.n][action[: problem.n] >= 0]:
        u, v = np.rint(problem.z[i]).astype(int)
        assert colour_count(img[v - 2:v + 3, u - 2:u + 3], draw.GREEN) >= 3       # green ×
    assert colour_count(img, draw.DARK_RED, 25) > colour_count(blank, draw.DARK_RED, 25)  # unassociated features


@pytest.mark.parametrize("bad,msg", [
    (lambda a, n, m: a[:-1], "shape"),
    (lambda a, n, m: np.where(np.arange(len(a)) == n, 0, a), "padded"),
    (lambda a, n, m: np.where(np.arange(len(a)) == 0, m + 3, a), "outside"),
    (lambda a, n, m: np.where(np.arange(len(a)) < 2, 0, -1), "more than once"),
])
def test_bad_actions_raise_or_are_penalised(bad, msg):
    env = gym.make("assocbench/Room-v0", frames=2, invalid_action="raise").unwrapped
    _, info = env.reset(seed=0)
    n, m = info["problem"].n, info["problem"].m
    action = bad(np.full(env.action_space.shape[0], -1), n, m)
    with pytest.raises(ValueError, match=msg):
        env.step(action)
    env = gym.make("assocbench/Room-v0", frames=2).unwrapped
    env.reset(seed=0)
    _, reward, _, _, info = env.step(action)
    assert reward == -n and msg in info["invalid_action"] and info["step_metrics"]["tp"] == 0


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_make_vec_works(mode):
    envs = gym.make_vec("assocbench/Checkerboard-v0", num_envs=2, vectorization_mode=mode, frames=2)
    obs, info = envs.reset(seed=[1, 2])
    assert obs["predictions"].shape[0] == 2
    obs, reward, term, trunc, info = envs.step(np.full(envs.action_space.shape, -1))
    assert reward.shape == (2,) and np.all(reward == 0)
    envs.close()


def test_examples_run(capsys, monkeypatch):
    import runpy
    import sys

    monkeypatch.setattr(sys, "argv", ["example"])
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "examples"
    runpy.run_path(str(root / "random_agent.py"), run_name="__main__")
    runpy.run_path(str(root / "classical_agent.py"), run_name="__main__")
    out = capsys.readouterr().out
    assert "random agent: return" in out and "jcbb: return" in out
