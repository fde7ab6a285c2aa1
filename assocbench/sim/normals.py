"""Outward normals of landmark sites: read from the site when the MJCF orients it, inferred from
the surface it sits on when it does not, and checked for plausibility either way.

A site written without ``quat``/``euler``/``axisangle``/``xyaxes``/``zaxis`` has the z axis of
its parent frame, +z in the world body: every landmark on a wall would then "face the
ceiling". Such a site's normal is the outward normal of the nearest surface, found with
``mj_ray`` from probe points around the site (see ``surface_normal``).
"""

from __future__ import annotations

import sys

import numpy as np

from .. import _runtime  # noqa: F401  (sets MUJOCO_GL before mujoco loads)

import mujoco  # noqa: E402

# the geom groups mujoco.Renderer draws (mjvOption's default, 0-2): only these are imaged, so
# only these carry a landmark, occlude one or stand in the camera's way (every ray uses this mask)
RENDERED_GROUPS = mujoco.MjvOption().geomgroup.copy()
PROBE_M = 0.05       # probe distance from the site (m): beyond a patch's offset or embedding
REACH_M = 0.015      # a surface within this of the site is the one it sits on (m)
N_PROBES = 96        # probe directions, spread evenly over the sphere


def unoriented_sites(spec: "mujoco.MjSpec", names: list[str]) -> np.ndarray:
    """(L,) True for each named site the MJCF gives no orientation of its own: no
    ``euler``/``axisangle``/``xyaxes``/``zaxis`` (the spec keeps which was used), an identity
    ``quat`` (what MuJoCo stores when none is given) and no ``fromto``."""
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


def surface_normal(model, data, point: np.ndarray, probe: float = PROBE_M,
                   reach: float = REACH_M) -> np.ndarray | None:
    """Outward unit normal of the surface ``point`` sits on, or None when no surface is within
    ``reach``.

    From probe points ``q = point + probe·d`` in ``N_PROBES`` directions ``d`` a ray is cast
    back at ``point``. A probe in open space on the surface's front side enters the surface
    from outside (MuJoCo reports the outward normal ``n`` of the hit, so ``n·d > 0``) at a hit
    ``h`` within ``reach`` of the point, whether the point lies a little in front of the
    surface, on it or embedded in it. A probe inside a solid first meets a surface from within
    (``n·d ≤ 0``) and a probe behind a thin wall meets its back face farther than the front
    one, so the hit nearest the point decides; on a flat surface every accepted hit gives the
    exact normal, on a pillar the nearest one gives the radial normal.
    """
    best, best_gap = None, np.inf
    for d in fibonacci_sphere(N_PROBES):
        dist, normal = _ray(model, data, point + probe * d, -d)
        if dist < 0 or normal @ d <= 0:
            continue
        gap = np.linalg.norm(point + probe * d - dist * d - point)
        if gap <= reach and gap < best_gap - 1e-9:
            best, best_gap = normal / np.linalg.norm(normal), gap
    return best


def faces_open_space(model, data, point: np.ndarray, normal: np.ndarray, probe: float = PROBE_M,
                     reach: float = REACH_M) -> bool | None:
    """Whether an explicit ``normal`` points out of the surface at ``point`` (None: no surface
    there to judge by). The ray from ``point + probe·normal`` back at the point must enter a
    surface facing it near the point; a probe inside a solid, or a surface facing the other
    way, means the site's z axis points into the wall."""
    dist, hit_normal = _ray(model, data, point + probe * normal, -normal)
    if dist < 0 or dist > probe + reach:  # nothing near the point on the side it claims is open
        return None if surface_normal(model, data, point, probe, reach) is None else False
    if dist < probe - reach:
        return None  # something stands in front of the site: cannot tell from here
    return bool(hit_normal @ normal > 0.5)


def plausibility_warning(landmarks: np.ndarray, normals: np.ndarray, names: list[str],
                         unsupported: list[str], against: list[str]) -> str | None:
    """One line saying why the landmark normals look wrong, or None when they look plausible."""
    if unsupported:
        return (f"{len(unsupported)} of {len(names)} landmark sites ({_some(unsupported)}) have no orientation and sit "
                f"on no surface within {REACH_M * 100:.1f} cm: their normals are the sites' z axes; give each a "
                f"zaxis pointing into open space or put it on a geom")
    if against:
        return (f"{len(against)} of {len(names)} landmark sites ({_some(against)}) have a z axis that does not point "
                f"out of the surface they sit on: make their zaxis point into open space (or drop it to have it "
                f"inferred)")
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


def landmark_normals(spec: "mujoco.MjSpec", model, data, site_ids: list[int],
                     scene_name: str) -> tuple[np.ndarray, np.ndarray]:
    """World unit normals (L, 3) of the landmark sites and which of them were inferred (L,).

    Oriented sites keep their z axis; un-oriented ones take the normal of the surface they sit
    on (their z axis when there is none). One line on stderr when the result looks wrong."""
    names = [model.site(i).name for i in site_ids]
    points = data.site_xpos[site_ids].copy()
    normals = data.site_xmat[site_ids].reshape(-1, 3, 3)[:, :, 2].copy()
    infer = unoriented_sites(spec, names)
    unsupported, against = [], []
    for j in range(len(names)):
        if infer[j]:
            found = surface_normal(model, data, points[j])
            if found is None:
                unsupported.append(names[j])
            else:
                normals[j] = found
        elif faces_open_space(model, data, points[j], normals[j]) is False:
            against.append(names[j])
    message = plausibility_warning(points, normals, names, unsupported, against)
    if message:
        warn_once(f"scene {scene_name}: {message}")
    return normals, infer & ~np.isin(names, unsupported)
