"""The campaign talks only to the hardware-abstraction interface: never to a backend."""

import ast
import subprocess
import sys
from pathlib import Path

import twin.campaign

CAMPAIGN = Path(twin.campaign.__file__).parent
ALLOWED = (
    "twin.hal",
    "twin.localization",
    "twin.instruments",
    "twin.scenario",
    "twin.campaign",
    "twin.timing",
    "twin.truth",
)
FORBIDDEN = ("twin.sim", "twin.drivers", "mujoco", "twin.runner", "twin.record")


def _imports(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.append(node.module)
    return names


def test_campaign_modules_import_no_backend():
    files = sorted(CAMPAIGN.glob("*.py"))
    assert len(files) >= 5
    for path in files:
        for name in _imports(path):
            assert not name.startswith(FORBIDDEN), f"{path.name} imports {name}"
            if name.startswith("twin"):
                assert name.startswith(ALLOWED), f"{path.name} imports {name}"


def test_importing_the_campaign_loads_no_backend():
    code = (
        "import sys, twin.campaign, twin.campaign.log_results\n"
        "bad = [m for m in sys.modules if m.startswith(('mujoco', 'twin.sim', 'twin.drivers'))]\n"
        "print(bad)\n"
        "assert not bad, bad\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr


def test_the_checker_catches_a_backend_import(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("from twin.sim.world import World\nimport numpy\n")
    assert any(n.startswith(FORBIDDEN) for n in _imports(bad))
