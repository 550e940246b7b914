"""The command line under fuzzing: every subcommand of ``twin.cli.main`` with arguments drawn
at the edges (0, -1, huge, 1e308, NaN, infinity, empty, not a number; paths to files, to
folders, to missing places, under a file) ends with an exit code (0, 1, 2 or 130, and a
command's own documented ones; argparse's refusal is SystemExit 2) and never with a
traceback: no exception but SystemExit leaves ``main``, and no "Traceback" is printed.

An argument list is valid (a fifth of the examples), valid but for one part drawn at the
edges (three fifths: one bad value in an otherwise good command is how a missed case shows),
or bad in every part it can be (a fifth). The commands stay cheap: campaigns in the smoke
room only, at the geometric fidelity where there is a choice, without the report;
``twin emulate`` for one second; counts (trials, episodes) of 1 or 2 when valid. Each
example runs in a fresh folder of its own, where its outputs go; the inputs a valid run
needs (a run's log and cameras, a check, a Monte-Carlo run, LED frames, a map, a rig file)
are made once for the module.

Not drawn, as they cost too much for the suite: ``twin strategies random`` (a site is built
per episode), ``twin montecarlo --engine ray`` and several ``--workers`` (processes started),
``--fidelity render`` of the campaigns, ``twin site`` without ``--no-predict``.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from twin.cli import main

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "scenarios" / "smoke.toml"

EXIT_CODES = (0, 1, 2, 130)

OWN_CODES = {"detect": (3,)}
"""Exit codes of a command's own, as its help says: ``twin detect``'s 3, no LED found."""

NUMBERS = ["0", "-0", "-1", "1e308", "-1e308", "nan", "inf", "-inf", "", "x", "1e-320", "0.5"]
"""Numbers at the edges, and what is not a number."""

HUGE_INTS = ["9223372036854775807", "9223372036854775808", "99999999999999999999"]

OUT_FILE = ["{W}/new/out{ext}", "{W}/a_file", "{W}/folder", "{W}/a_file/under{ext}", ""]
"""An output file: new, over a file, a folder, under a file, empty."""

OUT_FOLDER = ["{W}/new/out", "{W}/folder", "{W}/full", "{W}/a_file", "{W}/a_file/under", ""]
"""An output folder: new, empty, holding something else, a file, under a file, empty."""

BAD_INPUT = [
    "{W}/a_file",
    "{W}/folder",
    "{W}/missing.toml",
    "{W}/a_file/under.toml",
    "",
    "{W}/binary",
]
"""An input file that is not one: text of another kind, a folder, missing, under a file,
empty, bytes that are not text."""


def option(name: str, values: st.SearchStrategy[str]) -> st.SearchStrategy[list[str]]:
    """``[name, value]`` or nothing."""
    return st.one_of(st.just([]), values.map(lambda v: [name, v]))


def required(name: str, values: st.SearchStrategy[str]) -> st.SearchStrategy[list[str]]:
    """``[name, value]``."""
    return values.map(lambda v: [name, v])


def flag(name: str) -> st.SearchStrategy[list[str]]:
    return st.sampled_from([[], [name]])


def several(name: str, values: st.SearchStrategy[str], most: int) -> st.SearchStrategy[list[str]]:
    """``[name, value, value...]`` (1 to ``most`` values) or nothing."""
    return st.one_of(
        st.just([]), st.lists(values, min_size=1, max_size=most).map(lambda v: [name, *v])
    )


def command(*parts: st.SearchStrategy[list[str]]) -> st.SearchStrategy[list[str]]:
    """The argument list of the parts, in order."""
    return st.tuples(*parts).map(lambda lists: [a for part in lists for a in part])


def fixed(*args: str) -> st.SearchStrategy[list[str]]:
    return st.just(list(args))


def argv_parts(edges: bool) -> dict[str, tuple[st.SearchStrategy[list[str]], ...]]:
    """Each subcommand's arguments, part by part: valid values (``edges`` False), or values
    at the edges (bad ones; an option always given), where a part has such values. Both
    have the same parts in the same order."""

    def pick(good: list[str], *bad: list[str]) -> st.SearchStrategy[str]:
        edge = [v for b in bad for v in b]
        return st.sampled_from(edge if edges and edge else good)

    def opt(name: str, values: st.SearchStrategy[str]) -> st.SearchStrategy[list[str]]:
        return required(name, values) if edges else option(name, values)

    def many(name: str, values: st.SearchStrategy[str], most: int) -> st.SearchStrategy[list[str]]:
        if edges:
            return st.lists(values, min_size=1, max_size=most).map(lambda v: [name, *v])
        return several(name, values, most)

    def value(values: st.SearchStrategy[str]) -> st.SearchStrategy[list[str]]:
        return values.map(lambda v: [v])

    def out_file(ext: str, *more: str) -> st.SearchStrategy[str]:
        places = [p.replace("{ext}", ext) for p in OUT_FILE]
        return pick([places[0], *more], places[1:])

    out_folder = pick(OUT_FOLDER[:2], OUT_FOLDER[2:])
    scenario = pick(["{M}/smoke.toml"], BAD_INPUT)
    seed = pick(["0", "5", HUGE_INTS[0]], NUMBERS, HUGE_INTS[1:])
    count = pick(["1", "2"], NUMBERS, ["1.5"])
    strategy = pick(["paper", "planned"])
    return {
        "calibrate": (
            fixed("calibrate"),
            value(pick(["{M}/points.csv"], BAD_INPUT)),
            st.tuples(pick(["320"], NUMBERS, HUGE_INTS), pick(["240"], NUMBERS)).map(
                lambda wh: ["--image-size", *wh]
            ),
            opt("--units", pick(["m", "mm"], ["km"])),
            opt("--model", pick(["tsai", "opencv"])),
            flag("--tangential"),
            flag("--k3"),
            opt("--pixel-size", pick(["0.015"], NUMBERS)),
            opt("--out", out_file(".json", "{W}/x.yaml")),
            opt("--json", out_file(".json")),
            flag("--keep-duplicates"),
            opt("--mirror-axis", pick(["x", "y", "z"])),
            opt("--pixel-origin", pick(["top-left", "bottom-left"])),
            flag("--one-based"),
        ),
        "scene": (fixed("scene"), value(scenario), opt("--export", out_file(".xml"))),
        "render": (
            fixed("render"),
            value(scenario),
            required("--camera", pick(["cam1"], ["cam9", ""])),
            opt("--leds", pick(["on", "off"])),
            flag("--pinhole"),
            required("--out", out_file(".png")),
        ),
        "detect-images": (
            fixed("detect"),
            st.one_of(
                st.just([f"{{M}}/frames/frame_{k:02d}.png" for k in range(6)]),
                st.lists(pick(["{M}/frames/frame_00.png"], BAD_INPUT), min_size=1, max_size=3),
            )
            if edges
            else st.just([f"{{M}}/frames/frame_{k:02d}.png" for k in range(6)]),
            opt("--sequence", pick(["binary", "one-at-a-time"])),
            opt("--leds", pick(["4"], NUMBERS, HUGE_INTS, ["65", "1000"])),
            opt("--channel", pick(["gray", "red", "max"])),
            opt("--saturation", pick(["255"], NUMBERS)),
            (
                st.lists(st.sampled_from(NUMBERS), min_size=1, max_size=5).map(
                    lambda v: ["--led-line", *v]
                )
                if edges
                else st.sampled_from([[], ["--led-line", "0.1", "0.2", "0.3", "0.4"]])
            ),
            opt("--out", out_folder),
            flag("--overwrite"),
        ),
        "detect-twin": (
            fixed("detect"),
            required("--scenario", scenario),
            required("--camera", pick(["cam1"], ["", "cam9"])),
            opt("--child", pick(["child1", "child2"], ["parent", ""])),
            st.one_of(
                many("--at", pick(["1", "0"], NUMBERS), 3),
                opt("--distance", pick(["5", "3"], NUMBERS)),
            ),
            opt("--seed", seed),
            opt("--out", out_folder),
            flag("--overwrite"),
        ),
        "run": (
            fixed("run"),
            value(scenario),
            fixed("--no-report"),
            st.one_of(
                command(fixed("--fidelity", "geometric"), opt("--seed", seed), flag("--no-noise")),
                required("--rig", pick(["{M}/dead_rig.toml"], BAD_INPUT)),
            ),
            opt("--strategy", strategy),
            opt("--out", out_folder),
            flag("--overwrite"),
        ),
        "check": (
            fixed("check"),
            value(scenario),
            required("--cameras", pick(["{M}/run/cameras"], OUT_FOLDER)),
            st.one_of(
                command(fixed("--fidelity", "geometric"), opt("--seed", seed)),
                required("--rig", pick(["{M}/dead_rig.toml"], BAD_INPUT)),
            ),
            opt("--stops", pick(["2", "3"], NUMBERS, HUGE_INTS)),
            opt("--false-alarm-rate", pick(["0.001", "0.5"], NUMBERS)),
            opt("--min-pixel-sigma", pick(["0.05"], NUMBERS)),
            opt("--strategy", strategy),
            opt("--out", out_folder),
            flag("--overwrite"),
        ),
        "montecarlo": (
            fixed("montecarlo"),
            value(scenario),
            required("--trials", count),
            opt("--fidelity", pick(["batch", "geometric"])),
            flag("--adjust"),
            opt("--chunk-size", pick(["1", HUGE_INTS[0]], NUMBERS)),
            opt("--workers", pick(["1"], ["0", "-1", "x", "", "4097", "2147483648"], HUGE_INTS)),
            opt("--seed", seed),
            opt("--strategy", strategy),
            fixed("--no-budget"),
            opt("--out", pick(["{W}/mc", *OUT_FOLDER[:2]], OUT_FOLDER[2:])),
            st.sampled_from([[], ["--resume"], ["--overwrite"]]),
        ),
        "strategies": (
            fixed("strategies"),
            value(pick(["{M}/smoke.toml"], BAD_INPUT)),
            fixed("--policy"),
            value(pick(["paper", "random", "greedy"])),
            required("--episodes", count),
            opt("--seed", seed),
            opt("--budget", pick(["40"], NUMBERS)),
            opt("--planner", pick(["campaign", "stands"])),
            opt("--out", out_folder),
            flag("--overwrite"),
        ),
        "site": (
            fixed("site"),
            value(pick(["{M}/map.yaml"], BAD_INPUT)),
            fixed("--cameras"),
            value(pick(["{M}/cameras.yaml"], BAD_INPUT)),
            st.one_of(
                st.just([]),
                st.tuples(
                    pick(["1"], NUMBERS), pick(["4"], NUMBERS), pick(["0", "90"], NUMBERS)
                ).map(lambda xyz: ["--start", *xyz]),
            ),
            opt("--visits", pick(["cam1,cam2", "cam2"], ["", ",", "cam9", "cam1,,cam1"])),
            flag("--return-to-start"),
            opt("--resolution", pick(["0.1", "0.2"], NUMBERS)),
            opt("--ceiling-height", pick(["2.5", "4"], NUMBERS)),
            opt("--wall-layers", pick(["wall"], ["", "-x"])),
            opt("--data-stops", pick(["all_leds", "accuracy"])),
            opt("--name", pick(["room"], ["", "a/b"])),
            opt("--repairs", pick(["0", "3"], NUMBERS)),
            fixed("--no-predict"),
            required("--out", out_file(".toml")),
            flag("--overwrite"),
        ),
        "emulate": (
            fixed("emulate"),
            value(scenario),
            fixed("--fidelity", "geometric", "--duration", "1"),
            opt("--seed", seed),
            opt("--time-scale", pick(["10", "1000"], NUMBERS)),
            opt("--links", pick(["tcp", "pty"])),
            opt("--fps", pick(["30"], NUMBERS)),
            required("--rig-out", out_file(".toml", "{W}/r.yaml")),
        ),
        "devices": (
            fixed("devices"),
            value(pick(["{M}/dead_rig.toml"], BAD_INPUT)),
            flag("--no-blink"),
        ),
        "replay": (
            fixed("replay"),
            value(pick(["{M}/run/log.mcap"], ["{M}/check/log.mcap"], BAD_INPUT)),
            opt("--out", out_folder),
            opt("--model", pick(["tsai", "opencv"])),
            opt("--scenario", pick(["{M}/smoke.toml"], ["{M}/other.toml"], BAD_INPUT)),
            flag("--force"),
            opt("--adjust", pick(["shared", "per_visit", "none"])),
            fixed("--no-report"),
            flag("--overwrite"),
        ),
    }


def one_spoiled(
    valid: tuple[st.SearchStrategy[list[str]], ...], edges: tuple[st.SearchStrategy[list[str]], ...]
) -> st.SearchStrategy[list[str]]:
    """Valid arguments but one part, drawn at the edges: the likeliest way to meet a value a
    command misses (one bad value in an otherwise good command)."""
    pairs = list(zip(valid, edges, strict=True))
    spoilable = [k for k, (v, e) in enumerate(pairs) if repr(v) != repr(e)]
    return st.sampled_from(spoilable).flatmap(
        lambda i: command(*(e if k == i else v for k, (v, e) in enumerate(pairs)))
    )


_VALID, _EDGES = argv_parts(edges=False), argv_parts(edges=True)
ARGV = {
    name: st.sampled_from(["valid", "one", "one", "one", "any"]).flatmap(
        lambda how, name=name: {
            "valid": command(*_VALID[name]),
            "one": one_spoiled(_VALID[name], _EDGES[name]),
            "any": command(*_EDGES[name]),
        }[how]
    )
    for name in _VALID
}
"""Each subcommand's argument lists: valid (a fifth), valid but one part at the edges (three
fifths), or every part at the edges (a fifth); ``{M}`` (the module's inputs) and ``{W}`` (the
example's own folder) in the paths."""

EXAMPLES = {
    "calibrate": 80,
    "scene": 30,
    "render": 40,
    "detect-images": 40,
    "detect-twin": 15,
    "run": 16,
    "check": 40,
    "montecarlo": 10,
    "strategies": 12,
    "site": 40,
    "emulate": 10,
    "devices": 20,
    "replay": 60,
}
"""Examples per subcommand (hypothesis's max_examples)."""


def make_inputs(m: Path) -> Path:
    """The inputs a valid command needs, in ``m``: the smoke scenario and another one, a run
    of it (its log and cameras), a check of that run, a Monte-Carlo run, a points file, the
    frames of an LED sequence, a map with its cameras, and a rig file of the smoke room
    whose devices do not answer."""
    import tomli_w

    from tests.twin.planning.test_site import PILLAR, write_cameras, write_grid
    from twin.run.runner import check_scenario, run_scenario

    shutil.copy(SMOKE, m / "smoke.toml")
    (m / "other.toml").write_text(SMOKE.read_text().replace("f = 400.0", "f = 420.0"))
    shutil.copy(ROOT / "examples" / "camera1_points.csv", m / "points.csv")
    run_scenario(m / "smoke.toml", m / "run", fidelity="geometric", report=False)
    check_scenario(m / "smoke.toml", m / "run" / "cameras", m / "check", fidelity="geometric")
    write_grid(m, [PILLAR])
    write_cameras(m)
    scenario = str(m / "smoke.toml")
    main(["detect", "--scenario", scenario, "--camera", "cam1", "--out", str(m / "frames")])
    main(["montecarlo", scenario, "--trials", "1", "--no-budget", "--out", str(m / "mc")])
    nowhere = "socket://127.0.0.1:9"  # the discard port: refused at once
    rig = {
        "time_scale": 10.0,
        "total_station": {"port": nowhere, "timeout_s": 1.0},
        "robots": [
            {"name": "parent", "model": "p3at", "port": nowhere, "timeout_s": 1.0},
            *(
                {"name": c, "model": "p3dx", "port": nowhere, "led_bits": [0, 1, 2, 3]}
                for c in ("child1", "child2")
            ),
        ],
        "cameras": [{"name": "cam1", "source": "http://127.0.0.1:9/", "timeout_s": 1.0}],
    }
    (m / "dead_rig.toml").write_text(tomli_w.dumps(rig))
    return m


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> Path:
    return make_inputs(tmp_path_factory.mktemp("inputs"))


def world(folder: Path, inputs: Path) -> Path:
    """A fresh folder holding a file, an empty folder, a folder with something in it, a
    file of bytes that are not text, and a Monte-Carlo run (``mc``) to resume."""
    w = Path(tempfile.mkdtemp(dir=folder))
    shutil.copytree(inputs / "mc", w / "mc")
    (w / "a_file").write_text("the user's\n")
    (w / "folder").mkdir()
    (w / "full").mkdir()
    (w / "full" / "notes.txt").write_text("the user's\n")
    (w / "binary").write_bytes(b"\x00\xff\xfe not text")
    return w


def call(argv: list[str]) -> int:
    """``main(argv)``'s exit code; a SystemExit's code counts (argparse's refusal: 2)."""
    try:
        return main(argv)
    except SystemExit as exc:
        if exc.code is None:
            return 0
        return exc.code if isinstance(exc.code, int) else 1


@pytest.mark.parametrize("name", sorted(ARGV))
def test_every_command_ends_with_an_exit_code(name, inputs, tmp_path, capsys, monkeypatch):
    allowed = EXIT_CODES + OWN_CODES.get(name.split("-")[0], ())

    @settings(
        max_examples=EXAMPLES[name],
        deadline=None,
        suppress_health_check=[HealthCheck.too_slow],
        database=None,
    )
    @given(ARGV[name])
    def example(template: list[str]) -> None:
        w = world(tmp_path, inputs)
        monkeypatch.chdir(w)
        argv = [a.format(M=inputs, W=w) for a in template]
        code = call(argv)  # any exception but SystemExit fails the test with its argv
        said = capsys.readouterr()
        assert code in allowed, (argv, code, said.err[-2000:])
        assert "Traceback" not in said.out + said.err, (argv, said.err[-2000:])

    example()
