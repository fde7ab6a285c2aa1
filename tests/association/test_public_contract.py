"""The public contract is light: an associator author imports ``Problem`` and the associators
without the simulator (MuJoCo), OpenCV, Gymnasium or the harness."""

import subprocess
import sys

HEAVY = ("mujoco", "cv2", "gymnasium", "assocbench.harness", "assocbench.sim", "assocbench.tracks",
         "assocbench.gymenv")


def test_problem_and_make_associator_load_no_simulator_opencv_gymnasium_or_harness():
    out = subprocess.run([sys.executable, "-X", "importtime", "-c", "from assocbench import Problem, make_associator"],
                         capture_output=True, text=True, check=True)
    loaded = {line.split("|")[-1].strip() for line in out.stderr.splitlines() if line.startswith("import time:")}
    assert "assocbench.associators.registry" in loaded   # the measurement reads what was imported
    heavy = sorted(m for m in loaded if any(m == h or m.startswith(h + ".") for h in HEAVY))
    assert heavy == []


def test_importing_gymenv_registers_the_environments():
    code = ("import gymnasium as gym; import assocbench.gymenv; "
            "print('assocbench/Room-v0' in gym.registry, 'assocbench/RoomLoop-v0' in gym.registry)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["True", "True"]
