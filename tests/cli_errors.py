"""The CLI's bad-input contract, checked the same way everywhere: exit 2, one line, no traceback."""

from __future__ import annotations


def assert_one_line_error(capsys, code: int, *needles: str) -> None:
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("assocbench: error:"), err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in err, err
