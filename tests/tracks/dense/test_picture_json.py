"""The map picture's JSON text: the numbers ``json.dumps(np.round(a, 4).tolist())`` gives, once read."""

from __future__ import annotations

import json

import numpy as np
import pytest

from assocbench.tracks.dense.picture_json import fixed_json


def read(text: str) -> np.ndarray:
    return np.array(json.loads(text), dtype=np.float64).reshape(-1, 4)


def test_the_numbers_are_json_dumps_of_the_rounded_array_bit_for_bit():
    rng = np.random.default_rng(3)
    a = np.column_stack([rng.normal(0, 3, (5000, 3)), rng.exponential(4, 5000)])
    a[::9] = np.round(a[::9], 2)                       # short decimals: json.dumps drops the zeros
    a[1] = [-0.00004, 0.00005, -0.000049999, 0.0]     # round to -0.0, 0.0001 (half to even: 0.0), -0.0, 0.0
    a[2] = [np.nan, np.inf, -np.inf, -12.34565]
    a[3] = [1e6 + 0.12345, -987.65435, 5e-5, -5e-5]
    ref, ours = read(json.dumps(np.round(a, 4).tolist())), read(fixed_json(a))
    assert np.array_equal(ours, ref, equal_nan=True)
    assert np.array_equal(np.signbit(ours), np.signbit(ref))   # -0.0 stays -0.0
    assert fixed_json(a[1:2]).startswith("[[-0.0000, ")


def test_empty_huge_and_bad_input():
    assert fixed_json(np.zeros((0, 4))) == "[]"
    huge = np.array([[1e15, 1.0, 2.0, 3.0]])          # past the exact integers: json.dumps writes it
    assert fixed_json(huge) == json.dumps(np.round(huge, 4).tolist())
    with pytest.raises(ValueError, match="2-D"):
        fixed_json(np.zeros(4))
    with pytest.raises(ValueError, match=r"got shape \(\)"):   # a scalar is named as one, not as shape (1,)
        fixed_json(np.float64(1.0))


def test_other_dtypes_and_layouts_read_back_as_their_float64_rounding():
    rng = np.random.default_rng(5)
    wide = rng.normal(0, 50, (30, 8))
    for a in (wide[::3, ::2], np.asfortranarray(wide[:, :4]), wide[:, :4].astype(np.float32), np.arange(12).reshape(3, 4)):
        ref = read(json.dumps(np.round(np.asarray(a, np.float64), 4).tolist()))
        assert np.array_equal(read(fixed_json(a)), ref)
