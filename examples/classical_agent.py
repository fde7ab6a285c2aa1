"""A classical associator driving a Gymnasium environment through ``info["problem"]``.
Run: python examples/classical_agent.py [method] [env id]   (default jcbb on assocbench/Room-v0;
assocbench/RoomLoop-v0 is the closed loop: its actions update the filter that predicts the next frame;
assocbench/ParkLoop-v0 and assocbench/Hallway-v0 are the planar and lines tracks' envs)"""

import sys

import gymnasium as gym

from assocbench.gymenv import classical_action, env_ids  # importing assocbench.gymenv registers the envs
from assocbench.tracks.capabilities import Pictures, has
from assocbench.tracks.registry import get_track


def main(method: str = "jcbb", env_id: str = "assocbench/Room-v0") -> None:
    rendered = has(get_track(env_ids()[env_id][0]), Pictures) if env_id in env_ids() else True
    env = gym.make(env_id, frames=10, difficulty="medium", render_mode="rgb_array" if rendered else None)
    obs, info = env.reset(seed=0)
    total = tp = fp = fn = 0
    done = False
    while not done:
        obs, reward, done, _, info = env.step(classical_action(info, env.action_space.shape[0], method))
        total += reward
        tp, fp, fn = (tp + info["step_metrics"]["tp"], fp + info["step_metrics"]["fp"], fn + info["step_metrics"]["fn"])
    drawn = f", last frame drawn {env.render().shape}" if rendered else ""   # a track without pictures draws none
    print(f"{method}: return {total:.0f}, precision {tp / max(tp + fp, 1):.3f}, recall {tp / max(tp + fn, 1):.3f}{drawn}")
    if "pos_err" in info:   # a closed-loop env: the filter's pose error after the last frame
        print(f"final pose error {info['pos_err']:.3f} m, {info['rot_err_deg']:.2f} deg, NEES {info['nees']:.1f}")
    env.close()


if __name__ == "__main__":
    main(*sys.argv[1:3])
