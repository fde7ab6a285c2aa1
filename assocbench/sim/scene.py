"""Load a scene: a shipped name (``room``) or any MJCF following the ``lm*`` convention: a landmark
is an ``lm*`` site whose z axis is its outward normal (or, un-oriented, its surface's:
``normals.landmark_normals``). The loader adds its own camera and reads the offscreen buffer size,
which bounds the resolution.
"""

from __future__ import annotations

import hashlib
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import mujoco  # loaded under MUJOCO_GL by assocbench.sim (gl.py) before this module runs
import numpy as np

from ..errors import UserError
from .normals import RENDERED_GROUPS, landmark_normals

CAMERA_NAME = "assocbench_eye"
LANDMARK_PREFIX = "lm"
WALL_PREFIX = "lw"        # the lines track's map walls: box geoms named lw*


def shipped_scenes() -> dict[str, Path]:
    """Names and paths of the scenes shipped in the wheel (``assocbench/scenes``)."""
    root = Path(str(resources.files("assocbench.scenes")))
    return {p.stem: p for p in sorted(root.glob("*.xml"))}


def resolve_scene_path(scene: str | Path) -> Path:
    """Path of a shipped scene name or an MJCF file; a one-line error otherwise (not found, a
    folder, not ``.xml``)."""
    shipped = shipped_scenes()
    if str(scene) in shipped:
        return shipped[str(scene)]
    path = Path(scene)
    names = ", ".join(shipped)
    if path.is_dir():
        raise UserError(f"scene {str(scene)!r} is a folder: give the MJCF .xml file in it, or one of {names}")
    if path.is_file():
        if path.suffix.lower() == ".xml":
            return path.resolve()
        raise UserError(f"scene {str(scene)!r} is not an MJCF file: a scene is MuJoCo XML with lm* sites, named "
                        f"*.xml (rename it if it is one), or one of {names}")
    raise UserError(f"scene {str(scene)!r} not found: use one of {names} or the path of an existing MJCF .xml file")


def mjcf_error(path: Path, exc: Exception) -> UserError:
    """MuJoCo's whole message on one line (its first line is often only "XML parse error 6:"), plus
    Python's parser's reason for malformed XML."""
    said = " ".join(str(exc).split()) or type(exc).__name__
    if "XML_ERROR" in said or "parse error" in said.lower():
        import xml.etree.ElementTree as ET

        try:
            ET.parse(path)
        except ET.ParseError as perr:
            said += f" (Python's XML parser: {perr})"
    return UserError(f"cannot load MJCF {path}: {said}")


def mjcf_names(path: Path) -> tuple[int, int, int]:
    """How many ``lm*`` sites, ``lm*`` geoms and ``lw*`` geoms an MJCF names (parsed, not compiled):
    what the scene conventions read."""
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except (ValueError, RuntimeError) as exc:
        raise mjcf_error(path, exc) from None

    def named(items, prefix: str) -> int:
        return sum(1 for item in items if item.name.startswith(prefix))

    return named(spec.sites, LANDMARK_PREFIX), named(spec.geoms, LANDMARK_PREFIX), named(spec.geoms, WALL_PREFIX)


@dataclass
class Scene:
    """A compiled scene with its landmarks and the camera the renderer drives."""

    name: str
    path: Path
    model: mujoco.MjModel
    data: mujoco.MjData
    landmark_names: list[str]
    landmarks: np.ndarray      # (L, 3) world positions of the X-junctions
    normals: np.ndarray        # (L, 3) outward unit normals
    camera_id: int
    fovy: float
    offscreen: tuple[int, int]  # (width, height) of the MJCF offscreen buffer
    inferred: np.ndarray | None = None  # (L,) normals taken from the surface (un-oriented sites)

    @property
    def digest(self) -> str:
        """The scene's content hash (``scene_digest``): the cache key part."""
        return scene_digest(self.path)

    def free_distance(self, origin: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Distance (k,) from ``origin`` to the first surface along each direction: ``inf`` for
        none, 0 inside a solid."""
        dirs = np.ascontiguousarray(directions, dtype=np.float64)
        k = len(dirs)
        dist, geom, normal = np.empty(k), np.empty(k, np.int32), np.empty(3 * k)
        mujoco.mj_multiRay(self.model, self.data, np.asarray(origin, np.float64), dirs.ravel(), RENDERED_GROUPS,
                           True, -1, geom, dist, normal, k, 1e6)
        inside = np.einsum("ij,ij->i", normal.reshape(k, 3), dirs) > 0
        return np.where(dist < 0, np.inf, np.where(inside & (dist >= 0), 0.0, dist))


ASSET_SUFFIXES = {".png", ".obj", ".stl", ".msh", ".xml"}
# which <compiler> folder an element's files are looked up in (MuJoCo's rule: meshes, height fields
# and skins in meshdir, textures in texturedir; assetdir sets both), relative to the main file
ASSET_DIRS = {"mesh": "meshdir", "hfield": "meshdir", "skin": "meshdir", "texture": "texturedir"}


def _mjcf_trees(path: Path) -> list[tuple[Path, ET.Element]]:
    """The main MJCF and its ``<include>``s, recursively, parsed; includes looked for beside the
    main and the including file."""
    trees, todo, seen = [], [path], set()
    while todo:
        current = todo.pop()
        if current in seen or not current.is_file():
            continue
        seen.add(current)
        try:
            root = ET.parse(current).getroot()
        except ET.ParseError:
            continue   # MuJoCo's own parse reports it when the scene loads
        trees.append((current, root))
        todo += [(base / element.get("file")).resolve() for element in root.iter("include") if element.get("file")
                 for base in (path.parent, current.parent)]
    return trees


def _asset_folders(path: Path, trees: list[tuple[Path, ET.Element]]) -> dict[str, Path]:
    """``meshdir`` and ``texturedir`` as the scene's ``<compiler>`` sets them (``assetdir`` both)."""
    out: dict[str, Path] = {}
    for _, root in trees:
        for compiler in root.iter("compiler"):
            for key in ("assetdir", "meshdir", "texturedir"):
                if compiler.get(key):
                    folder = (path.parent / compiler.get(key)).resolve()
                    out |= {"meshdir": folder, "texturedir": folder} if key == "assetdir" else {key: folder}
    return out


def scene_files(path: Path) -> list[Path]:
    """Every file the MJCF at ``path`` is made of, what a digest must cover: itself, its
    ``<include>``s (recursively), every file an element names (meshes, height fields, skins,
    textures) in its ``<compiler>`` folders or beside the including or main file, and the asset
    files beside it."""
    path = path.resolve()
    trees = _mjcf_trees(path)
    folders = _asset_folders(path, trees)
    found = [file for file, _ in trees]
    for current, root in trees:
        for element in root.iter():
            if element.tag == "include":
                continue
            bases = [folders[ASSET_DIRS[element.tag]]] if ASSET_DIRS.get(element.tag) in folders else []
            bases += [current.parent, path.parent]
            names = [value for key, value in element.attrib.items() if key.startswith("file") and value]
            found += [f for name in names for f in ((base / name).resolve() for base in bases) if f.is_file()]
    extras = [f.resolve() for f in sorted(path.parent.iterdir()) if f.suffix.lower() in ASSET_SUFFIXES - {".xml"}]
    return sorted(dict.fromkeys([*found, *extras]))


def scene_digest(scene: str | Path) -> str:
    """SHA-256 (16 hex digits) of the names and contents of every file of a scene (``scene_files``)."""
    path = resolve_scene_path(scene)
    h = hashlib.sha256()
    for f in scene_files(path):
        h.update(str(f.relative_to(path.parent) if f.is_relative_to(path.parent) else f.name).encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


def load_scene(scene: str | Path) -> Scene:
    """Compile a scene and extract its ``lm*`` landmark sites."""
    path = resolve_scene_path(scene)
    try:
        spec = mujoco.MjSpec.from_file(str(path))
        fovy = float(spec.visual.global_.fovy)
        spec.worldbody.add_camera(name=CAMERA_NAME, fovy=fovy)
        model = spec.compile()
    except (ValueError, RuntimeError) as exc:
        raise mjcf_error(path, exc) from None
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    names = [model.site(i).name for i in range(model.nsite)]
    idx = [i for i, n in enumerate(names) if n.startswith(LANDMARK_PREFIX)]
    if not idx:
        raise UserError(
            f"MJCF {path} has no landmarks: add <site name=\"lm0\" .../> at each X-junction (camera track), or make "
            f"posts cylinder geoms named lm0, lm1... of one radius (planar track)"
        )
    normals, inferred = landmark_normals(spec, model, data, idx, path.stem)
    return Scene(
        name=path.stem,
        path=path,
        model=model,
        data=data,
        landmark_names=[names[i] for i in idx],
        landmarks=data.site_xpos[idx].copy(),
        normals=normals,
        camera_id=mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, CAMERA_NAME),
        fovy=fovy,
        offscreen=(int(model.vis.global_.offwidth), int(model.vis.global_.offheight)),
        inferred=inferred,
    )
