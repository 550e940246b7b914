"""The architecture, as the imports show it: the campaign talks only to the hardware
interface, never to a backend; its strategies see no device at all; the simulator does not
reach up into positioning or the campaign; the campaign does not read the twin's simulated
noise from the scenario. Every module of each package is checked, subpackages included."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
CAMPAIGN = ROOT / "twin" / "campaign"
SIM = ROOT / "twin" / "sim"
HAL = ROOT / "twin" / "hal"

BACKENDS = ("twin.sim", "twin.drivers", "twin.emulators", "mujoco")
CAMPAIGN_ALLOWED = (
    "twin.hal",
    "twin.localization",
    "twin.instruments",
    "twin.scenario",
    "twin.campaign",
    "twin.timing",
    "twin.truth",
    "twin.planning.route",  # shortest paths over shapely geometry, nothing of a backend
)
CAMPAIGN_FORBIDDEN = (*BACKENDS, "twin.run", "twin.record")
STRATEGY_MODULES = ("strategy.py", "paper_strategy.py", "strategies.py", "plan")
SIM_FORBIDDEN = ("twin.localization", "twin.campaign")
SIMULATED = ("noise", "faults", "sim")
"""A scenario's sections that belong to the twin, not to what the campaign knows."""


def _modules(package: Path) -> list[Path]:
    return sorted(package.rglob("*.py"))


def _imports(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.append(node.module)
    return names


def _attributes(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return {node.attr for node in ast.walk(tree) if isinstance(node, ast.Attribute)}


def _relative(path: Path) -> str:
    return str(path.relative_to(ROOT))


def test_every_campaign_module_is_checked():
    files = _modules(CAMPAIGN)
    assert len(files) >= 15
    assert any(p.parent.name == "plan" for p in files)


@pytest.mark.parametrize("path", _modules(CAMPAIGN), ids=_relative)
def test_campaign_modules_import_only_the_interface(path):
    for name in _imports(path):
        assert not name.startswith(CAMPAIGN_FORBIDDEN), f"{_relative(path)} imports {name}"
        if name.startswith("twin"):
            assert name.startswith(CAMPAIGN_ALLOWED), f"{_relative(path)} imports {name}"


@pytest.mark.parametrize("path", _modules(CAMPAIGN), ids=_relative)
def test_the_campaign_does_not_read_the_twins_noise(path):
    # What the campaign knows of its devices comes from the interface (the instrument's
    # range from rig.total_station.spec), not from the scenario's simulated noise.
    read = _attributes(path) & set(SIMULATED)
    assert not read, f"{_relative(path)} reads scenario.{sorted(read)}"


def _strategy_modules() -> list[Path]:
    out = []
    for name in STRATEGY_MODULES:
        target = CAMPAIGN / name
        out += _modules(target) if target.is_dir() else [target]
    return out


@pytest.mark.parametrize("path", _strategy_modules(), ids=_relative)
def test_strategies_see_no_device(path):
    for name in _imports(path):
        assert not name.startswith((*BACKENDS, "twin.hal")), f"{_relative(path)} imports {name}"


@pytest.mark.parametrize("path", _modules(SIM), ids=_relative)
def test_the_simulator_does_not_reach_up(path):
    for name in _imports(path):
        assert not name.startswith(SIM_FORBIDDEN), f"{_relative(path)} imports {name}"


@pytest.mark.parametrize("path", _modules(HAL), ids=_relative)
def test_the_interface_imports_no_backend(path):
    for name in _imports(path):
        assert not name.startswith(BACKENDS), f"{_relative(path)} imports {name}"


def test_importing_the_campaign_loads_no_backend():
    code = (
        "import sys, twin.campaign, twin.campaign.log_results, twin.campaign.strategies\n"
        "bad = [m for m in sys.modules if m.startswith(('mujoco', 'twin.sim', 'twin.drivers'))]\n"
        "print(bad)\n"
        "assert not bad, bad\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr


def test_the_checks_catch_what_they_guard(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text(
        "from twin.sim.world import World\nimport twin.localization.sequence\n"
        "from twin.hal.devices import TotalStation\nrange_ = scenario.noise.total_station\n"
    )
    names = _imports(bad)
    assert any(n.startswith(CAMPAIGN_FORBIDDEN) for n in names)
    assert any(n.startswith(SIM_FORBIDDEN) for n in names)
    assert any(n.startswith("twin.hal") for n in names)
    assert "noise" in _attributes(bad)


DRIVERS = ROOT / "twin" / "drivers"
SIMULATORS = ("twin.sim", "twin.emulators", "mujoco")


@pytest.mark.parametrize("path", _modules(DRIVERS), ids=_relative)
def test_the_drivers_need_no_simulator(path):
    # Real hardware runs without MuJoCo: a driver implements twin.hal and nothing else's.
    for name in _imports(path):
        assert not name.startswith(SIMULATORS), f"{_relative(path)} imports {name}"


def test_a_run_on_real_devices_loads_no_simulator():
    code = (
        "import sys, twin.run.hardware_run, twin.drivers.probe, twin.run.replay\n"
        "import twin.drivers.geocom\n"
        "import twin.drivers.arcos.base, twin.drivers.arcos.leds, twin.drivers.camera\n"
        "bad = [m for m in sys.modules if m.startswith(('mujoco', 'twin.sim', 'twin.emulators'))]\n"
        "print(bad)\n"
        "assert not bad, bad\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
