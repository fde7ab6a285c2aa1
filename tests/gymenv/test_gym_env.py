"""The camera track's Gymnasium environment (every track's: test_gym_tracks.py): determinism, equivalence with `assocbench run`, pictures."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ResetNeeded

import assocbench.gymenv  # noqa: F401  (registers assocbench/Room-v0 and friends)
from assocbench.association.problem import Problem
from assocbench.errors import UserError
from assocbench.gymenv import AssociationEnv, classical_action, sample_mask, sample_valid_action
from assocbench.harness.config import defaults, merge, run_spec
from assocbench.harness.sandbox import execute
from assocbench.harness.suite import shipped_difficulties
from assocbench.viz import draw


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
    cfg = merge(merge(defaults(), shipped_difficulties()["medium"], "t"), {"frames": 6, "seed": 0, "method": "jcbb"}, "t")
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
    from assocbench.sim.render import FrameRenderer
    from assocbench.sim.scene import load_scene

    with FrameRenderer(load_scene("room"), 640, 480) as renderer:
        blank = renderer.render(env._seq.sequence.rotations[0], env._seq.sequence.positions[0])["rgb"]
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
    assert info["step_metrics"]["jointly_compatible"] is False   # it was no association, let alone a compatible one


def test_examples_run(capsys, monkeypatch):
    import runpy
    import sys

    monkeypatch.setattr(sys, "argv", ["example"])
    from pathlib import Path

    root = Path(__file__).resolve().parents[2] / "examples"
    runpy.run_path(str(root / "random_agent.py"), run_name="__main__")
    runpy.run_path(str(root / "classical_agent.py"), run_name="__main__")
    out = capsys.readouterr().out
    assert "random agent: return" in out and "0 invalid actions" in out and "jcbb: return" in out


# -- vector envs, action masks, end of episode, bad arguments (issues 10.5 and 11.15) ---------
SMALL = {"frames": 2, "resolution": (320, 240)}
# Async workers are spawned: forked ones cannot render once this process has (another test
# rendered here), and the env refuses that (test_async_close_after_a_failed_reset_returns)
SPAWN = {"context": "spawn"}


def refusal(env, action) -> str | None:
    """Why the env refuses ``action`` (None if it accepts it)."""
    try:
        env._check_action(action)
    except ValueError as exc:
        return str(exc)
    return None


# async: the same episodes as sync (test_gym_tracks' vector test, by default), so the slow set's
@pytest.mark.parametrize("mode,scene", [("sync", "Room"), pytest.param("async", "Room", marks=pytest.mark.slow),
                                        ("sync", "Corridor"), pytest.param("async", "Checkerboard", marks=pytest.mark.slow)])
def test_make_vec_runs_full_episodes(mode, scene):
    """Several episodes per env (autoreset included): every info entry stacks although candidates
    and features differ per env, and acting with info["truth"] earns exactly the true pairs."""
    envs = gym.make_vec(f"assocbench/{scene}-v0", num_envs=2, vectorization_mode=mode,
                        vector_kwargs=SPAWN if mode == "async" else {}, **SMALL)
    obs, info = envs.reset(seed=5)
    n_max, m_max = envs.single_action_space.shape[0], int(envs.single_action_space.nvec[0]) - 1
    sizes, done_episodes, resetting = set(), np.zeros(2, int), np.zeros(2, bool)
    for _ in range(6):                                    # two 2-frame episodes each, with the resets
        assert info["truth"].shape == (2, n_max) and info["action_mask"].shape == (2, n_max, m_max + 1)
        sizes.add(tuple(obs["landmark_mask"].sum(axis=1)) + tuple(obs["feature_mask"].sum(axis=1)))
        n_true = (info["truth"] >= 0).sum(axis=1)
        obs, reward, term, trunc, info = envs.step(info["truth"])
        assert np.array_equal(reward, np.where(resetting, 0, n_true))
        assert "invalid_action" not in info
        stepped = ~resetting
        assert np.array_equal(info.get("_step_metrics", np.zeros(2, bool)), stepped)
        if stepped.any():
            assert np.all(info["step_metrics"]["fp"][stepped] == 0)
        done_episodes += term
        resetting = term | trunc
    assert np.array_equal(done_episodes, [2, 2])
    assert any(s[0] != s[1] or s[2] != s[3] for s in sizes)   # the envs' frames really differ in size
    envs.close()


def test_async_envs_with_different_episode_lengths():
    """Envs whose episodes end at different steps: one resets while the other still scores."""
    fns = [lambda k=k: AssociationEnv(frames=k, resolution=(320, 240)) for k in (2, 3)]
    envs = gym.vector.AsyncVectorEnv(fns, **SPAWN)
    _, info = envs.reset(seed=[11, 12])
    terms = []
    for _ in range(7):
        _, reward, term, _, info = envs.step(info["truth"])
        terms.append(term.tolist())
        assert np.all(reward >= 0)
    assert [t[0] for t in terms] == [False, True, False, False, True, False, False]
    assert [t[1] for t in terms] == [False, False, True, False, False, False, True]
    assert info["_problem"].tolist() == [True, False]        # env 1's episode just ended: no frame left
    assert isinstance(info["problem"][0], Problem)           # pickled back from the worker
    assert info["problem"][0].n == info["action_mask"][0][:, 1:].any(axis=1).sum()
    envs.close()


def test_masked_sampling_respects_padding_and_valid_helper_is_one_to_one():
    env = gym.make("assocbench/Room-v0", **SMALL).unwrapped
    _, info = env.reset(seed=3)
    n, m = info["problem"].n, info["problem"].m
    assert n < env.max_landmarks and m < env.max_features          # there are padded slots
    assert refusal(env, env.action_space.sample()) is not None   # the plain sample pairs padded slots
    rng = np.random.default_rng(0)
    reasons, paired = set(), []
    for _ in range(200):
        a = env.action_space.sample(mask=sample_mask(info["action_mask"]))
        assert np.all(a[n:] == -1) and np.all((a[:n] >= -1) & (a[:n] < m))
        err = refusal(env, a)
        reasons.add(None if err is None else "more than once" in err)
        valid = sample_valid_action(info["action_mask"], rng)
        assert refusal(env, valid) is None
        used = valid[valid >= 0]
        assert len(set(used.tolist())) == len(used) and np.all(valid[n:] == -1)
        paired.append(len(used))
    assert reasons <= {None, True}                              # a masked sample fails only one-to-one
    assert np.mean(paired) > n / 2                               # valid, and not by pairing nothing
    _, reward, _, _, info = env.step(sample_valid_action(info["action_mask"], rng))
    assert "invalid_action" not in info


def test_masked_sampling_on_a_vector_env():
    envs = gym.make_vec("assocbench/Room-v0", num_envs=2, vectorization_mode="sync", **SMALL)
    _, info = envs.reset(seed=0)
    n = info["action_mask"][:, :, 1:].any(axis=2).sum(axis=1)
    a = np.stack([envs.single_action_space.sample(mask=sample_mask(rows)) for rows in info["action_mask"]])
    assert a.shape == envs.action_space.shape and all(np.all(a[e, n[e]:] == -1) for e in range(2))
    _, _, _, _, info = envs.step(sample_valid_action(info["action_mask"], np.random.default_rng(1)))
    assert "invalid_action" not in info
    envs.close()


def test_step_after_the_episode_ended_raises_and_never_scores():
    env = gym.make("assocbench/Room-v0", **SMALL)
    with pytest.raises(ResetNeeded):
        env.step(np.full(env.action_space.shape, -1))
    _, info = env.reset(seed=0)
    _, _, term, _, info = env.step(info["truth"])
    assert not term
    obs, _, term, _, info = env.step(info["truth"])
    assert term and info["scored_frame"] == 1 and "problem" not in info
    assert obs["landmark_mask"].sum() == 0 and np.all(info["truth"] == -1)   # no frame left
    with pytest.raises(ResetNeeded, match="episode is over"):
        env.step(np.full(env.action_space.shape, -1))
    _, info = env.reset(seed=0)                                     # reset starts a new episode
    assert info["frame"] == 0
    env.close()


def test_a_feature_used_twice_is_named_whatever_its_index():
    """The duplicate's index was looked up among the used features: an IndexError (a crash
    instead of a penalty) when the feature index exceeded their count."""
    env = gym.make("assocbench/Room-v0", **SMALL).unwrapped
    _, info = env.reset(seed=0)
    m = info["problem"].m
    action = np.where(np.arange(env.max_landmarks) < 2, m - 1, -1)
    _, reward, _, _, info = env.step(action)
    assert reward == -info["step_metrics"]["n"]
    assert info["invalid_action"] == f"association uses feature {m - 1} more than once"


@pytest.mark.parametrize("kwargs,msg", [
    ({"resolution": (0, 0)}, "resolution width"),
    ({"resolution": (640, 8)}, "resolution height"),
    ({"resolution": (640,)}, "resolution must be"),
    ({"frames": 0}, "frames"),
    ({"frames": 2.5}, "frames"),
    ({"frames": True}, "frames"),
    ({"difficulty": {"sigma_rotation": float("nan")}}, "difficulty.sigma_rotation"),
    ({"difficulty": {"sigma_landmark": float("inf")}}, "difficulty.sigma_landmark"),
    ({"difficulty": {"sigma_pixle": 1.0}}, "sigma_pixle"),
    ({"difficulty": "extreme"}, "unknown difficulty"),
    ({"difficulty": 3}, "difficulty must be"),
    ({"scene": "/nonexistent/scene.xml"}, "not found"),
    ({"scene": None}, "scene must be"),
    ({"config": "hard"}, "config must be"),
    ({"render_mode": "human"}, "render_mode"),
])
def test_bad_constructor_arguments_are_one_line_user_errors(kwargs, msg):
    with pytest.raises(UserError, match=msg) as exc:
        AssociationEnv(**{"frames": 2, **kwargs})
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_make_vec_refuses_bad_arguments_in_the_parent(mode):
    with pytest.raises(UserError, match="resolution width"):
        gym.make_vec("assocbench/Room-v0", num_envs=2, vectorization_mode=mode, resolution=(0, 0))


def test_reset_refuses_options():
    env = AssociationEnv(**SMALL)
    with pytest.raises(UserError, match="no options"):
        env.reset(seed=0, options={"frames": 5})


CLOSE_AFTER_FAILED_RESET = """
import gymnasium as gym, numpy as np, assocbench.gymenv

def vec():
    return gym.make_vec("assocbench/Room-v0", num_envs=2, vectorization_mode="async", frames=2,
                        resolution=(320, 240))    # forked workers: the default on Linux

envs = vec()
try:
    obs, info = envs.reset(seed=0)       # raised in the parent when info arrays differed in length
    for _ in range(3):
        obs, reward, term, trunc, info = envs.step(info["truth"])
    try:
        envs.reset(seed=1, options={"bogus": 1})
    except ValueError as exc:
        print("reset failed:", exc)
finally:
    envs.close()                         # hung for minutes when the reset had failed in the parent
print("closed")
env = gym.make("assocbench/Room-v0", frames=2, resolution=(320, 240), render_mode="rgb_array")
env.reset(seed=0)
env.render()                             # this process now holds an EGL context
envs = vec()
try:
    envs.reset(seed=0)                   # a forked worker would hang in its first render
except ValueError as exc:
    print("forked reset failed:", exc)
finally:
    envs.close()
print("closed again")
"""


def test_async_close_after_a_failed_reset_returns(tmp_path):
    """A failed reset (in a worker or in the parent) never leaves ``close`` or a worker hanging."""
    import subprocess
    import sys

    try:
        out = subprocess.run([sys.executable, "-c", CLOSE_AFTER_FAILED_RESET], capture_output=True, text=True,
                             timeout=120, cwd=tmp_path)
    except subprocess.TimeoutExpired:
        pytest.fail("an async vector env hung (reset or close)")
    assert out.returncode == 0, out.stderr[-2000:]
    assert "reset failed: AssociationEnv.reset takes no options" in out.stdout and "closed\n" in out.stdout
    assert "forked reset failed: this process was forked from one that had already rendered" in out.stdout
    assert "closed again" in out.stdout


def test_a_frame_whose_P_is_wrong_as_a_whole_is_refused_before_the_agent_sees_it():
    """Construction reads only P's diagonal blocks; the env checks the whole P (``validate``), as
    the harness does, when it takes a frame."""
    P = np.kron(np.ones((3, 3)), np.array([[2.0, 0.5], [0.5, 1.0]])) - 1e-6 * np.eye(6)
    bad = Problem(np.zeros((2, 2)), np.repeat(np.eye(2)[None], 2, 0), np.ones((3, 2)), P)
    env = gym.make("assocbench/Room-v0", **SMALL).unwrapped
    with pytest.raises(ValueError, match="Problem.P is not positive semidefinite"):
        env._take(bad, None)
