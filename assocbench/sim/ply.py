"""A point map as a binary PLY file (MeshLab, CloudCompare and Open3D read it)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def write_ply(path: Path | str, positions: np.ndarray, normals: np.ndarray, scalars: dict[str, np.ndarray]) -> None:
    """Little-endian binary PLY: ``x y z nx ny nz`` and one float property per ``scalars`` entry."""
    names = ["x", "y", "z", "nx", "ny", "nz", *scalars]
    table = np.empty(len(positions), dtype=[(n, "<f4") for n in names])
    for i, axis in enumerate("xyz"):
        table[axis] = positions[:, i]
        table[f"n{axis}"] = normals[:, i]
    for name, values in scalars.items():
        table[name] = values
    header = "\n".join(["ply", "format binary_little_endian 1.0", f"element vertex {len(positions)}",
                        *[f"property float {n}" for n in names], "end_header"]) + "\n"
    with open(path, "wb") as fh:
        fh.write(header.encode("ascii"))
        fh.write(table.tobytes())


def read_ply(path: Path | str) -> dict[str, np.ndarray]:
    """The float properties of a PLY written by ``write_ply`` (for tests and users' scripts)."""
    raw = Path(path).read_bytes()
    end = raw.index(b"end_header\n") + len(b"end_header\n")
    lines = raw[:end].decode("ascii").splitlines()
    count = int(next(l for l in lines if l.startswith("element vertex")).split()[-1])
    names = [l.split()[-1] for l in lines if l.startswith("property float")]
    table = np.frombuffer(raw[end:], dtype=[(n, "<f4") for n in names], count=count)
    return {n: table[n].astype(np.float64) for n in names}
