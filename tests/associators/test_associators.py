"""One test body over every registered associator (plugins included), plus method-specific checks."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from plugins import install_entry_point
from problems import for_method, random_problem, reference_joint, reference_surprisal

from assocbench import Problem, make_associator, validate_association
from assocbench.associators.dense import is_dense
from assocbench.associators.registry import available
from assocbench.models.synthetic import lattice_problem, range_bearing_problem

METHODS = sorted(m for m in available() if not is_dense(m))   # the dense ones: tests/tracks/dense


def easy_problem(n: int = 6) -> tuple[Problem, np.ndarray]:
    zhat = np.column_stack([np.arange(n) * 40.0, np.zeros(n)])
    truth = np.roll(np.arange(n), 2)
    z = np.empty((n, 2))
    z[truth] = zhat + 0.3
    P = 4.0 * np.eye(2 * n)
    return Problem(z, np.repeat(np.eye(2)[None], n, 0), zhat, P, volume=1e5), truth


@pytest.mark.parametrize("method", METHODS)
def test_output_is_valid_on_random_problems(method, rng):
    assoc = make_associator(method)
    for _ in range(10):
        p = for_method(method, random_problem(rng, n=int(rng.integers(1, 7)), m=int(rng.integers(1, 8))))
        validate_association(assoc.associate(p), p)


@pytest.mark.parametrize("method", METHODS)
def test_perfect_on_an_easy_problem(method):
    p, truth = easy_problem()
    assert make_associator(method).associate(for_method(method, p, truth)).tolist() == truth.tolist()


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("m,n", [(0, 3), (3, 0), (0, 0)])
def test_empty_inputs_give_all_unassociated(method, m, n):
    p = Problem(np.zeros((m, 2)), np.repeat(np.eye(2)[None], m, 0), np.zeros((n, 2)), np.eye(2 * n))
    out = make_associator(method).associate(for_method(method, p))
    assert out.shape == (n,) and np.all(out == -1)


@pytest.mark.parametrize("method", ["mnn", "jcbb"])
def test_line_features_wrap_at_plus_minus_pi(method):
    """Lines (α, r): predictions just below +π, measurements just above -π."""
    alphas = np.array([np.pi - 0.02, np.pi - 0.3, -np.pi + 0.5])
    zhat = np.column_stack([alphas, [2.0, 3.5, 5.0]])
    z = zhat[[2, 0, 1]].copy()
    z[1, 0] = -np.pi + 0.01   # the same line as landmark 0, measured across the cut
    z[:, 1] += 0.02
    P = np.kron(np.eye(3), np.diag([0.02**2, 0.05**2]))
    p = Problem(z, np.repeat(np.diag([0.01**2, 0.02**2])[None], 3, 0), zhat, P, volume=2 * np.pi * 10, angular=(0,))
    assert make_associator(method).associate(p).tolist() == [1, 2, 0]


def test_lsa_all_gated_returns_unassociated():
    p = Problem(np.array([[1e4, 1e4]]), np.eye(2)[None], np.zeros((2, 2)), np.eye(4))
    assert make_associator("lsa").associate(p).tolist() == [-1, -1]


def test_jcbb_node_budget_sets_timed_out():
    p, _ = lattice_problem(np.random.default_rng(3), n=25, sigma_common=40.0, n_clutter=10)
    jcbb = make_associator("jcbb", max_nodes=5)
    validate_association(jcbb.associate(p), p)
    assert jcbb.info["timed_out"] is True


def reference_snn(problem: Problem, confidence: float = 0.99) -> np.ndarray:
    """SNN the plain way: at each step evaluate the surprisal of every extended hypothesis with
    explicit inverses (tests/problems.py) and keep the lowest that stays jointly compatible."""
    from scipy.stats import chi2

    out = np.full(problem.n, -1)
    current = reference_surprisal(problem, out)
    while True:
        best = (current, None)
        for i in sorted(set(range(problem.m)) - set(out[out >= 0].tolist())):
            for j in np.flatnonzero(out < 0):
                single = np.full(problem.n, -1)
                single[j] = i
                if reference_joint(problem, single)[0] > chi2.ppf(confidence, problem.d):
                    continue
                trial = out.copy()
                trial[j] = i
                k = int(np.sum(trial >= 0))
                if reference_joint(problem, trial)[0] > chi2.ppf(confidence, problem.d * k):
                    continue
                s = reference_surprisal(problem, trial)
                if s < best[0]:
                    best = (s, (i, j))
        if best[1] is None:
            return out
        current, (i, j) = best
        out[j] = i


def test_snn_equals_the_plain_surprisal_descent():
    for seed in range(25):
        rng = np.random.default_rng(seed)
        p = random_problem(rng, n=int(rng.integers(2, 8)), m=int(rng.integers(1, 9)), angular=(1,) if seed % 3 == 0 else ())
        assert make_associator("snn").associate(p).tolist() == reference_snn(p).tolist(), seed


def precision(method: str, problems) -> float:
    tp = fp = 0
    for p, truth in problems:
        out = make_associator(method).associate(p)
        tp += np.sum((out >= 0) & (out == truth))
        fp += np.sum((out >= 0) & (out != truth))
    return tp / max(tp + fp, 1)


def test_on_a_hard_problem_jcbb_beats_mnn_beats_enn():
    """EKF-SLAM-like range-bearing: pose σ 1 m and 8°, landmarks correlated with the pose,
    20 % clutter, 80 % detection. Euclidean distance mixes metres and radians; MNN uses the
    covariance; JCBB also uses the correlations."""
    problems = [range_bearing_problem(np.random.default_rng(s), n=20, sigma_pose=(1.0, np.deg2rad(8.0)), extent=10.0)
                for s in range(12)]
    scores = {m: precision(m, problems) for m in ("enn", "mnn", "jcbb")}
    assert scores["jcbb"] > scores["mnn"] + 0.05 > scores["enn"] + 0.1, scores


def test_on_a_lattice_with_common_mode_error_only_jcbb_holds_up():
    """Lattice 30 px apart shifted by a common error of σ 20 px: individually every
    neighbour looks right; jointly only the true shift does."""
    problems = [lattice_problem(np.random.default_rng(s), n=20, spacing=30.0, sigma_common=20.0,
                                n_clutter=6, p_detect=0.85) for s in range(15)]
    scores = {m: precision(m, problems) for m in ("enn", "mnn", "jcbb")}
    assert scores["jcbb"] >= 0.9 and max(scores["mnn"], scores["enn"]) <= 0.5, scores


def test_unknown_method_and_parameter_give_clear_errors():
    from assocbench import UserError

    with pytest.raises(UserError, match="did you mean jcbb"):
        make_associator("jcbbb")
    with pytest.raises(UserError, match="accepted are confidence, max_nodes, prefix_test"):
        make_associator("jcbb", confidance=0.9)


def test_plugin_by_module_class_spec(tmp_path, monkeypatch):
    (tmp_path / "my_assoc.py").write_text(
        "import numpy as np\nfrom assocbench import Associator\n"
        "class Nothing(Associator):\n    def associate(self, problem):\n        return np.full(problem.n, -1)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    p, _ = easy_problem()
    assert np.all(make_associator("my_assoc:Nothing").associate(p) == -1)


def test_plugin_by_entry_point(tmp_path, monkeypatch):
    """A package that declares the entry point group is listed and usable by name."""
    install_entry_point(tmp_path, monkeypatch, "fancy_assoc",
                        "import numpy as np\nfrom assocbench import Associator\n"
                        "class Fancy(Associator):\n    def associate(self, problem):\n        return np.full(problem.n, -1)\n",
                        "fancy", "Fancy")
    assert "fancy" in available()
    p, _ = easy_problem()
    assert np.all(make_associator("fancy").associate(p) == -1)


def test_readme_python_example_runs_and_prints_what_it_says(capsys):
    import re
    from pathlib import Path

    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    block = next(b for b in re.findall(r"```python\n(.*?)```", readme, re.S) if "make_associator(\"jcbb\")" in b)
    exec(compile(block, "README.md", "exec"), {})
    assert capsys.readouterr().out.strip() == "[2 0]"


WARM_CHECK = """
import json
import os
import sys
import numpy as np
from numba.core.registry import CPUDispatcher
from assocbench import make_associator
from assocbench.models.synthetic import range_bearing_problem
from assocbench.tracks.camera.synthetic import camera_problem
from assocbench.harness.runner import private_copy, warm_up

sys.path.insert(0, sys.argv[1])
from problems import for_method

def signatures():
    return {f"{name}.{attr}": len(obj.signatures) for name, mod in list(sys.modules.items())
            if name.startswith("assocbench") for attr, obj in list(vars(mod).items()) if isinstance(obj, CPUDispatcher)}

def new_after_warm_up(method):
    associator = make_associator(method)
    warm_up(associator)
    before = signatures()
    makers = [range_bearing_problem, range_bearing_problem, camera_problem]   # learned: its planar and camera models
    for seed, make in enumerate(makers):
        problem, truth = make(np.random.default_rng(seed), n=60 + 40 * seed)
        associator.associate(private_copy(for_method(method, problem, truth)))
    return sorted(k for k, v in signatures().items() if v > before.get(k, 0))

found = {}
for method in sys.argv[2:]:   # a child per method, forked before any kernel of any method loaded
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(read)
        try:
            result = new_after_warm_up(method)
        except BaseException as exc:
            result = f"{type(exc).__name__}: {exc}"
        os.write(write, json.dumps(result).encode())
        os._exit(0)
    os.close(write)
    with os.fdopen(read, "rb") as pipe:
        data = pipe.read()
    os.waitpid(pid, 0)
    found[method] = json.loads(data) if data else "the child died"
print(json.dumps(found))
"""


@pytest.mark.skipif(not hasattr(os, "fork"), reason="forks a child per method")
def test_warm_up_loads_every_kernel_a_frame_uses():
    """After the harness's warm-up on a tiny problem, real problems (n = 60-140, budgets spent,
    large clusters) need no kernel it did not load: a cold cache's compile is never timed as a
    frame's runtime. Each method in its own child, forked from an interpreter that has imported
    the package and loaded no method's kernels, so no other method's kernels hide a gap (one
    interpreter's start for all methods, not one each)."""
    import subprocess
    import sys

    tests = str(Path(__file__).parents[1])   # where problems.py is
    out = subprocess.run([sys.executable, "-c", WARM_CHECK, tests, *METHODS], capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert json.loads(out.stdout.strip().splitlines()[-1]) == {method: [] for method in METHODS}, out.stdout


def test_sparse_greedy_equals_the_dense_rounds(rng):
    """``greedy_pairs`` (sort the allowed pairs, take each whose feature and landmark are free)
    against ``greedy_one_to_one`` (mutual-best rounds on the dense matrix), distinct costs."""
    from assocbench.associators.base import greedy_one_to_one, greedy_pairs

    for _ in range(300):
        m, n = int(rng.integers(1, 12)), int(rng.integers(1, 12))
        cost = rng.uniform(0, 10, (m, n))
        allowed = rng.uniform(size=(m, n)) < rng.uniform(0.05, 1.0)
        lms, feats = np.nonzero(allowed.T)               # by landmark, then feature
        assert np.array_equal(greedy_pairs(feats, lms, cost[feats, lms], m, n), greedy_one_to_one(cost, allowed))
