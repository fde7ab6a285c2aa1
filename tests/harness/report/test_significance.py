"""The Friedman / Nemenyi test against the worked example of Demšar (JMLR 7, 2006, section 3.2.2 and
table 6), and against scipy's Friedman statistic where no block has ties."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from assocbench.harness.report.significance import block_ranks, friedman_nemenyi

METHODS = ("C4.5", "C4.5+m", "C4.5+cf", "C4.5+m+cf")
# table 6: the ranks (in brackets in the paper) of the four methods' AUC on 14 data sets; the AUCs are
# printed to 3 decimals, and on "voting" the ranks (2, 3) come from the unrounded values (0.975, 0.975)
TABLE_6 = np.array([
    [4, 3, 2, 1], [1, 2, 3, 4], [4, 1, 2, 3], [4, 1, 3, 2], [4, 2, 3, 1], [1, 2.5, 4, 2.5], [3, 2, 4, 1],
    [2.5, 2.5, 4, 1], [4, 3, 2, 1], [2.5, 2.5, 2.5, 2.5], [4, 2.5, 1, 2.5], [3, 2, 4, 1], [4, 1, 2, 3], [3, 1, 4, 2]])


def test_demsar_worked_example():
    test = friedman_nemenyi(TABLE_6, METHODS)
    # the paper: mean ranks 3.143, 2.000, 2.893, 1.964; chi2_F = 9.28; F_F = 3.69 (F(3, 39) critical 2.85)
    assert np.allclose(test.mean_rank, [3.143, 2.000, 2.893, 1.964], atol=5e-4)
    assert test.chi2 == pytest.approx(9.28, abs=5e-3) and test.f == pytest.approx(3.69, abs=5e-3)
    assert test.rejects and test.p < 0.05 and stats.f.ppf(0.95, 3, 39) == pytest.approx(2.85, abs=5e-3)
    # Nemenyi at 0.05: q = 2.569, CD = 1.25; "the post-hoc test is not powerful enough to detect any
    # significant differences": C4.5+m+cf is 1.179 better than C4.5, under CD; everyone shares 1st place
    assert test.cd == pytest.approx(1.25, abs=5e-3)
    assert list(test.places()) == [1, 1, 1, 1] and test.cliques() == [(3, 1, 2, 0)]
    # at 0.10: CD = 1.12, and C4.5+m and C4.5+m+cf are better than C4.5; C4.5+cf cannot be placed
    loose = friedman_nemenyi(TABLE_6, METHODS, alpha=0.10)
    assert loose.cd == pytest.approx(1.12, abs=5e-3)
    assert loose.differ(0, 1) and loose.differ(0, 3) and not loose.differ(0, 2) and not loose.differ(2, 3)
    assert list(loose.places()) == [3, 1, 1, 1]
    assert loose.cliques() == [(3, 1, 2), (2, 0)]   # the diagram's two bars, C4.5+cf under both


def test_ranks_of_values_put_ties_together_and_missing_values_last():
    values = np.array([[0.1, 0.1, 0.3, np.nan, np.inf], [0.5, 0.2, np.nan, 0.1, 0.4]])
    assert block_ranks(values).tolist() == [[1.5, 1.5, 3, 4.5, 4.5], [4, 2, 5, 1, 3]]


def test_without_ties_the_statistic_is_scipys():
    rng = np.random.default_rng(3)
    values = rng.normal(size=(20, 5)) + np.arange(5) * 0.3
    test = friedman_nemenyi(block_ranks(values), tuple("abcde"))
    assert test.chi2 == pytest.approx(stats.friedmanchisquare(*values.T).statistic, rel=1e-12)


def test_blocks_that_all_agree_reject_and_one_block_tests_nothing():
    agree = np.tile([1.0, 2.0, 3.0], (12, 1))   # CD 0.96 < 1: each place its own
    test = friedman_nemenyi(agree, ("a", "b", "c"))
    assert test.p == 0.0 and list(test.places()) == [1, 2, 3] and test.cliques() == []
    one = friedman_nemenyi(agree[:1], ("a", "b", "c"))
    assert np.isnan(one.p) and not one.rejects and list(one.places()) == [1, 1, 1]
