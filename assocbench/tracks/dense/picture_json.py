"""The map's picture as JSON text, written by a compiled pass instead of ``json.dumps``.

A dense run's last record carries 10 000 map points (x, y, z in m, error in mm) rounded to 4
decimals. ``fixed_json`` writes ``rint(x · 10⁴)`` with the decimal point put back: the text differs
(``1.2300``), the numbers do not, since ``rint(x · 10⁴) / 10⁴`` is exactly ``np.round(x, 4)`` and
``json.loads`` reads that quotient. Non-finite numbers as ``json.dumps`` writes them.
"""

from __future__ import annotations

import json

import numpy as np
from numba import njit

DECIMALS = 4
_LIMIT = 1e14   # |x| · 10⁴ below 2⁵³ ≈ 9e15: the integer is exact; beyond it json.dumps writes the array


@njit(cache=True)
def _put(buf, k, text):
    for c in text:
        buf[k] = ord(c)
        k += 1
    return k


@njit(cache=True)
def _write(a, scale, decimals, buf):
    """``a`` (rows, cols) as a JSON list of lists into ``buf`` (bytes); returns the length."""
    k = _put(buf, 0, "[")
    digits = np.empty(20, np.uint8)
    for r in range(a.shape[0]):
        k = _put(buf, k, "[" if r == 0 else ", [")
        for c in range(a.shape[1]):
            if c:
                k = _put(buf, k, ", ")
            x = a[r, c]
            if x != x:
                k = _put(buf, k, "NaN")
                continue
            if x == np.inf or x == -np.inf:
                k = _put(buf, k, "Infinity" if x > 0 else "-Infinity")
                continue
            m = np.rint(x * scale)
            if m < 0 or (m == 0 and np.copysign(1.0, m) < 0):   # -0.0 keeps its sign, as np.round's does
                k = _put(buf, k, "-")
                m = -m
            v = np.int64(m)
            nd = 0
            while v > 0 or nd <= decimals:   # at least one digit before the point
                digits[nd] = 48 + v % 10
                v //= 10
                nd += 1
            for d in range(nd - 1, -1, -1):
                if d == decimals - 1:
                    buf[k] = 46   # "."
                    k += 1
                buf[k] = digits[d]
                k += 1
        k = _put(buf, k, "]")
    return _put(buf, k, "]")


def fixed_json(a: np.ndarray, decimals: int = DECIMALS) -> str:
    """JSON of the 2-D array ``a`` rounded to ``decimals``: once read, ``np.round(a, decimals)`` (as
    float64)."""
    shape = np.shape(a)   # before ascontiguousarray, which makes a 0-d array 1-d
    if len(shape) != 2:
        raise ValueError(f"fixed_json: a 2-D array is needed, got shape {shape}")
    a = np.ascontiguousarray(a, dtype=np.float64)
    finite = a[np.isfinite(a)]
    if finite.size and np.abs(finite).max() * 10.0 ** decimals >= _LIMIT:
        return json.dumps(np.round(a, decimals).tolist())
    buf = np.empty(2 + a.shape[0] * (4 + a.shape[1] * 24), np.uint8)
    return buf[:_write(a, 10.0 ** decimals, decimals, buf)].tobytes().decode("ascii")
