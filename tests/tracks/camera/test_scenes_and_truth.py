"""Simulation half: scenes, rendering, detection and ground truth on real MuJoCo frames."""

from __future__ import annotations

import numpy as np
import pytest

from assocbench.models.camera import look_at
from assocbench.sim.render import FrameRenderer
from assocbench.sim.scene import load_scene, shipped_scenes
from assocbench.tracks.camera.detect import detect
from assocbench.tracks.camera.sequence import SequenceSpec, load_sequence, render_sequence
from assocbench.tracks.camera.settings import DetectorConfig, TruthConfig
from assocbench.tracks.camera.truth import label_features, occluded_by_depth, visibility
from assocbench.tracks.inference import track_for_scene


def label_errors(seq) -> np.ndarray:
    errs = [np.linalg.norm(f[lab >= 0] - uv[lab[lab >= 0]], axis=1)
            for f, lab, uv in zip(seq.features, seq.labels, seq.projections)]
    return np.concatenate(errs)


def test_shipped_scenes_have_enough_landmarks():
    counts = {name: len(load_scene(name).landmarks) for name in shipped_scenes() if track_for_scene(name).name == "camera"}
    assert set(counts) == {"room", "checkerboard", "corridor", "bays", "crates"}
    assert counts["room"] >= 60 and min(counts.values()) >= 60


@pytest.mark.parametrize("scene", ["room", "checkerboard", "corridor"])
def test_labelled_features_sit_on_true_projections(scene):
    """Median distance to the true projection <= 0.3 px at 640x480; typical frames see >= 10."""
    seq = load_sequence(SequenceSpec(scene=scene, frames=8))
    errs = label_errors(seq)
    assert len(errs) >= 8 * 10
    assert np.median(errs) <= 0.3
    assert np.median(seq.visible.sum(axis=1)) >= 10


@pytest.mark.parametrize("width,height", [(320, 240), (640, 480)])
def test_without_multisampling_labels_stay_accurate(width, height):
    """msaa=0 (the fast path) renders other pixels but its labels stay within 0.3 px (median)."""
    fast = render_sequence(SequenceSpec(scene="room", frames=4, width=width, height=height, msaa=0, keep_images=True))
    smooth = render_sequence(SequenceSpec(scene="room", frames=1, width=width, height=height, keep_images=True))
    assert not np.array_equal(fast.images[0], smooth.images[0])
    assert np.median(label_errors(fast)) <= 0.3
    scene = load_scene("room")
    with FrameRenderer(scene, 64, 48, msaa=0):
        assert scene.model.vis.quality.offsamples == 4                    # the scene's own setting is kept


def test_room_detects_and_labels_95_percent_of_visible_landmarks(room_sequence):
    visible = room_sequence.visible.sum()
    labelled_visible = sum(int(np.sum(vis[lab[lab >= 0]])) for vis, lab in zip(room_sequence.visible, room_sequence.labels))
    assert labelled_visible >= 0.95 * visible


def test_landmark_behind_a_pillar_is_not_visible_nor_labelled():
    """Camera placed so the pillar at (1.9, 1.9) hides landmark (4, 2.2, 1.55) on the +x wall."""
    scene = load_scene("room")
    target = int(np.argmin(np.linalg.norm(scene.landmarks - [4.0, 2.2, 1.55], axis=1)))
    cam = np.array([0.0, 1.629, 1.55])
    R = look_at(cam, scene.landmarks[target])
    with FrameRenderer(scene, 640, 480) as r:
        frame = r.render(R, cam, depth=True)
        K = r.K
    uv, visible = visibility(scene, R, cam, K, TruthConfig())
    assert np.allclose(uv[target], [K.cx, K.cy], atol=1.0)     # straight ahead, in view
    assert not visible[target]
    depth_says = occluded_by_depth(frame["depth"], uv[[target]], np.array([np.linalg.norm(scene.landmarks[target] - cam)]) * 0.999)
    assert depth_says[0]                                         # the depth image agrees with mj_ray
    labels = label_features(detect(frame["rgb"], DetectorConfig()), uv, visible, 2.0)
    assert target not in labels
    assert np.sum(labels >= 0) >= 5                              # the unhidden landmarks are labelled


def test_two_renders_are_identical():
    spec = SequenceSpec(scene="checkerboard", frames=3)
    a, b = render_sequence(spec), render_sequence(spec)
    for fa, fb, la, lb in zip(a.features, b.features, a.labels, b.labels):
        assert np.array_equal(fa, fb) and np.array_equal(la, lb)
    assert np.array_equal(a.visible, b.visible)


def test_cache_hit_does_no_rendering(tmp_path, monkeypatch):
    import assocbench.tracks.camera.sequence as sequence

    spec = SequenceSpec(scene="room", frames=2, seed=5)
    first = load_sequence(spec, tmp_path)
    assert not first.from_cache

    def no_render(*args, **kwargs):
        raise AssertionError("rendered on a cache hit")

    monkeypatch.setattr(sequence, "FrameRenderer", no_render)
    second = load_sequence(spec, tmp_path)
    assert second.from_cache
    assert all(np.array_equal(x, y) for x, y in zip(first.features, second.features))
    with pytest.raises(AssertionError, match="rendered"):   # a changed setting is a new key
        load_sequence(SequenceSpec(scene="room", frames=2, seed=5, detector=DetectorConfig(quality=0.05)), tmp_path)


@pytest.mark.parametrize("method", ["fast", "orb"])
def test_other_detectors_run_and_refine(method):
    seq = load_sequence(SequenceSpec(scene="checkerboard", frames=1, detector=DetectorConfig(method=method)))
    assert len(seq.features[0]) > 0


def test_noise_model_moves_features_by_its_sigma():
    seq = load_sequence(SequenceSpec(scene="checkerboard", frames=1, keep_images=True))
    img = seq.images[0]
    base = detect(img, DetectorConfig())
    noisy = detect(img, DetectorConfig(noise_px=0.5), np.random.default_rng(0))
    assert len(base) == len(noisy) > 30
    nearest = np.linalg.norm(noisy[:, None] - base[None], axis=2).argmin(axis=1)
    assert np.std(noisy - base[nearest]) == pytest.approx(0.5, rel=0.2)


USER_MJCF = """<mujoco>
  <visual><global offwidth="320" offheight="240" fovy="50"/>
    <headlight ambient="1 1 1" diffuse="0 0 0" specular="0 0 0"/></visual>
  <worldbody>
    <geom type="box" pos="0 0.02 0" size="2 0.01 2" rgba="0.6 0.6 0.6 1"/>
    {patches}
  </worldbody>
</mujoco>"""


def user_patch(k: int, x: float, z: float) -> str:
    s = 0.06
    quads = [(1, 1, "0 0 0 1"), (-1, -1, "0 0 0 1"), (1, -1, "1 1 1 1"), (-1, 1, "1 1 1 1")]
    geoms = "".join(f'<geom type="box" pos="{x + a * s} 0 {z + b * s}" size="{s} 0.005 {s}" rgba="{c}"/>' for a, b, c in quads)
    return geoms + f'<site name="lm{k}" pos="{x} -0.005 {z}" zaxis="0 -1 0"/>'


def test_user_mjcf_with_lm_sites_works_without_code_change(tmp_path):
    patches = "".join(user_patch(k, x, z) for k, (x, z) in enumerate([(-0.3, 0.2), (0.0, 0.0), (0.3, 0.2), (-0.3, -0.2), (0.3, -0.2)]))
    path = tmp_path / "wall.xml"
    path.write_text(USER_MJCF.format(patches=patches))
    seq = load_sequence(SequenceSpec(scene=str(path), frames=4, width=320, height=240))
    assert len(seq.landmarks) == 5
    assert seq.visible.sum(axis=1).min() == 5
    assert np.median(label_errors(seq)) <= 0.3


def oracle_visible(scene, R, p, K) -> np.ndarray:
    """Landmarks really imaged, decided here without ``truth``: in front, projecting into the
    image, front side towards the camera and the first surface on the ray is the landmark."""
    import mujoco

    from assocbench.models.camera import project

    uv, z = project(scene.landmarks, R, p, K)
    inside = (z > 0) & K.in_image(np.nan_to_num(uv, nan=-1e9))
    facing = np.einsum("ij,ij->i", scene.normals, p - scene.landmarks) > 0
    clear = np.zeros(len(uv), bool)
    geom = np.zeros(1, np.int32)
    for j in np.flatnonzero(inside & facing):
        vec = scene.landmarks[j] - p
        dist = np.linalg.norm(vec)
        hit = mujoco.mj_ray(scene.model, scene.data, p, vec / dist, None, 1, -1, geom)
        clear[j] = hit < 0 or hit >= dist - 0.02
    return clear


@pytest.mark.parametrize("scene_name", ["room", "checkerboard", "corridor"])
def test_every_imaged_landmark_with_a_feature_on_it_is_labelled(scene_name):
    """Truth follows what is imaged: a landmark that is in view, unoccluded, turned towards the
    camera (however obliquely) and has a detected feature within the gate of its true projection
    (and no other such landmark near that feature) is labelled, so pairing it is never an FP."""
    spec = SequenceSpec(scene=scene_name, frames=10, width=640, height=480)
    seq, scene = load_sequence(spec), load_scene(scene_name)
    gate, missed, checked = spec.truth.gate_px, [], 0
    for k in range(len(seq)):
        clear = oracle_visible(scene, seq.rotations[k], seq.positions[k], seq.K)
        feats, uv = seq.features[k], seq.projections[k]
        if not len(feats):
            continue
        for j in np.flatnonzero(clear):
            d = np.linalg.norm(feats - uv[j], axis=1)
            near = int(d.argmin())
            others = np.linalg.norm(uv[clear] - feats[near], axis=1) <= gate
            if d[near] > gate or others.sum() > 1:
                continue
            checked += 1
            if seq.labels[k][near] != j:
                missed.append((k, seq.landmark_names[j], round(float(d[near]), 2)))
    assert checked >= 10 * 8
    assert not missed, f"unlabelled landmarks with a feature on them (frame, name, px): {missed[:10]}"


def test_depth_and_ray_occlusion_give_the_same_truth_on_oblique_walls():
    """The corridor's walls recede at up to ~89°: the rendered-depth test must not take a wall
    for its own occluder (the pixel next to an oblique landmark is already centimetres nearer)."""
    ray = load_sequence(SequenceSpec(scene="corridor", frames=6, width=320, height=240))
    depth = load_sequence(SequenceSpec(scene="corridor", frames=6, width=320, height=240,
                                       truth=TruthConfig(occlusion="depth")))
    assert ray.visible.sum() >= 6 * 20
    assert np.array_equal(ray.visible, depth.visible)
    assert all(np.array_equal(a, b) for a, b in zip(ray.labels, depth.labels))


@pytest.mark.parametrize("scene_name,index", [("room", 20), ("corridor", 0)])
def test_frame_summary_counts_nest(scene_name, index):
    """``frame``'s counts mean one thing: every labelled feature names a visible landmark, so
    "labelled" never exceeds "visible" (it said "12 landmarks visible ... 15 labelled")."""
    import re

    from assocbench.tracks.camera.truth_frame import render_truth_frame

    tf = render_truth_frame(SequenceSpec(scene=scene_name, frames=40), index)
    named = tf.labels[tf.labels >= 0]
    assert len(named) and tf.visible[named].all() and len(set(named)) == len(named)
    assert not (tf.visible & ~tf.in_view).any()
    said = re.match(r"(\d+) landmarks visible, (\d+) of them labelled \(detected\), (\d+) not detected; "
                    r"(\d+) more in view", tf.summary())
    assert said, tf.summary()
    n_vis, n_lab, n_missed, n_hidden = map(int, said.groups())
    assert (n_vis, n_lab, n_missed) == (tf.visible.sum(), len(named), tf.visible.sum() - len(named))
    assert n_vis + n_hidden == tf.in_view.sum()


def test_only_rendered_geoms_occlude(tmp_path):
    """A box in group 3 (a collision geom: the renderer does not draw it) stands before one
    landmark, a drawn box before another: the first landmark is imaged, so it is visible and
    labelled; the second is hidden."""
    spots = [(-0.3, 0.2), (0.0, 0.0), (0.3, 0.2), (-0.3, -0.2), (0.3, -0.2)]
    boxes = ('<geom type="box" pos="-0.225 -0.2 0.16" size="0.04 0.01 0.04" group="3" rgba="1 0 0 1"/>'
             '<geom type="box" pos="0.225 -0.2 0.16" size="0.04 0.01 0.04" rgba="1 0 0 1"/>')
    path = tmp_path / "occluders.xml"
    path.write_text(USER_MJCF.format(patches=boxes + "".join(user_patch(k, x, z) for k, (x, z) in enumerate(spots))))
    seq = load_sequence(SequenceSpec(scene=str(path), frames=3, width=320, height=240))
    behind_collision, behind_drawn = seq.landmark_names.index("lm0"), seq.landmark_names.index("lm2")
    assert seq.visible[:, behind_collision].all() and not seq.visible[:, behind_drawn].any()
    assert all(behind_collision in lab and behind_drawn not in lab for lab in seq.labels)
