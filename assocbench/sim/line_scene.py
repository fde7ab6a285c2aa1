"""Load a lines scene (``office``, or an MJCF whose map walls are upright ``lw*`` boxes) and find
which map line each lidar beam truly hits.

A wall gives its four side faces. Face ``f`` with outward normal ``n`` (``±u`` or ``±v``) through
``p_f`` is the world line ``(α_w, r_w) = (atan2(n_y, n_x), n·p_f)``, flipped to ``(α_w + π, −r_w)``
when ``r_w < 0``. Faces on one infinite line (``|Δα| < 1e-6`` rad, ``|Δr| < 1e-4`` m) are one map
line with several segments: the (α, r) model cannot tell them apart. Faces shorter than
``MIN_FACE_LENGTH`` (a wall's end, a door jamb; no extractor keeps such a segment) join a line they
lie on, else their beams are −1 like clutter; geoms not named ``lw*`` are clutter.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco  # loaded under MUJOCO_GL by assocbench.sim (gl.py) before this module runs
import numpy as np

from ..errors import UserError
from ..models.range_bearing import wrap
from . import footprint
from .scan import Scan
from .scene import WALL_PREFIX, Scene, mjcf_error, resolve_scene_path

MIN_HALF_SIZE = 1e-3      # m: a wall thinner, shorter or lower than 2 mm is refused (faces need a length)
MIN_FACE_LENGTH = 0.2     # m: shorter faces are no map line of their own (the extractor's min_length is 0.3)
ALPHA_TOL = 1e-6          # rad: faces on one line ...
R_TOL = 1e-4              # m: ... are one map line
VERTICAL_TOL = 1e-6       # |R_z,k| ≥ 1 − this: box axis k is vertical


@dataclass
class Wall:
    """One ``lw*`` box seen from above: centre, horizontal unit axes ``u, v``, half sizes ``a, b``."""

    geom: int
    centre: np.ndarray   # (2,)
    axes: np.ndarray     # (2, 2) rows u, v
    half: np.ndarray     # (2,) a, b
    z_span: tuple[float, float] = (-np.inf, np.inf)   # bottom and top (m)

    def faces(self) -> list[tuple[np.ndarray, np.ndarray, float]]:
        """The four side faces ``(normal, centre, half length)`` in the order +u, −u, +v, −v."""
        out = []
        for k in (0, 1):
            for sign in (1.0, -1.0):
                n = sign * self.axes[k]
                out.append((n, self.centre + self.half[k] * n, float(self.half[1 - k])))
        return out

    def face_of(self, p: np.ndarray) -> np.ndarray:
        """Index (n,) of the face nearest each boundary point, in the box frame:
        ``q = (u·(p − c), v·(p − c))``, argmin of ``|q_u ∓ a|, |q_v ∓ b|``."""
        q = (p - self.centre) @ self.axes.T
        gaps = np.column_stack([np.abs(q[:, 0] - self.half[0]), np.abs(q[:, 0] + self.half[0]),
                                np.abs(q[:, 1] - self.half[1]), np.abs(q[:, 1] + self.half[1])])
        return np.argmin(gaps, axis=1)


@dataclass
class LineScene:
    """A compiled lines scene and its map: lines, their segments (the faces) and the walls."""

    name: str
    path: Path
    model: mujoco.MjModel
    data: mujoco.MjData
    lines: np.ndarray          # (K, 2) world (α_w, r_w), α_w in [−π, π), r_w ≥ 0
    segments: np.ndarray       # (S, 2, 2) world end points of each mapped face
    segment_line: np.ndarray   # (S,) index into lines
    segment_geom: np.ndarray   # (S,) geom id of the wall the face belongs to
    segment_normal: np.ndarray # (S, 2) each face's outward unit normal: it is seen from that side only
    walls: list[Wall]          # the lw* boxes, in geom order
    face_line: np.ndarray      # (W, 4) map line of each wall's faces (+u, −u, +v, −v), −1: too short

    digest = Scene.digest              # the MJCF text and its neighbouring files (only ``path`` is read)
    clearance = footprint.clearance    # distance (n,) from points (n, 2) to the nearest obstacle

    @property
    def anchors(self) -> np.ndarray:
        """(S, 2) the points the default ellipse is built around: the mapped faces' midpoints."""
        return self.segments.mean(axis=1)


def face_line(normal: np.ndarray, point: np.ndarray) -> np.ndarray:
    """World ``(α, r)`` of the line through ``point`` with unit ``normal``: ``r = n·p``, flipped
    when negative, α wrapped."""
    alpha, r = float(np.arctan2(normal[1], normal[0])), float(normal @ point)
    if r < 0:
        alpha, r = alpha + np.pi, -r
    return np.array([float(wrap(alpha)), r])


def same_line(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two ``(α, r)`` lines coincide within ``ALPHA_TOL``, ``R_TOL`` (near the origin
    ``(α + π, −r)`` is tried too)."""
    d = float(wrap(a[0] - b[0]))
    return (abs(d) < ALPHA_TOL and abs(a[1] - b[1]) < R_TOL) or \
        (abs(float(wrap(d - np.pi))) < ALPHA_TOL and a[1] + b[1] < R_TOL)


def _wall(model: mujoco.MjModel, data: mujoco.MjData, g: int, path: Path) -> Wall:
    """The ``lw*`` geom ``g`` as an upright box (one-line errors: not a box, tilted, degenerate)."""
    name = model.geom(g).name
    if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_BOX:
        kind = mujoco.mjtGeom(model.geom_type[g]).name.removeprefix("mjGEOM_").lower()
        raise UserError(f"MJCF {path}: map walls must be boxes, but {name} is a {kind} (make it type=\"box\" or "
                        f"rename it so it does not start with 'lw': it becomes clutter)")
    size = model.geom_size[g]
    if size.min() < MIN_HALF_SIZE:
        raise UserError(f"MJCF {path}: map wall {name} has a half-size of {size.min():g} m, below "
                        f"{MIN_HALF_SIZE * 1e3:g} mm: give it a length, thickness and height "
                        f"(size=\"half_length half_thickness half_height\") or remove it")
    rot = data.geom_xmat[g].reshape(3, 3)
    vertical = np.flatnonzero(np.abs(rot[2]) >= 1 - VERTICAL_TOL)
    if not len(vertical):
        raise UserError(f"MJCF {path}: map wall {name} is tilted (no box axis is vertical): rotate walls about "
                        f"z only (euler=\"0 0 yaw\") or rename it so it does not start with 'lw'")
    i, j = [k for k in range(3) if k != vertical[0]]
    axes = rot[:2, [i, j]].T
    z, dz = float(data.geom_xpos[g, 2]), float(size[vertical[0]])
    return Wall(g, data.geom_xpos[g, :2].copy(), axes / np.linalg.norm(axes, axis=1, keepdims=True),
                size[[i, j]].copy(), (z - dz, z + dz))


def build_map(walls: list[Wall]) -> tuple[np.ndarray, ...]:
    """Map lines from the walls' faces: long faces first (new unless on a line), short ones join a
    line or stay unmapped. Returns lines (K, 2), segments (S, 2, 2), segment_line (S,), segment_geom
    (S,), face_line (W, 4), segment_normal (S, 2)."""
    lines: list[np.ndarray] = []
    face_to_line = -np.ones((len(walls), 4), int)
    faces = [(w, f, *face) for w, wall in enumerate(walls) for f, face in enumerate(wall.faces())]
    for long_pass in (True, False):
        for w, f, n, p, half in faces:
            if (2 * half >= MIN_FACE_LENGTH) != long_pass:
                continue
            line = face_line(n, p)
            k = next((i for i, other in enumerate(lines) if same_line(line, other)), -1)
            if k < 0 and long_pass:
                lines.append(line)
                k = len(lines) - 1
            face_to_line[w, f] = k
    segs, seg_line, seg_geom, normals = [], [], [], []
    for w, f, n, p, half in faces:
        if face_to_line[w, f] >= 0:
            t = np.array([-n[1], n[0]]) * half
            segs.append([p - t, p + t])
            seg_line.append(face_to_line[w, f])
            seg_geom.append(walls[w].geom)
            normals.append(n)
    return (np.array(lines).reshape(-1, 2), np.array(segs).reshape(-1, 2, 2), np.array(seg_line, int),
            np.array(seg_geom, int), face_to_line, np.array(normals, float).reshape(-1, 2))


def load_line_scene(scene: str | Path) -> LineScene:
    """Compile a lines scene and build its map from the ``lw*`` box walls (one-line errors)."""
    path = resolve_scene_path(scene)
    try:
        model = mujoco.MjModel.from_xml_path(str(path))
    except (ValueError, RuntimeError) as exc:
        err = mjcf_error(path, exc)
        if "size" in str(err) and "must be positive" in str(err):
            err = UserError(f"{err} (a wall needs a positive half-size on every axis: "
                            f"size=\"half_length half_thickness half_height\")")
        raise err from None
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    ids = [g for g in range(model.ngeom) if model.geom(g).name.startswith(WALL_PREFIX)]
    if not ids:
        raise UserError(f"MJCF {path} has no map walls: add upright box geoms named lw0, lw1... (their vertical "
                        f"side faces become the map's lines)")
    walls = [_wall(model, data, g, path) for g in ids]
    lines, segments, segment_line, segment_geom, face_to_line, normals = build_map(walls)
    if not len(lines):
        raise UserError(f"MJCF {path}: no wall face is {MIN_FACE_LENGTH} m long or longer, so the map has no "
                        f"lines: make the lw* walls longer")
    return LineScene(path.stem, path, model, data, lines, segments, segment_line, segment_geom, normals, walls,
                     face_to_line)


def check_scan_plane(scene: LineScene, height: float) -> None:
    """One-line error when a map wall does not cross the scan plane at ``height`` (its faces could
    never be measured)."""
    for wall in scene.walls:
        lo, hi = wall.z_span
        if not lo <= height <= hi:
            name = scene.model.geom(wall.geom).name
            raise UserError(f"MJCF {scene.path}: map wall {name} spans z {lo:g}..{hi:g} m and does not cross the "
                            f"lidar's scan plane at z = {height:g} m (lidar.height): move or resize it, or rename it "
                            f"so it does not start with 'lw'")


def beam_lines(scene: LineScene, scan: Scan, pose: np.ndarray) -> np.ndarray:
    """(B,) the map line each beam truly hits, −1 for none: the true hit
    ``p_i = (x, y) + d_i (cos(θ + α_i), sin(θ + α_i))`` with the true distance ``d_i``, on the face
    of ``scan.geom[i]`` nearest it (``Wall.face_of``)."""
    labels = -np.ones(len(scan.angles), int)
    row = -np.ones(scene.model.ngeom + 1, int)           # geom id -> wall index; geom −1 -> last slot
    row[[w.geom for w in scene.walls]] = np.arange(len(scene.walls))
    wall_of = row[scan.geom]
    for w in np.unique(wall_of[wall_of >= 0]):
        beams = np.flatnonzero(wall_of == w)
        heading = pose[2] + scan.angles[beams]
        d = scan.distance[beams] if scan.distance is not None else _distance_to(scene, scene.walls[w], pose, heading)
        p = pose[:2] + d[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])
        labels[beams] = scene.face_line[w, scene.walls[w].face_of(p)]
    return labels


def _distance_to(scene: LineScene, wall: Wall, pose: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """True distances along horizontal rays from the pose to one wall alone, at mid-height."""
    g, m, d = wall.geom, scene.model, scene.data
    origin = np.array([pose[0], pose[1], d.geom_xpos[g, 2]])
    return np.array([mujoco.mju_rayGeom(d.geom_xpos[g], d.geom_xmat[g], m.geom_size[g], origin,
                                        np.array([np.cos(h), np.sin(h), 0.0]), int(m.geom_type[g]))
                     for h in heading])


def visible_lines(beam_line_labels: np.ndarray, n_lines: int, min_points: int) -> np.ndarray:
    """(K,) bool: at least ``min_points`` beams truly hit the map line in range (dropped returns
    included)."""
    labels = np.asarray(beam_line_labels, int)
    return np.bincount(labels[labels >= 0], minlength=n_lines)[:n_lines] >= min_points
