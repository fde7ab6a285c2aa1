"""A random agent on the Gymnasium environment: each step it draws a valid random association
from ``info["action_mask"]`` (every candidate takes -1 or a feature no other candidate took).
Run: python examples/random_agent.py

``env.action_space.sample()`` alone is refused (it pairs the padded candidate slots), and
``env.action_space.sample(mask=sample_mask(info["action_mask"]))`` respects the padding and the
index range but may give one feature to two candidates; ``sample_valid_action`` never does.
"""

import gymnasium as gym
import numpy as np

import assocbench.gymenv  # noqa: F401  (registers assocbench/Room-v0 and friends)
from assocbench.gymenv import sample_valid_action


def main() -> None:
    env = gym.make("assocbench/Room-v0", frames=10, difficulty="medium")
    rng = np.random.default_rng(0)
    obs, info = env.reset(seed=0)
    total, invalid, done = 0.0, 0, False
    while not done:
        obs, reward, done, _, info = env.step(sample_valid_action(info["action_mask"], rng))
        total += reward
        invalid += "invalid_action" in info
    print(f"random agent: return {total:.0f} over {info['scored_frame'] + 1} frames, {invalid} invalid actions")
    env.close()


if __name__ == "__main__":
    main()
