"""The config's one resolver (``harness.config``): an unknown key's hint names the right key."""

from __future__ import annotations

import pytest

from assocbench.errors import UserError
from assocbench.harness.config import load_run_config


@pytest.mark.parametrize("item,hint", [
    ("limits.time_limit_s=1", "did you mean 'time_limit_s'?"),         # a top-level key put in a section
    ("max_iterations=3", "did you mean 'icp.max_iterations'?"),         # a section's key given at the top
    ("limits.frame=10", "did you mean 'limits.frames'?"),               # a typo at its own level
    ("belief.sigma_rot=2", "did you mean 'belief.sigma_rotation'?"),
])
def test_an_unknown_key_suggests_the_key_of_that_name_wherever_it_lives(item, hint):
    with pytest.raises(UserError, match="unknown key") as caught:
        load_run_config(sets=[item])
    assert hint in str(caught.value) and "\n" not in str(caught.value)
