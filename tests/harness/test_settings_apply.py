"""Settings that cannot apply to a run are refused, every value is checked whether the run uses
it or not, and the refusals come before anything compiles or renders (issue 26, items 5, 6, 16,
17); a closed loop's baseline without its ATE is refused (item 14); orphaned temporary files of a
killed writer are cleaned by the next write (item 18)."""

import os
import subprocess
import sys

import pytest

from assocbench.atomic import write_text
from assocbench.errors import UserError
from assocbench.harness.check import read_baseline
from assocbench.harness.config import load_run_config, run_spec
from assocbench.harness.suite import load_suite, resolve_suite


def spec(*sets: str, **flags):
    return run_spec(load_run_config(None, list(sets), **flags))


@pytest.mark.parametrize("sets, flags, needle", [
    (["lines.method=bogus"], {"scene": "park"}, "lines.method"),                          # unused section, bad value
    (["depth.downsample=0"], {"scene": "park"}, "depth.downsample"),
    (["icp.max_rms=.nan"], {"scene": "room"}, "icp.max_rms"),
    (["lines.min_points=5"], {"scene": "park"}, "lines.min_points is a setting of the lines track"),
    (["posts.min_points=5"], {"scene": "room"}, "posts.min_points is a setting of the planar track"),
    (["estimator.name=isam2"], {"scene": "park"}, "applies to the closed loop only"),
    (["lidar.sigma_bearing_deg=1e-300", "lidar.mode=geometric"], {"scene": "park"}, "lidar.sigma_bearing_deg"),
    (["depth.normal_smooth_px=1e-300"], {"scene": "crates", "method": "projective"}, "depth.normal_smooth_px"),
])
def test_settings_that_cannot_apply_or_are_bad_are_one_line_errors(sets, flags, needle):
    with pytest.raises(UserError) as err:
        spec(*sets, **flags)
    assert needle in str(err.value) and "\n" not in str(err.value)


def test_the_defaults_of_every_track_pass():
    for flags in ({"scene": "room"}, {"scene": "park"}, {"scene": "office"}, {"scene": "crates", "method": "kdtree"}):
        spec(**flags)


def test_isam2_without_gtsam_is_refused_before_any_compile(tmp_path):
    """A missing extra is found while the settings are checked, not after the kernels compile."""
    prelude = "import sys; sys.modules['gtsam'] = None; "   # as if the extra were not installed
    run = subprocess.run([sys.executable, "-c", prelude + "from assocbench.cli.main import main; "
                          "sys.exit(main(sys.argv[1:]))", "run", "--method", "jcbb", "--scene", "park", "--loop",
                          "--set", "estimator.name=isam2", "--out", str(tmp_path / "o")],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and "pip install 'assocbench[gtsam]'" in run.stderr, run.stderr
    assert "compiling" not in run.stderr and not (tmp_path / "o").exists()


def test_a_closed_loop_baseline_without_its_ate_is_refused(tmp_path):
    suite = load_suite(resolve_suite("loop_ci"))
    assert suite.loop and "ate_rmse" in [g.name for g in suite.guards()]
    bad = tmp_path / "baseline.csv"
    bad.write_text("scenario,method,precision,recall,f1,perfect\nroom/hard,jcbb,0.9,0.9,0.9,0.5\n")
    with pytest.raises(UserError) as err:
        read_baseline(bad, suite.guards(), suite.name)
    assert "lacks columns ate_rmse" in str(err.value)


def test_a_killed_writers_temporary_files_are_removed_by_the_next_write(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    pid = int(dead.stdout)                                   # a process that has exited
    orphan = tmp_path / f".summary.csv.{pid}.abc123.csv"
    orphan.write_text("half written")
    live = tmp_path / f".summary.csv.{os.getppid()}.def456.csv"   # a live writer's file stays
    live.write_text("in progress")
    write_text(tmp_path / "summary.csv", "done")
    assert (tmp_path / "summary.csv").read_text() == "done"
    assert not orphan.exists() and live.exists()


EXTREMES = [   # settings in their old ranges whose computation crashed the worker (exit 1, a traceback)
    ("belief.sigma_pixel=1e-300", ("room",), "belief.sigma_pixel must be a finite number in [1e-06, 10000.0]"),
    ("lidar.sigma_range=1e-300", ("park", "office"), "lidar.sigma_range must be a finite number in [1e-06, 10]"),
    ("belief.sigma_position=1e300", ("room", "park", "office"), "belief.sigma_position must be a finite number in [0, 1000.0]"),
    ("belief.sigma_landmark=1e300", ("room", "park"), "belief.sigma_landmark must be a finite number in [0, 1000.0]"),
    ("belief.sigma_common=1e300", ("room", "park"), "belief.sigma_common must be a finite number in [0, 1000.0]"),
    ("belief.miscalibration=1e300", ("room",), "belief.miscalibration must be a finite number in (0, 1000.0]"),
    ("belief.sigma_pixel=1e300", ("room",), "belief.sigma_pixel must be a finite number in [1e-06, 10000.0]"),
]


@pytest.mark.parametrize("setting, scene, needle", [(s, scene, n) for s, scenes, n in EXTREMES for scene in scenes])
def test_a_setting_whose_computation_cannot_hold_is_refused(setting, scene, needle):
    """Reproduction: `assocbench run --scene room --set belief.sigma_pixel=1e-300` (R = σ²I is 0,
    not positive definite), `--scene park|office --set lidar.sigma_range=1e-300` (the same),
    `--set belief.sigma_position=1e300` on every track (σ² overflows: OverflowError) crashed the
    worker with a traceback; so did sigma_landmark, sigma_common and miscalibration at 1e300
    (room: math domain error) and sigma_pixel at 1e300. The ranges now exclude them."""
    with pytest.raises(UserError) as err:
        spec(setting, scene=scene)
    assert needle in str(err.value) and "\n" not in str(err.value)


BOUNDS = ["belief.sigma_position=1000", "belief.sigma_landmark=1000", "belief.sigma_common=1000",
          "belief.miscalibration=1000"]
PIXEL_BOUNDS = ["belief.sigma_pixel=1e-6", "belief.sigma_pixel=1e4"]   # the camera's: the lidar beliefs have no pixels


@pytest.mark.parametrize("scene, setting, loop", [
    *[(scene, s, False) for scene in ("room", "park", "office") for s in BOUNDS],
    *[("room", s, False) for s in PIXEL_BOUNDS],
    *[(scene, "lidar.sigma_range=1e-6", loop) for scene in ("park", "office") for loop in (False, True)],
    ("room", "belief.sigma_pixel=1e-6", True),
    *[(scene, "belief.sigma_position=1000", True) for scene in ("room", "park", "office")],
])
def test_every_track_computes_at_the_ends_of_the_ranges(tmp_path, capsys, scene, setting, loop):
    """At the new bounds each run is measured: ok, or not ok with its reason (no candidates when the
    estimate is a kilometre off), never a crash."""
    from assocbench.cli.main import main

    code = main(["run", "--scene", scene, "--frames", "2", "--method", "mnn", "--set", setting,
                 "--out", str(tmp_path), "--format", "csv", *(["--loop"] if loop else [])])
    err = capsys.readouterr().err
    assert code in (0, 1) and "Traceback" not in err and "error:" not in err, err
    assert (tmp_path / "summary.csv").is_file()
