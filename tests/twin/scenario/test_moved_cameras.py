"""``[[faults.moved_cameras]]``: a camera the twin's world holds away from its scenario pose,
validated like every other key, and built where it was moved to."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calib.pose_change import pose_change
from twin.scenario import ScenarioError, load_scenario
from twin.sim.world import build_world

from .helpers import SCENARIOS, variant

CALIBRATION = 'visits = [{ camera = "cam1", station = [0.5, 0.0] }]'


def _moved(tmp_path, entries: str, name: str = "moved"):
    return variant(tmp_path, name, [(CALIBRATION, CALIBRATION + "\n\n" + entries)])


def test_a_moved_camera_is_built_at_its_moved_pose(tmp_path):
    path = _moved(
        tmp_path,
        '[[faults.moved_cameras]]\ncamera = "cam1"\nshift = [0.02, -0.01, 0.0]\n'
        "turn_deg = [0.0, 0.2, 0.0]\n",
    )
    sc = load_scenario(path)
    fault = sc.faults.moved_camera("cam1")
    assert fault is not None
    assert fault.turn_deg == (0.0, 0.2, 0.0)
    nominal = sc.camera("cam1").tsai()
    built = build_world(sc).camera("cam1")
    shift, turn = pose_change(nominal, built)
    # MuJoCo holds the camera's pose in single precision.
    assert_allclose(shift, [0.02, -0.01, 0.0], atol=1e-6)
    assert_allclose(np.degrees(turn), [0.0, 0.2, 0.0], atol=1e-5)


def test_a_camera_without_the_fault_is_where_the_scenario_puts_it():
    sc = load_scenario(SCENARIOS / "smoke.toml")
    assert sc.faults.moved_cameras == ()
    assert sc.faults.moved_camera("cam1") is None
    built = build_world(sc).camera("cam1")
    shift, turn = pose_change(sc.camera("cam1").tsai(), built)
    assert np.abs(shift).max() < 1e-6
    assert np.abs(turn).max() < 1e-6


def _issue(path, key):
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    err = info.value
    assert str(path) in str(err)
    keys = [i.key for i in err.issues]
    assert key in keys, keys
    return next(i for i in err.issues if i.key == key), str(err)


def test_an_unknown_camera_is_named_with_the_file(tmp_path):
    path = _moved(tmp_path, '[[faults.moved_cameras]]\ncamera = "cam9"\nshift = [0.02, 0, 0]\n')
    issue, text = _issue(path, "faults.moved_cameras[0].camera")
    assert issue.problem == "unknown camera"
    assert issue.value == "cam9"
    assert "cam1" in issue.expected
    assert "faults.moved_cameras[0].camera: unknown camera (got 'cam9')" in text


def test_a_camera_moved_twice_is_refused(tmp_path):
    one = '[[faults.moved_cameras]]\ncamera = "cam1"\nshift = [0.02, 0.0, 0.0]\n'
    issue, _ = _issue(_moved(tmp_path, one + "\n" + one), "faults.moved_cameras[1].camera")
    assert issue.problem == "camera moved twice"


def test_a_camera_moved_out_of_the_space_is_refused(tmp_path):
    path = _moved(tmp_path, '[[faults.moved_cameras]]\ncamera = "cam1"\nshift = [0.0, 0.0, 5.0]\n')
    issue, _ = _issue(path, "faults.moved_cameras[0].shift")
    assert "moves outside the space" in issue.problem


@pytest.mark.parametrize(
    ("entry", "key"),
    [
        ('camera = "cam1"\nturn_deg = [0.0, 200.0, 0.0]', "faults.moved_cameras[0].turn_deg[1]"),
        ('camera = "cam1"\nshift = [0.0, 0.0]', "faults.moved_cameras[0].shift[2]"),
        ('camera = "cam1"\nshfit = [0.0, 0.0, 0.1]', "faults.moved_cameras[0].shfit"),
    ],
)
def test_bad_values_are_named(tmp_path, entry, key):
    _issue(_moved(tmp_path, "[[faults.moved_cameras]]\n" + entry + "\n"), key)


def test_the_batch_fidelity_measures_a_moved_camera_against_where_it_stands(tmp_path):
    # 50 mm off its scenario pose: measured against the scenario pose, every trial would be
    # about 50 mm off; against the moved one, a few mm (the smoke room's RMS is about 3 mm).
    from twin.montecarlo import run_montecarlo

    path = _moved(tmp_path, '[[faults.moved_cameras]]\ncamera = "cam1"\nshift = [0.05, 0.0, 0.0]\n')
    mc = tmp_path / "mc"
    rows = run_montecarlo(
        load_scenario(path), mc, 40, fidelity="batch", master_seed=3, report=False
    )
    errors = np.array([r["position_error_mm"] for r in rows])
    assert len(errors) == 40
    assert np.median(errors) < 15.0
