"""Cameras: the MuJoCo <-> Tsai conversion, and projection against rendered images.

The headline test renders small emissive spheres and checks that their image centroids
land where the camera read back from the compiled model projects them, within 0.1 px.
"""

from __future__ import annotations

import cv2
import mujoco
import numpy as np
import pytest

from calib.camera import TsaiCamera
from twin.sim.camera import (
    CV2MJ,
    opencv_from_principal_pixel,
    principal_pixel_from_opencv,
    tsai_from_model,
)
from twin.sim.render import CameraRenderer
from twin.sim.scene import build_spec
from twin.sim.world import build_world

from .helpers import SCENARIOS, scenario

ALL = sorted(p.stem for p in SCENARIOS.glob("*.toml"))


def test_principal_point_convention():
    # Measured: principal_pixel (0, 0) puts the principal point at OpenCV (W/2 - 0.5, H/2 - 0.5),
    # and a positive principal_pixel moves it left and up.
    assert principal_pixel_from_opencv(159.5, 119.5, (320, 240)) == (0.0, 0.0)
    assert principal_pixel_from_opencv(170.3, 109.1, (320, 240)) == pytest.approx((-10.8, 10.4))
    for cx, cy in [(0.0, 0.0), (170.3, 109.1), (312.7, 3.2)]:
        ppx, ppy = principal_pixel_from_opencv(cx, cy, (320, 240))
        assert opencv_from_principal_pixel(ppx, ppy, (320, 240)) == pytest.approx((cx, cy))
    np.testing.assert_array_equal(CV2MJ @ CV2MJ, np.eye(3))


@pytest.mark.parametrize("name", ALL)
def test_cameras_read_back_from_the_model_equal_the_scenario(name):
    world = build_world(scenario(name))
    for cfg in world.scenario.cameras:
        want = cfg.tsai()
        got = world.camera(cfg.name)
        np.testing.assert_allclose(got.position, want.position, atol=1e-9)
        np.testing.assert_allclose(got.world2cam_r, want.world2cam_r, atol=1e-7)
        assert got.f == pytest.approx(want.f, abs=1e-3)
        assert got.sx == pytest.approx(want.sx, abs=1e-6)
        assert (got.cx, got.cy) == pytest.approx((want.cx, want.cy), abs=1e-3)
        assert got.kappa1 == cfg.kappa1
        assert got.image_size == want.image_size


def sphere_image_centre(camera: TsaiCamera, centre_world, radius: float) -> np.ndarray:
    """Pixel of the centre of a sphere's image (an ellipse), exact for a pinhole camera.

    The rays tangent to a sphere with centre c (camera frame) and radius r form the cone
    p^T (c c^T - (|c|^2 - r^2) I) p = 0 in homogeneous image coordinates p = (x, y, 1);
    the centre of that conic is the centroid of the sphere's image.
    """
    c = camera.to_camera_frame(centre_world)[0]
    m = np.outer(c, c) - (c @ c - radius**2) * np.eye(3)
    xy = np.linalg.solve(m[:2, :2], -m[:2, 2])
    return np.array([camera.sx * camera.f * xy[0] + camera.cx, camera.f * xy[1] + camera.cy])


def _render_pair(model, data, camera: str) -> tuple[np.ndarray, np.ndarray]:
    """Images with geom group 1 (the test spheres) hidden and shown."""
    w, h = model.cam_resolution[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera)]
    out = []
    with mujoco.Renderer(model, height=int(h), width=int(w)) as r:
        for show in (0, 1):
            opt = mujoco.MjvOption()
            opt.geomgroup[:] = [1, show, 1, 0, 0, 0]
            opt.sitegroup[:] = 0
            r.update_scene(data, camera=camera, scene_option=opt)
            out.append(r.render().astype(float))
    return out[0], out[1]


def _coverage_centroids(off: np.ndarray, on: np.ndarray, n: int) -> np.ndarray:
    """Centroids (u, v) of the white spheres' coverage, from images without and with them.

    A pixel partly covered by a white (255) sphere reads a*255 + (1 - a)*background, so the
    coverage is a = (on - off) / (255 - off), whatever the background.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        a = np.where(off < 254.5, (on - off) / (255.0 - off), 0.0).mean(axis=2)
    a = np.clip(a, 0.0, 1.0)
    count, labels = cv2.connectedComponents((a > 0.02).astype(np.uint8))
    assert count - 1 == n, f"expected {n} blobs, found {count - 1}"
    v, u = np.mgrid[0 : a.shape[0], 0 : a.shape[1]]
    out = []
    for k in range(1, count):
        w = a * (labels == k)
        out.append([(w * u).sum() / w.sum(), (w * v).sum() / w.sum()])
    return np.array(out)


@pytest.mark.parametrize(
    ("name", "camera"), [("paper_hall", "cam2"), ("paper_hall", "cam3"), ("smoke", "cam1")]
)
def test_rendered_points_land_where_the_camera_projects_them(name, camera):
    sc = scenario(name)
    truth = sc.camera(camera).tsai()
    # Sphere centres spread over the image, 3-7 m in front of the camera and above the floor.
    pixels = np.array([[50.0, 40.0], [270.0, 45.0], [160.0, 120.0], [60.0, 200.0], [262.0, 196.0]])
    rays_c = np.column_stack([truth.pixels_to_normalized(pixels), np.ones(len(pixels))])
    rays_w = rays_c @ truth.world2cam_r  # per unit of depth
    with np.errstate(divide="ignore"):
        to_floor = np.where(
            rays_w[:, 2] < 0, (sc.space.floor_z - truth.position[2]) / rays_w[:, 2], np.inf
        )
    depths = np.minimum([6.0, 7.0, 5.5, 5.0, 6.5], 0.8 * to_floor)
    points = truth.position + rays_w * depths[:, None]
    radius = 0.045
    spec = build_spec(sc)
    spec.visual.quality.numslices = 96
    spec.visual.quality.numstacks = 48
    mat = spec.add_material(name="test_white", rgba=[1, 1, 1, 1])
    mat.emission = 1.0
    for k, p in enumerate(points):
        spec.worldbody.add_geom(
            name=f"test_sphere{k}",
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[radius, 0, 0],
            pos=p.tolist(),
            material="test_white",
            group=1,
            contype=0,
            conaffinity=0,
        )
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    cam = tsai_from_model(model, data, camera)  # intrinsics and pose read back
    off, on = _render_pair(model, data, camera)
    found = _coverage_centroids(off, on, len(points))
    expected = np.array([sphere_image_centre(cam, p, radius) for p in points])
    # The image of a sphere is centred almost, not exactly, on the projected centre.
    assert np.abs(expected - cam.project(points)).max() < 0.2
    for e in expected:
        d = np.linalg.norm(found - e, axis=1)
        assert d.min() < 0.1, f"nearest blob {d.min():.3f} px from {e}"


def test_leds_switch_and_appear_where_projected():
    world = build_world(scenario("paper_hall"))
    world.run(0.3)
    # MuJoCo renders a pinhole image: compare with the camera's projection without kappa1.
    cam = world.camera("cam1").with_(kappa1=0.0)
    _, leds = world.marker_points("child1")
    with CameraRenderer(world) as r:
        off = r.render("cam1").astype(float)
        world.sensing.set_leds("child1", True)
        assert world.sensing.leds_on("child1") == [True] * 4
        on = r.render("cam1").astype(float)
        world.sensing.set_leds("child1", [False, True, False, False])
        one = r.render("cam1").astype(float)
    diff = np.abs(on - off).sum(axis=2)
    assert diff.max() > 150
    # Every LED inside the image and in view shows up within 0.5 px of its projection.
    uv = cam.project(leds)
    visible = cam.in_image(uv) & np.array(
        [world.sensing.line_of_sight(cam.position, p, tolerance=0.03) for p in leds]
    )
    assert visible.sum() >= 2
    count, labels = cv2.connectedComponents((diff > 30).astype(np.uint8))
    v, u = np.mgrid[0 : diff.shape[0], 0 : diff.shape[1]]
    blobs = []
    for k in range(1, count):
        w = diff * (labels == k)
        blobs.append([(w * u).sum() / w.sum(), (w * v).sum() / w.sum()])
    blobs = np.array(blobs)
    for p in uv[visible]:
        assert np.linalg.norm(blobs - p, axis=1).min() < 0.5
    # One LED alone: only its blob remains.
    single = np.abs(one - off).sum(axis=2) > 30
    vv, uu = np.nonzero(single)
    assert np.hypot(uu.mean() - uv[1, 0], vv.mean() - uv[1, 1]) < 1.0
