"""Outward normals of landmark sites: read from the site when the MJCF orients it, else inferred
from the surface it sits on, and checked for plausibility either way. An un-oriented site has its
parent's z axis (a wall's landmarks would "face the ceiling"), so its normal is found with
``mj_ray`` from probes around it and, where faces meet at the site, decided by the face covering a
small ring round it (``surface_normal``).
"""

from __future__ import annotations

import sys

import mujoco  # loaded under MUJOCO_GL by assocbench.sim (gl.py) before this module runs
import numpy as np

# the geom groups mujoco.Renderer draws (mjvOption's default, 0-2): only these are imaged, so
# only these carry a landmark, occlude one or stand in the camera's way (every ray uses this mask)
RENDERED_GROUPS = mujoco.MjvOption().geomgroup.copy()
PROBE_M = 0.05       # probe distance from the site (m): beyond a patch's offset or embedding
REACH_M = 0.015      # a surface within this of the site is the one it sits on (m)
N_PROBES = 96        # probe directions, spread evenly over the sphere
RING_M = 0.005       # radius of the ring of rays that checks a candidate face round the site (m)
N_RING = 8           # rays in that ring
SAME_FACE_DEG = 5.0  # hit normals closer than this are one face (a 30 cm pillar turns 3° over reach)
FACING_COS = 0.7     # a ring ray's hit faces the candidate within 45°: a side face (90°) does not,
                     # a pillar does down to 7 mm radius (its normal turns asin(RING_M / radius))


def unoriented_sites(spec: mujoco.MjSpec, names: list[str]) -> np.ndarray:
    """(L,) True for each named site given no orientation: no
    ``euler``/``axisangle``/``xyaxes``/``zaxis``, an identity ``quat`` (MuJoCo's default) and no
    ``fromto``."""
    sites = {s.name: s for s in spec.sites}
    quat_given = mujoco.mjtOrientation.mjORIENTATION_QUAT
    out = []
    for name in names:
        s = sites.get(name)
        if s is None:  # not in the spec under this name (generated): trust its compiled frame
            out.append(False)
            continue
        identity = np.allclose(np.asarray(s.quat, float), [1.0, 0.0, 0.0, 0.0])
        out.append(s.alt.type == quat_given and identity and np.isnan(s.fromto[0]))
    return np.array(out, bool)


def fibonacci_sphere(n: int) -> np.ndarray:
    """(n, 3) unit vectors spread evenly over the sphere (golden-angle spiral)."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = np.pi * (1.0 + 5**0.5) * k
    r = np.sqrt(1.0 - z * z)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def _ray(model, data, origin: np.ndarray, direction: np.ndarray) -> tuple[float, np.ndarray]:
    """Distance to the first rendered surface along a ray (-1: none) and its outward normal."""
    geom, normal = np.zeros(1, np.int32), np.zeros(3)
    dist = mujoco.mj_ray(model, data, origin, direction, RENDERED_GROUPS, 1, -1, geom, normal)
    return float(dist), normal


def _probe_hits(model, data, point: np.ndarray, probe: float, reach: float) -> list[tuple[float, np.ndarray]]:
    """(gap, unit outward normal) of each probe ray entering a surface from outside within ``reach``
    of ``point``, nearest first."""
    hits = []
    for d in fibonacci_sphere(N_PROBES):
        dist, normal = _ray(model, data, point + probe * d, -d)
        if dist < 0 or normal @ d <= 0:
            continue
        gap = float(np.linalg.norm((probe - dist) * d))   # |hit - point|, the hit being q - dist·d
        if gap <= reach:
            hits.append((gap, normal / np.linalg.norm(normal)))
    return sorted(hits, key=lambda h: h[0])


def _distinct_faces(hits: list[tuple[float, np.ndarray]], most: int = 8) -> list[np.ndarray]:
    """One normal per face direction among the hits (directions over ``SAME_FACE_DEG`` apart),
    nearest first: the nearest hit speaks for its direction."""
    faces: list[np.ndarray] = []
    for _, normal in hits:
        if len(faces) < most and all(normal @ f < np.cos(np.deg2rad(SAME_FACE_DEG)) for f in faces):
            faces.append(normal)
    return faces


def ring_offsets(normal: np.ndarray, radius: float = RING_M, k: int = N_RING) -> np.ndarray:
    """(k, 3) offsets of length ``radius`` perpendicular to ``normal``, evenly round it, avoiding
    the axes of the frame on ``normal`` (where tile edges lie)."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(normal, helper)
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    a = 2 * np.pi * (np.arange(k) + 0.25) / k
    return radius * (np.outer(np.cos(a), u) + np.outer(np.sin(a), v))


def starts_inside(model, data, origin: np.ndarray, away: np.ndarray) -> bool:
    """Whether ``origin`` lies inside a solid: the ray along ``away`` first meets a surface from
    within. A face glued to another solid is met at that solid's own face's distance, so only a ray
    from open space counts it as seen."""
    dist, hit = _ray(model, data, origin, away)
    return dist >= 0 and hit @ away > 0


def ring_shares(model, data, point: np.ndarray, normal: np.ndarray, probe: float = PROBE_M,
                reach: float = REACH_M) -> tuple[float, float]:
    """Of rays cast along ``-normal`` from ``point + probe·normal + o`` (``o`` in ``ring_offsets``):
    the share meeting, from open space, a surface facing ``normal`` (``cos > FACING_COS``) at the
    point's depth (``|dist - probe| ≤ reach``), i.e. how much of the ring that face covers; and the
    share stopped well before (something in front)."""
    facing = blocked = 0
    offsets = ring_offsets(normal)
    for o in offsets:
        dist, hit = _ray(model, data, point + probe * normal + o, -normal)
        blocked += 0 <= dist < probe - reach
        if abs(dist - probe) <= reach and hit @ normal > FACING_COS * np.linalg.norm(hit):
            facing += not starts_inside(model, data, point + probe * normal + o, normal)
    return facing / len(offsets), blocked / len(offsets)


def surface_normal(model, data, point: np.ndarray, probe: float = PROBE_M,
                   reach: float = REACH_M) -> tuple[np.ndarray, float] | None:
    """Outward unit normal of the surface ``point`` sits on and the share of the ring round it this
    face covers, or None when no surface is within ``reach``.

    Rays are cast back at ``point`` from probes ``q = point + probe·d`` in ``N_PROBES`` directions:
    a probe in open space on the front side enters the surface from outside (MuJoCo's outward normal
    ``n``, ``n·d > 0``) within ``reach``, whether the point lies in front of, on or in the surface;
    a probe inside a solid meets a surface from within. Every distinct hit normal is a candidate,
    and the face covering most of the ring (``ring_shares``) wins, nearest of equals. The ring
    decides where faces meet: at box tiles' shared corners every probe ray ends exactly there, and
    rounding reports a front or side face at random; the tiles' fronts cover the ring, a buried side
    face none of it.
    """
    hits = _probe_hits(model, data, point, probe, reach)
    if not hits:
        return None
    best, best_support = hits[0][1], -1.0
    for normal in _distinct_faces(hits):
        support = ring_shares(model, data, point, normal, probe, reach)[0]
        if support > best_support:   # strictly: the nearest of equally supported faces
            best, best_support = normal, support
        if support == 1.0:           # nothing farther can beat it
            break
    return best, best_support


def faces_open_space(model, data, point: np.ndarray, normal: np.ndarray, probe: float = PROBE_M,
                     reach: float = REACH_M) -> bool | None:
    """Whether an explicit ``normal`` points out of the surface at ``point`` (None: no surface to
    judge). The ray from ``point + probe·normal`` must enter a surface facing it near the point;
    when that one ray does not say yes (aimed at a seam between tiles) the ring decides
    (``ring_shares``)."""
    dist, hit_normal = _ray(model, data, point + probe * normal, -normal)
    if abs(dist - probe) <= reach and hit_normal @ normal > 0.5:
        if not starts_inside(model, data, point + probe * normal, normal):
            return True
    facing, blocked = ring_shares(model, data, point, normal, probe, reach)
    if facing >= 0.5:
        return True
    if blocked >= 0.5:
        return None  # something stands in front of the site: cannot tell from here
    return None if surface_normal(model, data, point, probe, reach) is None else False


def plausibility_warning(landmarks: np.ndarray, normals: np.ndarray, names: list[str],
                         unsupported: list[str], against: list[str], on_edge: list[str] = ()) -> str | None:
    """One line saying why the landmark normals look wrong, or None when they look plausible."""
    if unsupported:
        return (f"{len(unsupported)} of {len(names)} landmark sites ({_some(unsupported)}) have no orientation and sit "
                f"on no surface within {REACH_M * 100:.1f} cm: their normals are the sites' z axes; give each a "
                f"zaxis pointing into open space or put it on a geom")
    if against:
        return (f"{len(against)} of {len(names)} landmark sites ({_some(against)}) have a z axis that does not point "
                f"out of the surface they sit on: make their zaxis point into open space (or drop it to have it "
                f"inferred)")
    if on_edge:
        return (f"{len(on_edge)} of {len(names)} landmark sites ({_some(on_edge)}) have no orientation and sit on an "
                f"edge or corner that no one face surrounds: their inferred normals are a guess; give each a zaxis "
                f"pointing into open space or move it onto a face")
    spread = np.ptp(landmarks @ normals[0]) if len(landmarks) else 0.0
    if len(names) >= 4 and np.all(normals @ normals[0] > np.cos(np.deg2rad(1.0))) and spread > 0.25:
        return (f"all {len(names)} landmark normals are identical ({_fmt(normals[0])}) although the landmarks spread "
                f"{spread:.2f} m along them (not one flat wall): orient each site (zaxis) or put it on its surface")
    return None


_WARNED: set[str] = set()


def warn_once(message: str) -> None:
    """Print ``assocbench: warning: message`` on stderr once per process."""
    if message not in _WARNED:
        _WARNED.add(message)
        print(f"assocbench: warning: {message}", file=sys.stderr)


def _some(names: list[str], k: int = 3) -> str:
    return ", ".join(names[:k]) + (", ..." if len(names) > k else "")


def _fmt(v: np.ndarray) -> str:
    return ", ".join(f"{x:+.2f}" for x in v)


def landmark_normals(spec: mujoco.MjSpec, model, data, site_ids: list[int],
                     scene_name: str) -> tuple[np.ndarray, np.ndarray]:
    """World unit normals (L, 3) of the landmark sites and which were inferred (L,): oriented sites
    keep their z axis, others take their surface's normal (their z axis without one); one line on
    stderr when the result looks wrong."""
    names = [model.site(i).name for i in site_ids]
    points = data.site_xpos[site_ids].copy()
    normals = data.site_xmat[site_ids].reshape(-1, 3, 3)[:, :, 2].copy()
    infer = unoriented_sites(spec, names)
    unsupported, against, on_edge = [], [], []
    for j in range(len(names)):
        if infer[j]:
            found = surface_normal(model, data, points[j])
            if found is None:
                unsupported.append(names[j])
            else:
                normals[j] = found[0]
                if found[1] <= 0.5:  # no face covers most of the ring round the site: an edge or corner
                    on_edge.append(names[j])
        elif faces_open_space(model, data, points[j], normals[j]) is False:
            against.append(names[j])
    message = plausibility_warning(points, normals, names, unsupported, against, on_edge)
    if message:
        warn_once(f"scene {scene_name}: {message}")
    return normals, infer & ~np.isin(names, unsupported)
