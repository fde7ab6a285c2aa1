"""The harness records what methods claim: JCBB's proven optimality, a soft associator's
probability mass on the truth (validated marginals), NaN for methods that claim nothing."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from assocbench.association.truth import FrameTruth
from assocbench.harness.runner import frame_records
from assocbench.models.synthetic import range_bearing_problem
from assocbench.scoring.aggregate import leaderboard_table, summarize


def frames(n: int = 12, count: int = 4):
    out = []
    for seed in range(count):
        problem, truth = range_bearing_problem(np.random.default_rng(seed), n=n)
        labels = np.full(problem.m, -1)
        labels[truth[truth >= 0]] = np.flatnonzero(truth >= 0)
        out.append((problem, FrameTruth(labels, truth, truth >= 0)))
    return out


def records(method: str, params: dict | None = None) -> pd.DataFrame:
    return pd.DataFrame(list(frame_records(frames(), method, params or {})))


def test_jcbb_frames_say_proven_optimal_and_others_say_nothing():
    jcbb, mnn = records("jcbb"), records("mnn")
    assert jcbb["proven_optimal"].tolist() == [1.0] * 4
    assert records("jcbb", {"max_nodes": 1})["proven_optimal"].tolist() == [0.0] * 4
    assert mnn["proven_optimal"].isna().all() and mnn["true_mass"].isna().all()
    assert summarize(jcbb)["proven_optimal"] == 1.0 and math.isnan(summarize(mnn)["proven_optimal"])


def test_jpda_frames_carry_the_mass_on_the_truth():
    jpda = records("jpda")
    assert (jpda["error"] == "").all()
    assert ((jpda["true_mass"] > 0.5) & (jpda["true_mass"] <= 1.0)).all()
    summary = summarize(jpda)
    assert summary["true_mass"] == jpda["true_mass"].mean()
    table = leaderboard_table(pd.DataFrame([{**summary, "scenario": "s", "method": "jpda"}]))
    assert table.loc[0, "true_mass"] == summary["true_mass"] and math.isnan(table.loc[0, "proven_optimal"])


def test_a_soft_method_with_bad_marginals_fails_its_frames(tmp_path, monkeypatch):
    (tmp_path / "bad_soft.py").write_text(
        "import numpy as np\nfrom assocbench import Associator\n"
        "class WrongShape(Associator):\n    soft = True\n"
        "    def associate(self, problem):\n"
        "        self.info = {'marginals': np.ones((problem.n, problem.m))}\n"
        "        return np.full(problem.n, -1)\n"
        "class NotNormalised(WrongShape):\n"
        "    def associate(self, problem):\n"
        "        self.info = {'marginals': np.full((problem.n, problem.m + 1), 0.5)}\n"
        "        return np.full(problem.n, -1)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    shape = records("bad_soft:WrongShape")
    assert shape["error"].str.contains(r"info\['marginals'\] of shape").all()
    rows = records("bad_soft:NotNormalised")
    assert rows["error"].str.contains("must sum to 1").all() and rows["true_mass"].isna().all()


def test_a_truthy_soft_flag_is_soft_and_proven_must_be_a_bool(tmp_path, monkeypatch):
    (tmp_path / "odd_flags.py").write_text(
        "import numpy as np\nfrom assocbench import Associator\n"
        "class SoftOne(Associator):\n    soft = 1\n"
        "    def associate(self, problem):\n"
        "        self.info = {}\n"
        "        return np.full(problem.n, -1)\n"
        "class ProvenString(Associator):\n"
        "    def associate(self, problem):\n"
        "        self.info = {'proven_optimal': 'false'}\n"
        "        return np.full(problem.n, -1)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert records("odd_flags:SoftOne")["error"].str.contains("must set info\\['marginals'\\]").all()
    assert records("odd_flags:ProvenString")["error"].str.contains("must be True, False or absent").all()
