"""A random agent on the Gymnasium environment: it pairs each candidate with a random free
feature half of the time. Run: python examples/random_agent.py"""

import gymnasium as gym
import numpy as np

import assocbench  # noqa: F401  (registers assocbench/Room-v0 and friends)


def random_action(obs: dict, rng: np.random.Generator) -> np.ndarray:
    n, m = int(obs["landmark_mask"].sum()), int(obs["feature_mask"].sum())
    action = np.full(len(obs["landmark_mask"]), -1)
    picks = rng.permutation(m)[:n]
    chosen = rng.uniform(size=len(picks)) < 0.5
    action[: len(picks)][chosen] = picks[chosen]
    return action


def main() -> None:
    env = gym.make("assocbench/Room-v0", frames=10, difficulty="medium")
    rng = np.random.default_rng(0)
    obs, info = env.reset(seed=0)
    total, done = 0.0, False
    while not done:
        obs, reward, done, _, info = env.step(random_action(obs, rng))
        total += reward
    print(f"random agent: return {total:.0f} over {info['scored_frame'] + 1} frames")
    env.close()


if __name__ == "__main__":
    main()
