"""A scene's digest covers every file it is made of, so an edit to an ``<include>``d body, a
texture or the main file re-renders cached sequences and recomputes stored leaderboard jobs
(issue 26, items 11 and 12)."""

from assocbench.harness.suite import Job, MethodEntry
from assocbench.sim.scene import scene_digest, scene_files

MAIN = """<mujoco><asset><texture name="t" type="2d" file="tex.png"/></asset>
<include file="body.xml"/></mujoco>"""
BODY = """<mujocoinclude><worldbody><site name="lm0" pos="{x} 0 1"/></worldbody></mujocoinclude>"""


def write_scene(folder, x=1.0):
    (folder / "main.xml").write_text(MAIN)
    (folder / "body.xml").write_text(BODY.format(x=x))
    (folder / "tex.png").write_bytes(b"not really a png")
    return folder / "main.xml"


def test_the_digest_covers_included_files_and_textures(tmp_path):
    path = write_scene(tmp_path)
    assert {f.name for f in scene_files(path)} == {"main.xml", "body.xml", "tex.png"}
    before = scene_digest(path)
    write_scene(tmp_path, x=1.1)                       # the included body moved 10 cm
    after = scene_digest(path)
    assert after != before
    (tmp_path / "tex.png").write_bytes(b"another texture")
    assert scene_digest(path) != after


def test_a_stored_jobs_key_follows_the_scenes_content_not_its_path(tmp_path):
    path = write_scene(tmp_path)
    job = lambda: Job(str(path), 0, (("default", {"frames": 2}),), (MethodEntry("mnn", "mnn"),))  # noqa: E731
    before = job().key
    assert job().key == before
    write_scene(tmp_path, x=1.1)
    assert job().key != before
