"""Every scenario composes into a world that steps quietly, with everything named."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from twin.scenario import scenario_from_dict
from twin.sim.world import build_world

from .helpers import SCENARIOS, scenario, unnamed

ALL = sorted(p.stem for p in SCENARIOS.glob("*.toml"))


def _names(model, kind, count, first=0):
    return [mujoco.mj_id2name(model, kind, i) for i in range(first, count)]


@pytest.mark.parametrize("name", ALL)
def test_scenario_builds_and_steps_one_second_without_warnings(name):
    world = build_world(scenario(name))
    world.run(1.0)
    assert world.time == pytest.approx(1.0)
    assert world.warnings() == {}
    m = world.model
    assert not unnamed(m)
    # Robots at rest on the floor, not colliding.
    assert world.driving.collisions == []
    for robot in world.scenario.robots.all:
        pose = world.robot_pose(robot.name)
        np.testing.assert_allclose(pose[:2], robot.start_xy, atol=1e-3)
        assert (
            np.linalg.norm(
                world.data.qvel[world.robots[robot.name].qvel : world.robots[robot.name].qvel + 3]
            )
            < 1e-3
        )


def test_names_and_prefixes():
    world = build_world(scenario("paper_hall"))
    m = world.model
    bodies = set(_names(m, mujoco.mjtObj.mjOBJ_BODY, m.nbody, 1))
    assert {"parent/base", "child1/base", "child2/base"} <= bodies
    sites = set(_names(m, mujoco.mjtObj.mjOBJ_SITE, m.nsite))
    assert {"parent/instrument", "parent/inclinometer", "child1/cube0", "child2/led3"} <= sites
    assert _names(m, mujoco.mjtObj.mjOBJ_CAMERA, m.ncam) == ["cam1", "cam2", "cam3"]
    geoms = set(_names(m, mujoco.mjtObj.mjOBJ_GEOM, m.ngeom))
    assert {
        "floor",
        "wall_north",
        "core_north",
        "island",
        "stairs_west/step00",
        "tilt_west",
    } <= geoms


def test_world_frame_is_the_instrument_frame_at_the_start():
    world = build_world(scenario("paper_hall"))
    world.run(0.5)
    pos, rot = world.instrument_pose()
    # The parent settles on its tyres by a fraction of a millimetre.
    np.testing.assert_allclose(pos, [0.0, 0.0, 0.0], atol=1e-3)
    np.testing.assert_allclose(rot, np.eye(3), atol=1e-4)


def test_lights_cast_no_shadows_unless_asked():
    world = build_world(scenario("paper_hall"))
    assert world.model.nlight > 0
    assert not world.model.light_castshadow.any()
    raw = scenario("smoke").model_dump(exclude={"source"})
    raw["space"]["lighting"]["shadows"] = True
    shadowed = build_world(scenario_from_dict(raw))
    assert shadowed.model.light_castshadow.all()


def test_marker_geometry_follows_the_scenario():
    raw = scenario("smoke").model_dump(exclude={"source"})
    cubes = [[0.12, 0.0, 1.6], [-0.08, 0.12, 1.6], [-0.08, -0.12, 1.6]]
    raw["marker"]["cubes"] = cubes
    world = build_world(scenario_from_dict(raw))
    world.run(0.2)
    got, _ = world.marker_points("child1")
    _, rot = world.body_pose("child1")
    pos = world.robot_pose("child1")
    body = (got - np.array([pos[0], pos[1], world.scenario.space.floor_z])) @ rot
    np.testing.assert_allclose(body, cubes, atol=2e-3)


def test_export_loads_on_its_own(tmp_path):
    world = build_world(scenario("paper_hall"))
    path = world.export(tmp_path / "scene" / "paper_hall.xml")
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert model.ngeom == world.model.ngeom
    assert model.ncam == world.model.ncam
    np.testing.assert_allclose(data.cam_xpos, world.data.cam_xpos)
    np.testing.assert_allclose(model.cam_intrinsic, world.model.cam_intrinsic)


def test_line_of_sight():
    world = build_world(scenario("paper_hall"))
    inst, _ = world.instrument_pose()
    cubes, _ = world.marker_points("child1")
    assert world.sensing.line_of_sight(inst, cubes[0], exclude_robot="parent")
    # The island and the core hide the far east end from the start.
    assert not world.sensing.line_of_sight(inst, [42.0, 5.0, 1.0], exclude_robot="parent")
    dist, geom = world.sensing.ray(inst, [1.0, 0.0, 0.0], exclude_robot="parent")
    assert geom == "wall_east"
    assert dist == pytest.approx(52.0, abs=1e-6)


def test_the_space_uses_only_reserved_names_for_its_own_geoms():
    # Scenario validation keeps obstacle and patch names off these (MuJoCo wants unique
    # geom names); the builder must not name anything else in the space.
    from twin.scenario.cross_checks import RESERVED_NAMES

    world = build_world(scenario("smoke"))
    space = world.scenario.space
    mine = {o.name for o in space.obstacles} | {p.name for p in space.floor_patches}
    names = {
        mujoco.mj_id2name(world.model, mujoco.mjtObj.mjOBJ_GEOM, g)
        for g in range(world.model.ngeom)
        if world.model.geom_bodyid[g] == 0
    }
    assert names - mine <= set(RESERVED_NAMES)
    assert set(RESERVED_NAMES) <= names


def test_a_ray_ignores_every_body_of_the_excluded_robot():
    world = build_world(scenario("smoke"))
    inst, _ = world.instrument_pose("parent")
    wheel = world.data.xpos[
        mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_BODY, "parent/front_left_wheel")
    ]
    direction = wheel - inst
    dist, geom = world.sensing.ray(inst, direction)
    assert geom.startswith("parent/")
    # Past the chassis and the wheel, down to the floor.
    dist, geom = world.sensing.ray(inst, direction, exclude_robot="parent")
    assert geom == "floor"
    unit = direction / np.linalg.norm(direction)
    assert dist == pytest.approx((world.scenario.space.floor_z - inst[2]) / unit[2], abs=1e-5)
