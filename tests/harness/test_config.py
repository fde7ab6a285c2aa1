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


def alias_bomb(levels: int) -> str:
    """A YAML list whose ``levels`` lines of nested aliases expand to 10**levels values."""
    lines = ["&a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"&a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]" for i in range(1, levels)]
    return "".join(f"        - {line}\n" for line in lines)


def test_an_alias_bomb_in_a_suite_is_refused_in_one_short_line(tmp_path, capsys):
    """Reproduction: a suite whose method params hold nine lines of nested YAML aliases (10⁹
    values): the refusal of the value formatted all of it and died of MemoryError after 83 s at
    3 GB. Six lines (10⁶ values) made a message of megabytes. The loader refuses the expansion."""
    from assocbench.cli.main import main

    suite = tmp_path / "bomb.yaml"
    suite.write_text("base: {frames: 2}\nscenes: [park]\nseeds: [0]\nmethods:\n  - name: m\n    method: mnn\n"
                     f"    params:\n      confidence:\n{alias_bomb(6)}")
    code = main(["leaderboard", "--suite", str(suite), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert len(err) < 300, err[:300]
    assert_one_line_error_text(code, err, str(suite), "aliases expand to more than 100000 values")


def assert_one_line_error_text(code: int, err: str, *needles: str) -> None:
    assert code == 2 and err.count("\n") == 1 and err.startswith("assocbench: error:"), err[:300]
    for needle in needles:
        assert needle in err, err[:300]


def test_anchors_that_expand_a_little_are_read(tmp_path):
    """Aliases as people use them (a shared mapping of settings) still load."""
    from assocbench.harness.config import read_yaml

    path = tmp_path / "cfg.yaml"
    path.write_text("a: &shared {sigma_position: 0.05, clutter: 3}\nb: *shared\n")
    assert read_yaml(path) == {"a": {"sigma_position": 0.05, "clutter": 3}, "b": {"sigma_position": 0.05, "clutter": 3}}


def test_a_waypoint_file_alias_bomb_is_refused(tmp_path):
    from assocbench.sim.waypoints import yaml_list

    with pytest.raises(UserError, match="aliases expand to more than 100000 values"):
        yaml_list(tmp_path / "w.yaml", "waypoints:\n" + alias_bomb(6).replace("        -", "  -"), "[x, y, z]")


def test_a_huge_value_is_quoted_short_in_a_message():
    """No message formats a whole value: a 10⁵-item list given as a number is quoted in 80 characters."""
    from assocbench.validation import check_number

    with pytest.raises(UserError) as exc:
        check_number(list(range(100_000)), "belief.clutter", integer=True)
    assert len(str(exc.value)) < 150 and "belief.clutter must be an integer, got [0, 1, 2, 3, 4, 5, ...]" in str(exc.value)
