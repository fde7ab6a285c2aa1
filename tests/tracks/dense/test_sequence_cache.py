"""The dense sequence's cache entry (``tracks/dense/sequence.py``): stored uncompressed, its frames
memory-mapped when read and checked by their CRC-32, so a damaged entry (truncated, a flipped byte
in the frames, garbage, another key's) is discarded with one line and rendered again, never used."""

from __future__ import annotations

import numpy as np
import pytest

from assocbench.tracks.dense.sequence import DenseSequenceSpec, load_dense_sequence

SMALL = DenseSequenceSpec(scene="crates", frames=3, width=64, height=48, seed=0)
OTHER = DenseSequenceSpec(scene="crates", frames=4, width=64, height=48, seed=0)


def _entry(cache, spec):
    return cache / "dense" / f"{spec.key()}.npz"


@pytest.fixture(scope="module")
def good_cache(tmp_path_factory):
    cache = tmp_path_factory.mktemp("densecache")
    load_dense_sequence(OTHER, cache)
    return cache, load_dense_sequence(SMALL, cache)


def _flip(data: bytes, at: float) -> bytes:
    b = bytearray(data)
    b[int(len(b) * at)] ^= 0x01   # one bit: a depth a hair off, which only a checksum sees
    return bytes(b)


DAMAGE = {
    "truncated at half": lambda d, other: d[: len(d) // 2],
    "truncated by one byte": lambda d, other: d[:-1],
    "zero bytes": lambda d, other: b"",
    "one bit flipped at 20% (the depths)": lambda d, other: _flip(d, 0.2),
    "one bit flipped at 70% (the segmentation)": lambda d, other: _flip(d, 0.7),
    "garbage": lambda d, other: bytes(np.random.default_rng(0).integers(0, 256, 4000, dtype=np.uint8)),
    "a valid entry of another key": lambda d, other: other,
}


def test_an_entry_is_read_as_maps_of_the_stored_frames(good_cache):
    cache, rendered = good_cache
    seq = load_dense_sequence(SMALL, cache)
    assert seq.from_cache and isinstance(seq.depths, np.memmap) and not seq.depths.flags.writeable
    np.testing.assert_array_equal(seq.depths, rendered.depths)
    np.testing.assert_array_equal(seq.geoms, rendered.geoms)
    a, b = seq.frame(2), rendered.frame(2)
    np.testing.assert_array_equal(a.depth, b.depth)
    np.testing.assert_array_equal(a.normals, b.normals)


@pytest.mark.parametrize("damage", list(DAMAGE))
def test_a_damaged_entry_is_rendered_again_with_one_line(damage, good_cache, tmp_path, capsys):
    cache, rendered = good_cache
    (tmp_path / "dense").mkdir()
    for spec in (SMALL, OTHER):
        _entry(tmp_path, spec).write_bytes(_entry(cache, spec).read_bytes())
    path = _entry(tmp_path, SMALL)
    path.write_bytes(DAMAGE[damage](path.read_bytes(), _entry(tmp_path, OTHER).read_bytes()))
    seq = load_dense_sequence(SMALL, tmp_path)
    assert not seq.from_cache and len(seq) == SMALL.frames
    np.testing.assert_array_equal(seq.depths, rendered.depths)
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "unusable" in lines[0] and "rendering again" in lines[0], lines
    assert load_dense_sequence(SMALL, tmp_path).from_cache   # the new entry is sound and used


def test_an_unreadable_entry_is_one_line_naming_the_entry_and_the_setting(good_cache, monkeypatch):
    """An entry made unreadable (chmod 000) leaves its folder readable: the error names the entry
    itself, not only the cache folder, and ASSOCBENCH_CACHE. (np.load raises what open() raises for
    such a file, since a test run as root reads it anyway.)"""
    import errno

    from assocbench.errors import UserError

    cache, _ = good_cache
    entry = _entry(cache, SMALL)

    def denied(file, *args, **kwargs):
        raise PermissionError(errno.EACCES, "Permission denied", str(file))

    monkeypatch.setattr(np, "load", denied)
    with pytest.raises(UserError) as err:
        load_dense_sequence(SMALL, cache)
    message = str(err.value)
    assert "\n" not in message and str(entry) in message and "Permission denied" in message
    assert "ASSOCBENCH_CACHE" in message and entry.is_file()   # nothing deleted


def test_a_factor_that_does_not_divide_the_image_keeps_the_intrinsics_size(tmp_path):
    """``depth.downsample 3`` on 64x48 keeps 21x16 pixels, as its intrinsics (W//s, H//s) say: the
    stride alone kept 22 columns, every run failed in its worker with a shape error, and the entry
    stored was discarded as damaged by the next run."""
    from assocbench.tracks.dense.settings import DepthConfig

    spec = DenseSequenceSpec(scene="crates", frames=2, width=64, height=48, seed=0, depth=DepthConfig(downsample=3))
    seq = load_dense_sequence(spec, tmp_path)
    assert (seq.K.width, seq.K.height) == (21, 16) and seq.depths.shape == (2, 16, 21)
    assert seq.frame(1).depth.shape == (16, 21)
    assert load_dense_sequence(spec, tmp_path).from_cache   # stored sound, read back


def test_a_damaged_entry_that_cannot_be_removed_is_one_line_before_rendering(good_cache, tmp_path, monkeypatch,
                                                                            capsys):
    """A damaged entry in a read-only cache folder: one line naming the entry and ASSOCBENCH_CACHE,
    exit 2 at the CLI, before rendering (it printed "discarding it and rendering again", rendered,
    then failed to store: two lines and the render's time lost). As root a read-only folder is
    still writable, so unlink is made to refuse as it would."""
    import errno
    from pathlib import Path

    from assocbench.errors import UserError
    from assocbench.tracks.dense import sequence

    cache, _ = good_cache
    (tmp_path / "dense").mkdir()
    entry = _entry(tmp_path, SMALL)
    entry.write_bytes(_entry(cache, SMALL).read_bytes()[:-1])   # truncated by one byte

    def refused(self, missing_ok=False):
        raise PermissionError(errno.EACCES, "Permission denied", str(self))

    monkeypatch.setattr(Path, "unlink", refused)
    monkeypatch.setattr(sequence, "render_dense", lambda *a: pytest.fail("rendered before the error"))
    with pytest.raises(UserError) as err:
        load_dense_sequence(SMALL, tmp_path)
    message = str(err.value)
    assert "\n" not in message and str(entry) in message and "cannot be removed" in message
    assert "ASSOCBENCH_CACHE" in message and capsys.readouterr().err == ""
