"""A scene's digest covers every file it is made of, so an edit to an ``<include>``d body, a
texture, a mesh or a height field (beside the MJCF or in its ``<compiler>`` folders) re-renders
cached sequences and recomputes stored leaderboard runs (issue 26, items 11 and 12; issue 42)."""

import pytest

from assocbench.harness.suite import Cell, MethodEntry, Run
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


def test_a_stored_runs_key_follows_the_scenes_content_not_its_path(tmp_path):
    path = write_scene(tmp_path)
    run = lambda: Run(Cell(str(path), 0, "default", {"scene": str(path), "frames": 2}), MethodEntry("mnn", "mnn"))  # noqa: E731
    before = run().key
    assert run().key == before
    write_scene(tmp_path, x=1.1)
    assert run().key != before


FOLDERS = """<mujoco><compiler {compiler}/>
<asset><mesh name="rock" file="rock.obj"/><hfield name="ground" file="ground.png"/>
<texture name="paint" type="2d" file="paint.png"/>
<texture name="sky" type="cube" fileright="right.png" fileleft="left.png" fileup="up.png" filedown="down.png"
         filefront="front.png" fileback="back.png"/></asset>
<worldbody><site name="lm0" pos="1 0 1"/></worldbody></mujoco>"""
ASSETS = ("rock.obj", "ground.png", "paint.png", "right.png", "left.png", "up.png", "down.png", "front.png", "back.png")


@pytest.mark.parametrize("compiler, where", [
    ('meshdir="meshes" texturedir="textures"', {"rock.obj": "meshes", "ground.png": "meshes"}),
    ('assetdir="assets"', {}),
])
def test_the_digest_covers_files_in_the_compilers_folders(compiler, where, tmp_path):
    """A mesh or height field under ``meshdir``, a texture (and each face of a cube texture) under
    ``texturedir``, all under ``assetdir``: each edit changes the digest (they were not read)."""
    path = tmp_path / "scene" / "main.xml"
    path.parent.mkdir()
    path.write_text(FOLDERS.format(compiler=compiler))
    default = "assets" if "assetdir" in compiler else "textures"
    files = {name: path.parent / where.get(name, default) / name for name in ASSETS}
    for name, file in files.items():
        file.parent.mkdir(exist_ok=True)
        file.write_bytes(name.encode())
    assert set(scene_files(path)) == {path.resolve(), *(f.resolve() for f in files.values())}
    for name, file in files.items():
        before = scene_digest(path)
        file.write_bytes(b"edited " + name.encode())
        assert scene_digest(path) != before, name


def test_a_run_on_a_scene_whose_texture_changed_under_texturedir_has_another_key(tmp_path):
    """The issue's case: paint the landmark texture grey under texturedir; the run's source key
    (the sequence cache's) and its stored key change, so it is rendered again and recomputed."""
    scene = tmp_path / "painted.xml"
    (tmp_path / "textures").mkdir()
    texture = tmp_path / "textures" / "marks.png"
    texture.write_bytes(b"checkered")
    scene.write_text('<mujoco><compiler texturedir="textures"/><asset><texture name="m" type="2d" file="marks.png"/>'
                     '<material name="m" texture="m"/></asset><worldbody><geom type="box" size="1 1 1" material="m"/>'
                     '<site name="lm0" pos="1 0 1"/></worldbody></mujoco>')
    run = lambda: Run(Cell(str(scene), 0, "default", {"scene": str(scene), "frames": 2}), MethodEntry("mnn", "mnn"))  # noqa: E731
    before = run()
    source, key = before.spec.source.key, before.key
    texture.write_bytes(b"grey")
    after = run()
    assert after.spec.source.key != source and after.key != key
