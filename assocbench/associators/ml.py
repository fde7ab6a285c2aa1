"""ML: maximum likelihood per landmark with the new/spurious likelihood α (Prob. Rob. p. 322)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..association.compatibility import pairwise_log_likelihood
from ..association.problem import Problem
from .base import Associator, greedy_one_to_one


@dataclass
class ML(Associator):
    """Pair by largest likelihood ``N(z_i; zhat_j, P_jj + R_i)`` (log-det term included); a pair
    is accepted only if it beats the likelihood α of the feature being new or spurious.

    log_alpha: ``log α``; ``None`` uses the uniform density ``α = 1/|Y|`` over the domain.
    """

    name = "ml"
    summary = "maximum likelihood with new/spurious likelihood alpha, greedy one-to-one"
    log_alpha: float | None = None

    def associate(self, problem: Problem) -> np.ndarray:
        if problem.m == 0 or problem.n == 0:
            return self.empty(problem)
        loglik = pairwise_log_likelihood(problem)
        log_alpha = -np.log(problem.volume) if self.log_alpha is None else self.log_alpha
        return greedy_one_to_one(-loglik, loglik > log_alpha)
