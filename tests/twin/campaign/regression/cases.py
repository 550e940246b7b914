"""Stored results of the campaign, to show that a change of the code's shape leaves what
it computes as it was.

Each case is one run of a scenario (fidelity, seed, options); its ``results.json`` was
stored with the versions of the libraries that computed it. Regenerate them only when a
change of results is intended or a dependency upgrade changes them, and say which in the
commit:

    .venv/bin/python -m tests.twin.campaign.regression.cases

That replaces every store. Vectorised maths rounds differently on another processor, so a
store is kept per processor: on a new one, with the code's results unchanged (compare them
on a processor that has a store first), add its own with

    .venv/bin/python -m tests.twin.campaign.regression.cases --add-processor
"""

from __future__ import annotations

import json
import platform
import shutil
import sys
import tempfile
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[4]
STORED = Path(__file__).resolve().parent / "stored"

PACKAGES = ("numpy", "scipy", "mujoco", "opencv-python-headless", "pydantic")
"""The libraries whose versions decide the results bit for bit."""


@dataclass(frozen=True)
class Case:
    """One stored run: ``scenario`` (path from the repository's root), ``fidelity``,
    ``seed``, ``noise`` (False: every noise source off), ``faults`` (the scenario's
    ``[faults]`` replaced, as in the campaign's fault test)."""

    name: str
    scenario: str
    fidelity: str
    seed: int
    noise: bool = True
    faults: bool = False


CASES = (
    Case("smoke_geometric_1", "scenarios/smoke.toml", "geometric", 1),
    Case("smoke_geometric_2", "scenarios/smoke.toml", "geometric", 2),
    Case("smoke_geometric_3", "scenarios/smoke.toml", "geometric", 3),
    Case("smoke_geometric_faults_4", "scenarios/smoke.toml", "geometric", 4, faults=True),
    Case("hall_geometric_1", "scenarios/paper_hall.toml", "geometric", 1),
    Case("hall_geometric_32", "scenarios/paper_hall.toml", "geometric", 32),
    Case("hall_geometric_exact", "scenarios/paper_hall.toml", "geometric", 1, noise=False),
    Case("corridor_geometric_6", "scenarios/corridor.toml", "geometric", 6),
    Case("smoke_render_1", "scenarios/smoke.toml", "render", 1),
)


def environment() -> dict[str, str]:
    """What the stored results depend on besides the code: Python, the libraries, the
    machine's architecture and processor (vectorised maths and the software renderer may
    round differently on another)."""
    env = {"python": platform.python_version(), "machine": platform.machine(), "cpu": _cpu()}
    for name in PACKAGES:
        env[name] = metadata.version(name)
    return env


def _cpu() -> str:
    """The processor's model name and its widest vector extension, as Linux reports them
    ("" elsewhere)."""
    try:
        text = Path("/proc/cpuinfo").read_text(encoding="utf-8")
    except OSError:
        return ""
    fields: dict[str, str] = {}
    for line in text.splitlines():
        key, _, value = line.partition(":")
        fields.setdefault(key.strip(), value.strip())
    flags = set(fields.get("flags", "").split())
    widest = next((f for f in ("avx512f", "avx2", "sse4_2") if f in flags), "")
    return f"{fields.get('model name', '')} ({widest})"


def scenario_of(case: Case):
    """The case's scenario, with its faults where the case asks for them."""
    from twin.scenario import load_scenario

    sc = load_scenario(ROOT / case.scenario)
    return faulted(sc) if case.faults else sc


def faulted(sc):
    """The scenario with lost locks (10 %), hidden LEDs (5 %) and a second visit of its
    first camera from an unreachable station at (3, 0), on a straight route to x = 4 m."""
    faults = {"lost_lock_rate": 0.1, "hidden_led_rate": 0.05, "unreachable": ((3.0, 0.0),)}
    return sc.model_copy(
        update={
            "faults": sc.faults.model_copy(update=faults),
            "route": sc.route.model_copy(update={"waypoints": ((0.0, 0.0), (4.0, 0.0))}),
            "calibration": sc.calibration.model_copy(
                update={
                    "visits": (
                        sc.calibration.visits[0],
                        sc.calibration.visits[0].model_copy(update={"station": (3.0, 0.0)}),
                    )
                }
            ),
        }
    )


def run_case(case: Case, out_dir: Path) -> dict[str, Any]:
    """The case's results as ``results.json`` holds them (JSON types)."""
    from twin.run.runner import run_scenario

    results = run_scenario(
        scenario_of(case),
        out_dir,
        fidelity=case.fidelity,
        seed=case.seed,
        noise=case.noise,
        report=False,
        strategy="paper",
    )
    return json.loads(json.dumps(results, allow_nan=False))


PROCESSORS = STORED / "processors"
"""Stores of other processors than the main one's, a folder each."""


def _slug(cpu: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in cpu).strip("_") or "unknown"


def stored(case: Case) -> dict[str, Any]:
    """The stored record of a case (``environment`` and ``results``): the one made on this
    machine's processor if there is one, else the main store's."""
    main_path = STORED / f"{case.name}.json"
    here = _cpu()
    for path in [main_path, *sorted(PROCESSORS.glob(f"*/{case.name}.json"))]:
        if path.is_file():
            record = json.loads(path.read_text(encoding="utf-8"))
            if record["environment"].get("cpu") == here:
                return record
    return json.loads(main_path.read_text(encoding="utf-8"))


def main(args: list[str]) -> None:
    """Run the cases (all, or those named) and store their results: replacing every store,
    or with ``--add-processor`` as this processor's own store beside the others."""
    add = "--add-processor" in args
    names = [a for a in args if a != "--add-processor"]
    folder = PROCESSORS / _slug(_cpu()) if add else STORED
    if not add and not names and PROCESSORS.exists():
        shutil.rmtree(PROCESSORS)  # the other processors' stores are stale now
    folder.mkdir(parents=True, exist_ok=True)
    for case in CASES:
        if names and case.name not in names:
            continue
        with tempfile.TemporaryDirectory() as tmp:
            results = run_case(case, Path(tmp))
        record = {"case": case.__dict__, "environment": environment(), "results": results}
        path = folder / f"{case.name}.json"
        path.write_text(json.dumps(record, indent=1, allow_nan=False) + "\n", encoding="utf-8")
        print(f"{case.name}: {len(results['calibrations'])} calibrations -> {path}")


if __name__ == "__main__":
    main(sys.argv[1:])
