"""User camera paths: waypoints from a CSV or YAML file, or the cameras an MJCF defines. A waypoint
gives a camera position and a look-at point or a heading (``yaw`` degrees counter-clockwise from +x,
``pitch`` degrees up), and optionally a time ``t`` (else equally spaced); frames spread over the
whole path (``trajectory.through_keyframes``).

CSV (a header, ``#`` comments)::

    x, y, z, look_x, look_y, look_z        or        x, y, z, yaw, pitch
    0, 0, 1.5, 3, 0, 1.5                            0, 0, 1.5, 0, 0

YAML (a list, or a mapping with ``waypoints:``)::

    - {position: [0, 0, 1.5], look_at: [3, 0, 1.5]}
    - {position: [1, 0, 1.5], yaw: 90, t: 2.0}

The finding, reading and hashing helpers also serve the robot's waypoints (``robot_waypoints``).
"""

from __future__ import annotations

import csv
import hashlib
import io
import math
from pathlib import Path

import numpy as np
import yaml

from ..errors import UserError
from ..models.camera import CV_TO_MUJOCO, look_at
from ..validation import BoundedLoader, brief
from .normals import warn_once
from .scene import Scene, resolve_scene_path
from .trajectory import Keyframes

SUFFIXES = (".csv", ".yaml", ".yml")
_HOW = "a CSV or YAML file of camera positions with look-at points or headings"


def waypoint_path(params: dict, scene_dir: Path | None = None, how: str = _HOW) -> Path:
    """The file of ``trajectory_params.file``: as given, else beside the scene's MJCF; one-line
    error when missing or not CSV/YAML (``how``: whose waypoints)."""
    name = params.get("file")
    if not isinstance(name, str) or not name:
        raise UserError(f"trajectory waypoints needs trajectory_params.file: {how}; got {name!r}")
    path = Path(name).expanduser()
    tried = [path]
    if not path.is_absolute() and scene_dir is not None:
        tried.append(scene_dir / path)
    for candidate in tried:
        if candidate.is_file():
            if candidate.suffix.lower() not in SUFFIXES:
                raise UserError(f"waypoint file {candidate} must be .csv, .yaml or .yml ({how})")
            return candidate.resolve()
    where = " or ".join(str(t) for t in tried)
    raise UserError(f"waypoint file {name!r} not found (looked for {where}); trajectory_params.file names {how}")


def file_digest(path: Path) -> str:
    """Hash of the waypoint file's bytes: it enters the sequence cache key."""
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def waypoint_digest(trajectory: str | None, params: dict, scene: str | Path) -> str | None:
    """``file_digest`` of a ``waypoints`` path's file on any track (found as ``waypoint_path``
    does), else None: what a key holds besides the file's name."""
    if trajectory != "waypoints":
        return None
    return file_digest(waypoint_path(params, resolve_scene_path(scene).parent))


def read_text(path: Path) -> str:
    """The file's text (UTF-8, a byte-order mark dropped); one-line ``UserError`` when unreadable."""
    try:
        return path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"cannot read waypoint file {path}: {exc}") from None


def read_waypoints(path: Path) -> Keyframes:
    """Parse and check a waypoint file; one-line ``UserError`` naming the file and line."""
    text = read_text(path)
    rows = _csv_rows(path, text) if path.suffix.lower() == ".csv" else _yaml_rows(path, text)
    if len(rows) < 2:
        raise UserError(f"waypoint file {path} has {len(rows)} waypoint(s); give at least 2")
    return _keyframes(path, rows)


# one waypoint: where it is written (for messages), position, look-at point, (yaw, pitch), time
Row = tuple[str, np.ndarray, np.ndarray | None, tuple[float, float] | None, float | None]


def number(path: Path, where: str, name: str, value) -> float:
    """``value`` as a finite float, else a one-line ``UserError`` naming the file, row and column."""
    try:
        if isinstance(value, bool):
            raise TypeError
        x = float(value)
    except (TypeError, ValueError):
        raise UserError(f"waypoint file {path} {where}: {name} = {brief(value)} is not a number") from None
    if not math.isfinite(x):
        raise UserError(f"waypoint file {path} {where}: {name} is {x}; every value must be finite")
    return x


def csv_table(path: Path, text: str) -> tuple[str, list[str], list[tuple[str, list[str]]]]:
    """A waypoint CSV's header (where, lower-case names) and each data row's cells with its
    ``line N``; blank and ``#`` lines skipped; a row of another width is a one-line ``UserError``."""
    lines = [(k + 1, line) for k, line in enumerate(text.splitlines())
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        return "line 1", [], []
    header = [h.strip().lower() for h in next(csv.reader(io.StringIO(lines[0][1])))]
    rows = []
    for lineno, line in lines[1:]:
        cells = [c.strip() for c in next(csv.reader(io.StringIO(line)))]
        if len(cells) != len(header):
            raise UserError(f"waypoint file {path} line {lineno}: {len(cells)} values for {len(header)} columns")
        rows.append((f"line {lineno}", cells))
    return f"line {lines[0][0]}", header, rows


def _csv_rows(path: Path, text: str) -> list[Row]:
    at, header, table = csv_table(path, text)
    if not header:
        return []
    has_look = {"look_x", "look_y", "look_z"} <= set(header)
    if not {"x", "y", "z"} <= set(header) or not (has_look or "yaw" in header) or len(set(header)) != len(header):
        raise UserError(f"waypoint file {path} {at}: the header must name x, y, z and either look_x, "
                        f"look_y, look_z or yaw (pitch, t optional), each once; got {', '.join(header)}")
    rows = []
    for where, cells in table:
        # empty cells are allowed where a row uses the other way of looking (look-at or yaw)
        v = {h: number(path, where, h, c) for h, c in zip(header, cells) if c != "" or h in ("x", "y", "z")}
        pos = np.array([v["x"], v["y"], v["z"]])
        given = [k in v for k in ("look_x", "look_y", "look_z")]
        if any(given) and not all(given):
            raise UserError(f"waypoint file {path} {where}: give look_x, look_y and look_z together")
        look = np.array([v["look_x"], v["look_y"], v["look_z"]]) if all(given) else None
        heading = (v["yaw"], v.get("pitch", 0.0)) if look is None and "yaw" in v else None
        rows.append(_row(path, where, pos, look, heading, v.get("t")))
    return rows


def yaml_list(path: Path, text: str, each: str) -> list:
    """A waypoint YAML's list (or ``waypoints:``'s); one-line ``UserError`` otherwise (``each``: one
    waypoint's form)."""
    try:
        data = yaml.load(text, Loader=BoundedLoader)  # noqa: S506 - a SafeLoader, aliases bounded
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1}" if mark else ""
        raise UserError(f"malformed YAML in waypoint file {path}{at}: {getattr(exc, 'problem', exc)}") from None
    if isinstance(data, dict) and set(data) == {"waypoints"}:
        data = data["waypoints"]
    if not isinstance(data, list):
        raise UserError(f"waypoint file {path} must hold a list of waypoints (or waypoints: [...]), each {each}")
    return data


def _yaml_rows(path: Path, text: str) -> list[Row]:
    data = yaml_list(path, text, "{position: [x, y, z], look_at: [x, y, z]} or {position: ..., yaw: deg}")
    rows = []
    for k, item in enumerate(data):
        where = f"waypoint {k + 1}"
        known = {"position", "look_at", "yaw", "pitch", "t"}
        if not isinstance(item, dict) or "position" not in item or not set(item) <= known:
            raise UserError(f"waypoint file {path} {where}: expected a mapping with position and look_at or yaw "
                            f"(pitch, t optional), got {brief(item)}")
        pos = vector(path, where, "position", item["position"])
        look = vector(path, where, "look_at", item["look_at"]) if "look_at" in item else None
        heading = None
        if look is None and "yaw" in item:
            heading = (number(path, where, "yaw", item["yaw"]), number(path, where, "pitch", item.get("pitch", 0.0)))
        t = number(path, where, "t", item["t"]) if "t" in item else None
        rows.append(_row(path, where, pos, look, heading, t))
    return rows


def vector(path: Path, where: str, name: str, value, axes: str = "x, y, z") -> np.ndarray:
    """``value`` as a list of finite numbers, one per name in ``axes``; else a one-line ``UserError``."""
    if not isinstance(value, (list, tuple)) or len(value) != len(axes.split(",")):
        raise UserError(f"waypoint file {path} {where}: {name} must be [{axes}], got {brief(value)}")
    return np.array([number(path, where, f"{name}[{i}]", c) for i, c in enumerate(value)])


def _row(path: Path, where: str, pos, look, heading, t) -> Row:
    if look is None and heading is None:
        raise UserError(f"waypoint file {path} {where}: give where the camera looks (look_at point or yaw)")
    if look is not None and np.linalg.norm(look - pos) < 1e-9:
        raise UserError(f"waypoint file {path} {where}: the look-at point is the position itself; the camera "
                        f"needs a direction")
    return where, pos, look, heading, t


def _keyframes(path: Path, rows: list[Row]) -> Keyframes:
    times = [r[4] for r in rows]
    if any(t is None for t in times) and any(t is not None for t in times):
        raise UserError(f"waypoint file {path}: give t for every waypoint or for none")
    if times[0] is None:
        t = np.linspace(0.0, 1.0, len(rows))
    else:
        t = np.array(times, float)
        bad = np.flatnonzero(np.diff(t) <= 0)
        if len(bad):
            raise UserError(f"waypoint file {path} {rows[bad[0] + 1][0]}: t must increase strictly "
                            f"({t[bad[0]]:g} then {t[bad[0] + 1]:g})")
        t = (t - t[0]) / (t[-1] - t[0])
    rots = []
    for _, pos, look, heading, _t in rows:
        if look is None:
            yaw, pitch = np.deg2rad(heading)
            look = pos + np.array([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), np.sin(pitch)])
        rots.append(look_at(pos, look))
    return Keyframes(np.array(rots), np.array([r[1] for r in rows]), t)


def camera_keyframes(scene: Scene, cameras=None) -> Keyframes:
    """Keyframes at the MJCF's cameras ``cameras`` (default: all, in order), equally spaced in time."""
    model, data = scene.model, scene.data
    own = [i for i in range(model.ncam) if i != scene.camera_id]
    if not own:
        raise UserError(f"scene {scene.name} defines no <camera>: add one, or choose another trajectory")
    named = {model.camera(i).name: i for i in own if model.camera(i).name}
    if cameras is None:
        ids = own
    else:
        names = [cameras] if isinstance(cameras, str) else cameras
        if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
            raise UserError(f"trajectory_params.cameras must be a camera name or a list of them, got {cameras!r}")
        unknown = [n for n in names if n not in named]
        if unknown:
            raise UserError(f"scene {scene.name} has no camera {unknown[0]!r}: its named cameras are "
                            f"{', '.join(named) or 'none'}")
        ids = [named[n] for n in names]
    other = [model.camera(i).name or f"#{i}" for i in ids if abs(model.cam_fovy[i] - scene.fovy) > 0.5]
    if other:
        warn_once(f"scene {scene.name}: camera {other[0]} has its own fovy; frames are rendered with "
                  f"<visual><global fovy> = {scene.fovy:g}°, so they show a different field of view")
    rots = np.array([data.cam_xmat[i].reshape(3, 3) @ CV_TO_MUJOCO for i in ids])
    pos = np.array([data.cam_xpos[i] for i in ids])
    return Keyframes(rots, pos, np.linspace(0.0, 1.0, len(ids)) if len(ids) > 1 else np.zeros(1))


def user_keyframes(name: str, params: dict, scene: Scene) -> tuple[dict, Keyframes | None]:
    """Split ``trajectory_params`` into a user path's keyframes (``waypoints``: ``file``;
    ``mjcf-cameras``: ``cameras``) and the parameters left for ``make_trajectory``."""
    rest = dict(params)
    if name == "waypoints":
        path = waypoint_path(params, scene.path.parent)
        rest.pop("file")
        return rest, read_waypoints(path)
    if name == "mjcf-cameras":
        return rest, camera_keyframes(scene, rest.pop("cameras", None))
    return rest, None
