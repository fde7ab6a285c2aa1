"""Every registered track's Gymnasium envs, through one test body each: the ids come from the track
registry (``Track.gym_envs``), each passes Gymnasium's checker, its action masks are valid,
``make_vec`` sync and async give the same whole episodes for the same seeds, and bad input is
a one-line error. A plugin track gets its env from the registry, without editing ``gymenv``."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from assocbench.errors import UserError
from assocbench.gymenv import LoopAssociationEnv, env_ids, register_envs, sample_mask, sample_valid_action
from assocbench.tracks.capabilities import EnvSlots, GymEnv
from assocbench.tracks.registry import get_track

IDS = env_ids()                                    # id -> (track, GymEnv)
SHORT = {"frames": 2}
CAMERA = {"resolution": (320, 240)}                # small frames: the camera track renders them


def kwargs(env_id: str, **extra) -> dict:
    track = get_track(IDS[env_id][0])
    return {**SHORT, **(CAMERA if getattr(track, "renders_frames", False) else {}), **extra}


def first_per_track_and_mode() -> list[str]:
    """One id per track and mode (the first scene's): the vector-env runs, which start workers."""
    seen: dict[tuple[str, bool], str] = {}
    for env_id, (track, env) in IDS.items():
        seen.setdefault((track, env.loop), env_id)
    return list(seen.values())


def test_every_track_with_problems_offers_open_and_closed_envs_per_scene():
    tracks = {track for track, _ in IDS.values()}
    assert {"camera", "planar", "lines"} <= tracks and "dense" not in tracks
    for name in ("camera", "planar", "lines"):
        scenes = get_track(name).scenes()
        for loop in (False, True):
            assert sorted(env.scene for track, env in IDS.values() if track == name and env.loop == loop) \
                == sorted(scenes)
    assert {"assocbench/Room-v0", "assocbench/ParkLoop-v0", "assocbench/PostGrid-v0",
            "assocbench/HallwayLoop-v0"} <= set(IDS)
    assert all(env_id in gym.registry for env_id in IDS)


@pytest.mark.parametrize("env_id", list(IDS))
def test_checker_masks_and_a_bad_action(env_id):
    """Gymnasium's checker passes; every frame's mask allows exactly -1 on padded slots and -1 or a
    real feature on the n real ones; masked samples stay inside it; the true association scores
    every true pair; a feature used twice is refused (raise) or penalised with -n."""
    track = get_track(IDS[env_id][0])
    env = gym.make(env_id, **kwargs(env_id, render_mode="rgb_array" if getattr(track, "renders_frames", False) else None))
    check_env(env.unwrapped, skip_render_check=not getattr(track, "renders_frames", False))
    obs, info = env.reset(seed=3)
    rng, done = np.random.default_rng(0), False
    while not done:
        p, mask = info["problem"], info["action_mask"]
        assert p.d == env.unwrapped.dim and obs["features"].shape[1] == p.d
        assert mask.shape == (env.unwrapped.max_landmarks, env.unwrapped.max_features + 1)
        assert np.all(mask[:, 0] == 1) and np.all(mask[p.n:, 1:] == 0)
        assert np.all(mask[:p.n, 1:p.m + 1] == 1) and np.all(mask[:, p.m + 1:] == 0)
        assert obs["landmark_mask"].sum() == p.n and obs["feature_mask"].sum() == p.m
        sample = env.action_space.sample(mask=sample_mask(mask))
        assert np.all(sample[p.n:] == -1) and np.all(sample[:p.n] < p.m)
        assert np.all(mask[np.arange(len(sample)), sample + 1] == 1)
        valid = sample_valid_action(mask, rng)
        assert np.all(mask[np.arange(len(valid)), valid + 1] == 1)
        n_true = int((info["truth"] >= 0).sum())
        obs, reward, done, _, info = env.step(info["truth"])
        assert reward == n_true and info["step_metrics"]["fp"] == 0
    env.close()
    raising = gym.make(env_id, **kwargs(env_id, invalid_action="raise")).unwrapped
    _, info = raising.reset(seed=3)
    assert info["problem"].n >= 2 and info["problem"].m >= 1         # feature 0 can be given twice
    twice = np.where(np.arange(raising.max_landmarks) < 2, 0, -1)
    with pytest.raises(ValueError, match="more than once"):
        raising.step(twice)
    penalised = gym.make(env_id, **kwargs(env_id)).unwrapped
    _, info = penalised.reset(seed=3)
    _, reward, _, _, info = penalised.step(twice)
    assert reward == -info["step_metrics"]["n"] < 0
    assert "more than once" in info["invalid_action"]


def vector_episodes(env_id: str, mode: str) -> list:
    """Two envs over two whole 3-frame episodes each (autoreset included), acting with valid random
    actions drawn from a fixed generator: everything each step returns."""
    # a track of rendered frames spawns its workers (a forked one cannot render once this process has);
    # the others fork theirs, which they may: they never render
    spawn = mode == "async" and getattr(get_track(IDS[env_id][0]), "renders_frames", False)
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode=mode,
                        vector_kwargs={"context": "spawn"} if spawn else {}, **kwargs(env_id, frames=3))
    obs, info = envs.reset(seed=[21, 22])
    rng, steps = np.random.default_rng(5), [(obs, info["action_mask"], info["truth"])]
    for _ in range(8):
        obs, reward, term, trunc, info = envs.step(sample_valid_action(info["action_mask"], rng))
        loop = {k: info[k] for k in ("pos_err", "nees", "map_size") if k in info}
        steps.append((obs, reward, term, trunc, info["action_mask"], info["truth"], loop))
    envs.close()
    return steps


def same(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, tuple):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=np.asarray(a).dtype.kind == "f")


@pytest.mark.parametrize("env_id", first_per_track_and_mode())
def test_vector_envs_sync_and_async_give_the_same_episodes(env_id):
    sync, async_ = vector_episodes(env_id, "sync"), vector_episodes(env_id, "async")
    assert same(tuple(sync), tuple(async_))
    assert sum(int(step[2].sum()) for step in sync[1:]) == 4              # two episodes per env ended
    assert not same(sync[0][0]["predictions"][0], sync[0][0]["predictions"][1])   # two seeds, two episodes


@pytest.mark.parametrize("env_id", first_per_track_and_mode())
def test_the_same_seed_gives_the_same_episode(env_id):
    def episode(seed):
        env = gym.make(env_id, **kwargs(env_id, frames=3))
        obs, info = env.reset(seed=seed)
        rng, out, done = np.random.default_rng(1), [obs], False
        while not done:
            obs, reward, done, _, info = env.step(sample_valid_action(info["action_mask"], rng))
            out.append((obs, reward, info["step_metrics"]))
        return tuple(out)

    assert same(episode(4), episode(4))
    assert not same(episode(4)[0]["predictions"], episode(5)[0]["predictions"])


@pytest.mark.parametrize("env_id", first_per_track_and_mode())
def test_an_unknown_scene_is_a_one_line_error(env_id):
    with pytest.raises(UserError, match="no_such_scene") as exc:
        gym.make(env_id, **kwargs(env_id, scene="no_such_scene"))
    assert "\n" not in str(exc.value)


LIDAR_IDS = [env_id for env_id, (track, _) in IDS.items() if track in ("planar", "lines")]


@pytest.mark.parametrize("env_id", LIDAR_IDS)
def test_a_lidar_env_renders_the_top_view_of_each_step(env_id):
    """Reproduction: ``gymnasium.make("assocbench/Park-v0", render_mode="rgb_array")`` was refused
    (the planar and lines envs, 12 of 18 ids), although ``assocbench frame`` and ``render`` draw
    those tracks from above. ``render()`` gives that top view, (H, W, 3) uint8, after reset and
    after each step (the step's decisions coloured)."""
    env = gym.make(env_id, render_mode="rgb_array", **SHORT)
    assert env.unwrapped.metadata["render_modes"] == ["rgb_array"]
    _, info = env.reset(seed=1)
    first = env.render()
    assert first.ndim == 3 and first.shape[2] == 3 and first.dtype == np.uint8
    env.step(info["truth"])
    second = env.render()
    assert second.shape == first.shape and second.dtype == np.uint8 and not np.array_equal(first, second)
    env.close()


def test_a_lidar_env_records_with_gymnasiums_render_wrappers():
    """``RenderCollection`` (what ``RecordVideo`` builds on) gathers one picture per reset and step."""
    from gymnasium.wrappers import RenderCollection

    env = RenderCollection(gym.make("assocbench/ParkLoop-v0", render_mode="rgb_array", **SHORT))
    _, info = env.reset(seed=0)
    done = False
    while not done:
        _, _, done, _, info = env.step(info["truth"])
    frames = env.render()
    assert len(frames) == 3 and all(f.dtype == np.uint8 and f.ndim == 3 for f in frames)
    env.close()


def test_the_dense_track_has_no_env_and_says_why():
    with pytest.raises(UserError, match="the dense track has no Gymnasium env .scene 'room'.: its frames are not association"):
        gym.make("assocbench/Room-v0", track="dense", config={"method": "projective"}, **SHORT)


def test_lines_slam_is_refused_in_one_line():
    with pytest.raises(UserError, match="EKF localisation on the known map"):
        gym.make("assocbench/HallwayLoop-v0", mode="slam", **SHORT)


def test_planar_slam_slots_grow_to_the_map_cap():
    env = gym.make("assocbench/ParkLoop-v0", mode="slam", estimator={"max_landmarks": 120}, **SHORT).unwrapped
    assert env.max_landmarks == 120 > gym.make("assocbench/ParkLoop-v0", **SHORT).unwrapped.max_landmarks
    _, info = env.reset(seed=0)
    env.step(info["truth"])
    assert len(env.filter.book) > 0                                      # the map grew from the features


TOY_SCENE = """<mujoco><worldbody><site name="toy0" pos="0 0 0"/></worldbody></mujoco>"""


@pytest.fixture
def toy_envs(tmp_path):
    """A plugin track (the toy track of ``tests/tracks``) that declares one open-loop env."""
    import sys
    from pathlib import Path

    from assocbench.tracks import registry as base

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tracks"))
    from toy_track import ToyTrack

    scene = tmp_path / "toy.xml"
    scene.write_text(TOY_SCENE)

    class GymToy(ToyTrack):
        def gym_envs(self):
            return (GymEnv("assocbench/Toy-v0", str(scene)),)

        def env_slots(self, spec):
            n = spec.source.landmarks
            return EnvSlots(n, n + spec.belief.clutter)

    base._TRACKS.pop("toy", None)
    base.register_track(GymToy())
    yield
    base._TRACKS.pop("toy", None)
    gym.registry.pop("assocbench/Toy-v0", None)
    sys.path.remove(str(Path(__file__).resolve().parents[1] / "tracks"))


def test_a_plugin_track_gets_its_env_from_the_registry(toy_envs):
    assert "assocbench/Toy-v0" not in gym.registry
    register_envs()
    env = gym.make("assocbench/Toy-v0", frames=3, difficulty="hard")
    check_env(env.unwrapped)
    assert env.unwrapped.max_landmarks == 12
    _, info = env.reset(seed=0)
    assert info["problem"].n == 12
    with pytest.raises(UserError, match="the toy track has no closed loop"):
        LoopAssociationEnv(scene=env.unwrapped._cfg["scene"], frames=2)


def test_an_env_id_two_tracks_declare_is_refused(toy_envs):
    from assocbench.tracks import registry as base

    base._TRACKS["toy"].gym_envs = lambda: (GymEnv("assocbench/Room-v0", "room"),)
    with pytest.raises(UserError, match="assocbench/Room-v0 is declared by the camera and toy tracks"):
        env_ids()


# mnn on the post grid: jcbb's search on its lattice takes minutes per frame at this difficulty
@pytest.mark.parametrize("env_id,loop,method", [("assocbench/PostGrid-v0", False, "mnn"),
                                                ("assocbench/HallwayLoop-v0", True, "jcbb")])
def test_a_method_through_a_lidar_env_matches_assocbench_run(env_id, loop, method):
    """Driving the planar or lines env with a classical method counts what ``assocbench run``
    counts, frame by frame: the run's own frame loops (``frame_records``, ``loop_records``; ``run`` calls them in its
    worker) on the run config the env's arguments stand for."""
    from assocbench.gymenv import classical_action
    from assocbench.harness.config import defaults, merge, run_spec
    from assocbench.harness.loop import loop_records
    from assocbench.harness.runner import Problems, frame_records
    from assocbench.harness.suite import shipped_difficulties

    env = gym.make(env_id, frames=4, difficulty="medium").unwrapped
    _, info = env.reset(seed=2)
    counts, done = [], False
    while not done:
        _, _, done, _, info = env.step(classical_action(info, env.max_landmarks, method))
        counts.append((info["step_metrics"]["tp"], info["step_metrics"]["fp"], info["step_metrics"]["fn"]))
    track, env_spec = IDS[env_id]
    cfg = merge(merge(defaults(track), shipped_difficulties()["medium"], "t"),
                {"scene": env_spec.scene, "frames": 4, "seed": 2, "method": method, "loop": loop}, "t")
    spec = run_spec(cfg)
    if loop:
        records = list(loop_records(spec.source, spec))
    else:
        records = list(frame_records(Problems(spec.track_impl, spec.source, spec), method, {}))
    assert counts == [(r["tp"], r["fp"], r["fn"]) for r in records]
    assert sum(tp for tp, _, _ in counts) > 0


def test_a_frame_beyond_the_tracks_slots_is_a_one_line_error(toy_envs):
    """A track whose ``env_slots`` is no bound is named, instead of a numpy broadcasting error."""
    from assocbench.tracks import registry as base

    base._TRACKS["toy"].env_slots = lambda spec: EnvSlots(spec.source.landmarks - 1, 40)
    register_envs()
    env = gym.make("assocbench/Toy-v0", frames=2)
    with pytest.raises(RuntimeError, match=r"^frame 0 has 12 candidates .* 11 x 40 slots .* the toy track's "
                                           r"env_slots is not a bound$"):
        env.reset(seed=0)


def test_the_classical_agent_example_runs_a_planar_loop_env(capsys, monkeypatch):
    import runpy
    import sys
    from pathlib import Path

    example = Path(__file__).resolve().parents[2] / "examples" / "classical_agent.py"
    monkeypatch.setattr(sys, "argv", ["example", "jcbb", "assocbench/ParkLoop-v0"])
    runpy.run_path(str(example), run_name="__main__")
    out = capsys.readouterr().out
    assert "jcbb: return" in out and "last frame drawn (" in out and "final pose error 0.0" in out   # under 10 cm
