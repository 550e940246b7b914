"""What a batch's trials know, as arrays over all of them: the delivered calibration is, per
trial, the visit with the lowest predicted error of those that calibrated the camera, and
the free space is read along rays of a known map."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from twin.batch.estimators import ParentEstimates
from twin.envs.free_space import FreeSpace
from twin.envs.knowledge import BatchKnowledge, knowledge
from twin.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
HALL = ROOT / "scenarios" / "paper_hall.toml"


def _visit(calibrated, transfer, own, error):
    return SimpleNamespace(
        calibrated=np.array(calibrated),
        predicted_transfer=np.array(transfer, dtype=float),
        predicted_calibration=np.array(own, dtype=float),
        position_error=np.array(error, dtype=float),
    )


class _Cps:
    def __init__(self, parent):
        self.parent = parent

    def child_position(self, child):
        if child == "child1":
            return np.array([[1.0, 2.0, 0.0], [3.0, 4.0, 0.0], [5.0, 6.0, 0.0]]), np.zeros(
                (3, 3, 3)
            )
        raise ValueError("not measured yet")


def _batch(visits):
    t = 3
    parent = ParentEstimates(
        np.array([0.1, 0.2, 0.3]), np.zeros((t, 3)), np.tile(1e-6 * np.eye(4), (t, 1, 1))
    )
    believed = np.array([[7.0, 8.0, 0.5], [9.0, 10.0, 0.6], [11.0, 12.0, 0.7]])
    return SimpleNamespace(
        trials=t,
        cps=_Cps(parent),
        visits=visits,
        plan=SimpleNamespace(children=("child1", "child2")),
        robots={
            "child1": SimpleNamespace(believed=believed),
            "child2": SimpleNamespace(believed=believed),
        },
        last_estimate=parent,
        last_truth=np.array([[0.003, 0.004, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.012]]),
        distance=np.array([1.0, 2.0, 3.0]),
        executed=0,
    )


def test_the_delivered_calibration_is_each_trials_best_visit():
    visits = {
        # Trial 0: visit 2 predicts less. Trial 1: visit 1 failed there, visit 2 delivers.
        # Trial 2: a tie; the first visit's is delivered.
        ("cam1", 1): _visit(
            [True, False, True], [0.003, 0.001, 0.004], [0.004, 0.0, 0.003], [0.5, 0.6, 0.7]
        ),
        ("cam1", 2): _visit(
            [True, True, True], [0.0, 0.003, 0.003], [0.003, 0.004, 0.004], [0.1, 0.2, 0.3]
        ),
        ("cam2", 1): _visit(
            [False, False, True], [0.1, 0.1, 0.1], [0.2, 0.2, 0.2], [0.9, 0.9, 0.9]
        ),
    }
    known = knowledge(_batch(visits), ("cam1", "cam2", "cam3"), np.zeros((3, 3)))
    np.testing.assert_array_equal(
        known.calibrated, [[True, False, False], [True, False, False], [True, True, False]]
    )
    np.testing.assert_allclose(known.predicted[:, 0], [0.003, 0.005, 0.005])
    np.testing.assert_allclose(known.calibration[:, 0], [0.003, 0.004, 0.003])
    np.testing.assert_allclose(known.position_error[:, 0], [0.1, 0.2, 0.7])
    np.testing.assert_allclose(known.predicted[:, 1], [0.0, 0.0, math.hypot(0.1, 0.2)])
    assert np.isnan(known.position_error[:2, 1]).all()
    assert np.isnan(known.position_error[:, 2]).all()
    assert not known.predicted[:, 2].any()
    assert not known.calibration[:, 2].any()
    # A child measured by CPS reads its CPS position, the other its own estimate.
    np.testing.assert_array_equal(known.children[:, 0, :2], [[1, 2], [3, 4], [5, 6]])
    np.testing.assert_array_equal(known.children[:, 1], [[7, 8, 0.5], [9, 10, 0.6], [11, 12, 0.7]])
    np.testing.assert_allclose(known.parent_error, [0.005, 0.0, 0.012])
    # The parent 1 mm (sigma) off in x, y and z moves a camera at its centre by sqrt(3) mm.
    np.testing.assert_allclose(known.transfer_now, np.sqrt(3e-6), rtol=1e-12)


def test_knowledge_is_computed_again_only_after_a_step():
    batch = _batch({})
    shared = BatchKnowledge(batch, ("cam1",), np.zeros((1, 3)))
    first = shared.now()
    assert shared.now() is first
    batch.executed += 1
    assert shared.now() is not first


def test_free_space_rays_read_the_walls_and_obstacles():
    space = load_scenario(HALL).space
    free = FreeSpace(space)
    # From (10, 0) facing north: the north wall's face 13.4 m on, the south wall's 1.6 m
    # behind; facing east along y = 2: the island's west face at x = 20, 10 m on.
    poses = np.array([[10.0, 0.0], [10.0, 2.0]])
    rays = free.rays(poses, np.array([math.pi / 2, 0.0]))
    assert rays.shape == (2, 8)
    tolerance = free.resolution + 1e-9
    assert abs(rays[0, 0] - 13.4) <= tolerance
    assert abs(rays[0, 4] - 1.6) <= tolerance
    assert abs(rays[1, 0] - 10.0) <= tolerance
    for k in range(2):  # each pose alone reads the same
        np.testing.assert_array_equal(free.rays(poses[k], [[math.pi / 2, 0.0][k]])[0], rays[k])
