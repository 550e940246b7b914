"""Build a simulated rig on a world: the one place where a fidelity is chosen."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from twin.hal.devices import MobileBase
from twin.hal.recording import Recorder
from twin.hal.rig import Rig
from twin.scenario.schema import Noise
from twin.sim.capture import CameraSimulator
from twin.sim.rig.base import GeometricBase, RenderBase
from twin.sim.rig.clock import SimClock
from twin.sim.rig.creep import CreepingChildren
from twin.sim.rig.frames import WorldFrame
from twin.sim.rig.leds import GeometricLedSensor, RenderLedSensor, SimCamera, SimLeds
from twin.sim.rig.shot_noise import ShotNoise
from twin.sim.rig.total_station import SimTotalStation
from twin.sim.rig.truth import TruthWitness, WitnessedBase, WitnessedParent
from twin.sim.world import World
from twin.timing import timed

FIDELITIES = ("render", "geometric")
"""``render``: robots driven in MuJoCo, rendered images, LEDs found by subtraction.
``geometric``: robots placed with a stopping error, LEDs projected with detection noise."""

SETTLE_TIME = 0.5
"""Simulated seconds the robots settle on their wheels before a run starts, s."""

RIG_STREAM = 3
"""Spawn key of the rig's random streams (the world uses 1, the camera sensors 2)."""

CREEP_STREAM = 6
"""Spawn key of the children's creep (:mod:`twin.sim.rig.creep`), apart from the rig's
streams so that switching it on changes no other draw."""


@dataclass
class SimRig:
    """A simulated rig and what only the simulation knows.

    Attributes:
        rig: the devices, as the campaign sees them.
        world: the MuJoCo world. frame: W in MuJoCo's frame (set at the parent's start).
        fidelity: ``render`` or ``geometric``.
        simulator: the camera renderer (render fidelity), closed with :meth:`close`.
    """

    rig: Rig
    world: World
    frame: WorldFrame
    fidelity: str
    simulator: CameraSimulator | None = None
    extra: dict[str, object] = field(default_factory=dict)

    def close(self) -> None:
        """Close the devices and the renderer."""
        self.rig.close()
        if self.simulator is not None:
            self.simulator.close()


def build_sim_rig(
    world: World,
    fidelity: str,
    seed: int | None = None,
    advertised: Noise | None = None,
    truth: Recorder | None = None,
) -> SimRig:
    """The devices of ``world``'s scenario at ``fidelity``.

    Args:
        world: a world at its start state (the parent's first station defines W).
        fidelity: ``render`` or ``geometric``.
        seed: root of the rig's random streams (default the scenario's seed). The instrument,
            each robot's stopping error, the LED detection and the injected faults have
            their own streams, so switching one off changes nothing else; the instrument's
            measurement noise is keyed to what each shot measures (:mod:`.shot_noise`), so
            that runs at both fidelities with one seed share it.
        advertised: the noise the instrument reports to the campaign (default: the
            scenario's, which it simulates).
        truth: where the simulation records its truth (:mod:`twin.truth`): the cameras and
            the instrument at the start, the instrument at every fix of the parent's pose.
    """
    if fidelity not in FIDELITIES:
        raise ValueError(f"fidelity must be one of {FIDELITIES}, got {fidelity!r}")
    sc = world.scenario
    root = sc.seed if seed is None else int(seed)
    names = [r.name for r in sc.robots.all]
    cams = [c.name for c in sc.cameras]
    streams = np.random.SeedSequence(root, spawn_key=(RIG_STREAM,)).spawn(
        3 + len(names) + len(cams)
    )
    rng = [np.random.default_rng(s) for s in streams]
    ts_rng, fault_rng, fault_led_rng = rng[0], rng[1], rng[2]
    base_rng = dict(zip(names, rng[3 : 3 + len(names)], strict=True))
    led_rng = dict(zip(cams, rng[3 + len(names) :], strict=True))

    parent = sc.robots.parent.name
    timings: dict[str, float] = {}
    # Let the robots come to rest on their wheels before the first station defines W.
    with timed(timings, "physics"):
        world.run(SETTLE_TIME)
    position, rotation = world.instrument_pose(parent)
    frame = WorldFrame.from_instrument(position, rotation)
    render = fidelity == "render"
    clock = SimClock(world, physics=render, timings=timings)
    faults = sc.faults
    total_station = SimTotalStation(
        world,
        parent,
        sc.noise.total_station.spec(),
        sc.noise.inclinometer.spec(),
        ts_rng,
        clock,
        lost_lock_rate=faults.lost_lock_rate,
        fault_rng=fault_rng,
        advertised=None
        if advertised is None
        else (advertised.total_station.spec(), advertised.inclinometer.spec()),
        shot_noise=ShotNoise(root, len(sc.robots.children) + len(sc.control_points)),
    )
    bases: dict[str, MobileBase] = {}
    for name in names:
        if render:
            bases[name] = RenderBase(world, name, frame, clock, timings, faults.unreachable)
        else:
            bases[name] = GeometricBase(
                world,
                name,
                frame,
                clock,
                sc.noise.stopping,
                base_rng[name],
                timings,
                faults.unreachable,
            )
    leds = {c.name: SimLeds(world, c.name, clock) for c in sc.robots.children}
    simulator = None
    cameras = {}
    sensors = {}
    led_line = [float(p[2]) for p in sc.marker.leds]
    if render:
        simulator = CameraSimulator(world, seed=root)
        for cam in cams:
            cameras[cam] = SimCamera(simulator, cam, clock, timings)
            sensors[cam] = RenderLedSensor(
                cameras[cam],
                leds,
                clock,
                timings,
                led_line,
                hidden_led_rate=faults.hidden_led_rate,
                fault_rng=fault_led_rng,
                centroid_px=sc.led_centroid_px(cam),
                centroid_rng=led_rng[cam],
            )
    else:
        for cam in cams:
            sensors[cam] = GeometricLedSensor(
                world,
                cam,
                clock,
                sc.projected_led_px(cam),
                led_rng[cam],
                hidden_led_rate=faults.hidden_led_rate,
                fault_rng=fault_led_rng,
            )
    if sc.noise.child_creep_m > 0:
        creep_rng = np.random.default_rng(np.random.SeedSequence(root, spawn_key=(CREEP_STREAM,)))
        bases[parent] = CreepingChildren(
            bases[parent],
            world,
            [c.name for c in sc.robots.children],
            sc.noise.child_creep_m,
            creep_rng,
        )
    if truth is not None:
        witness = TruthWitness(truth, world, frame, clock, parent)
        witness.cameras()
        witness.instrument()
        for name in bases:
            witness.robot(name)
            bases[name] = WitnessedBase(bases[name], witness)
        bases[parent] = WitnessedParent(bases[parent], witness)
    rig = Rig(
        clock=clock,
        total_station=total_station,
        parent=bases[parent],
        children={c.name: bases[c.name] for c in sc.robots.children},
        leds=leds,
        led_sensors=sensors,
        cameras=cameras,
        timings=timings,
    )
    return SimRig(rig=rig, world=world, frame=frame, fidelity=fidelity, simulator=simulator)
