"""Shared fixtures: a private sequence cache and a short rendered room sequence."""

from __future__ import annotations

import os

import numpy as np
import pytest

# a benchmark script a test runs never writes benchmarks/records/ (tests/docs/test_benchmark_records.py
# turns records on for its own runs, into a temporary folder)
os.environ["ASSOCBENCH_NO_RECORD"] = "1"


@pytest.fixture(scope="session", autouse=True)
def private_cache(tmp_path_factory):
    """Every test renders into its own cache, never the user's ~/.cache."""
    path = tmp_path_factory.mktemp("cache")
    old = os.environ.get("ASSOCBENCH_CACHE")
    os.environ["ASSOCBENCH_CACHE"] = str(path)
    yield path
    if old is None:
        os.environ.pop("ASSOCBENCH_CACHE", None)
    else:
        os.environ["ASSOCBENCH_CACHE"] = old


@pytest.fixture(scope="session")
def room_sequence(private_cache):
    from assocbench.tracks.camera.sequence import SequenceSpec, load_sequence

    return load_sequence(SequenceSpec(scene="room", frames=24))


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
