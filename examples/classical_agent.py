"""A classical associator driving the Gymnasium environment through ``info["problem"]``.
Run: python examples/classical_agent.py [method]   (default jcbb)"""

import sys

import gymnasium as gym

import assocbench  # noqa: F401  (registers the environments)
from assocbench.gymenv import classical_action


def main(method: str = "jcbb") -> None:
    env = gym.make("assocbench/Room-v0", frames=10, difficulty="medium", render_mode="rgb_array")
    obs, info = env.reset(seed=0)
    total = tp = fp = fn = 0
    done = False
    while not done:
        obs, reward, done, _, info = env.step(classical_action(info, env.action_space.shape[0], method))
        total += reward
        tp, fp, fn = (tp + info["step_metrics"]["tp"], fp + info["step_metrics"]["fp"], fn + info["step_metrics"]["fn"])
    frame = env.render()
    print(f"{method}: return {total:.0f}, precision {tp / max(tp + fp, 1):.3f}, recall {tp / max(tp + fn, 1):.3f}, "
          f"last frame drawn {frame.shape}")
    env.close()


if __name__ == "__main__":
    main(*sys.argv[1:2])
