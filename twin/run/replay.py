"""A run again from its log: results, camera files, figures and report, from the twin or
from real hardware, optionally with each visit calibrated again in another camera model.

Everything a run gives is computed from its log (:mod:`twin.campaign.log_results`), so a
log copied from the robots' computer, or the log of a run that was killed, gives the same
outputs here. With ``model="opencv"`` each calibration is fitted again, from the same LED
points and pixels, in OpenCV's model (fx, fy, cx, cy, k1, k2 and the pose).
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from calib import calibrate_opencv, calibrate_tsai
from calib.io.camera_files import camera_from_dict, camera_to_dict
from twin.campaign.adjusted_results import adjusted_results, adjustment_settings
from twin.campaign.log_results import META, point_arrays, results_from_log
from twin.campaign.network_log import CAMERA_MODES
from twin.campaign.records import CALIBRATION, POINT
from twin.outputs import claim_folder, write_text_atomic
from twin.record import McapRecorder, read_log
from twin.record.mcap_log import LogMessage
from twin.report import write_report
from twin.run.campaign_run import write_cameras
from twin.run.run_cameras import IDENTITY_KEYS
from twin.scenario import Scenario, load_scenario
from twin.scenario.digest import scenario_digest

MODELS = ("tsai", "opencv")

REPLAY_OUTPUTS = ("results.json", "cameras", "figures", "report.md")
"""What a replay writes in its folder."""

ASK_SCENARIO = (
    "give the run's scenario (twin replay --scenario FILE), or replay without the figures "
    "and report (--no-report)"
)


class ScenarioMismatch(ValueError):
    """The scenario given or found is not the one the log's run was made from."""


def replay_log(
    log: str | Path,
    out_dir: str | Path,
    *,
    model: str = "tsai",
    scenario: Scenario | str | Path | None = None,
    report: bool = True,
    overwrite: bool = False,
    adjust: str | None = "auto",
    force: bool = False,
    warn: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Compute a run's results again from its log and write them in ``out_dir``.

    Args:
        log: the run's ``log.mcap`` (whole, or cut short by a kill).
        out_dir: where ``results.json``, ``cameras/``, ``figures/`` and ``report.md`` go.
        model: ``tsai`` (the campaign's own calibrations, as logged) or ``opencv`` (each
            visit's points fitted again in OpenCV's model).
        scenario: the scenario for the report's figures (default: the file the log names,
            found as :func:`run_scenario_of` finds it).
        report: write the figures and ``report.md`` (needs the scenario).
        overwrite: replace what an earlier replay wrote in ``out_dir``.
        adjust: adjust the whole network (:mod:`twin.campaign.adjusted_results`), a camera
            visited twice being one camera (``shared``, as a run does) or one per visit
            (``per_visit``: tied through control points only); None: no adjustment;
            ``auto`` (default): ``shared`` in Tsai's model, none in OpenCV's. With
            the scenario, its pixel noise weighs the pixels; without, each camera's
            calibration residual does.
        force: use a scenario whose digest is not the one the log records.
        warn: called with what the caller should be told (a scenario that cannot be
            checked against the log).

    Returns:
        The results (also in ``results.json``).

    Raises:
        ValueError: an unknown model or adjustment, a log that holds no run or that another
            command than a campaign wrote (``twin check``), the report's scenario not found,
            or an adjustment asked for with ``model="opencv"`` (it adjusts Tsai's model).
        ScenarioMismatch: the scenario is not the run's (and not ``force``).
        twin.scenario.ScenarioError: the scenario cannot be read.
    """
    if model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
    if adjust == "auto":
        adjust = "shared" if model == "tsai" else None
    if adjust is not None and adjust not in CAMERA_MODES:
        raise ValueError(f"adjust must be one of {CAMERA_MODES} or None, got {adjust!r}")
    if adjust is not None and model != "tsai":
        raise ValueError(
            f"--adjust {adjust}: the adjustment works in Tsai's model, not OpenCV's; pass "
            "--model tsai (the default) to adjust, or --adjust none to refit in OpenCV's "
            "model (from Python: model='tsai', or adjust=None)"
        )
    contents = read_log(log)
    messages = list(contents.messages)
    meta = next((m.data for m in messages if m.topic == META), None)
    if meta is None:
        raise ValueError(f"{log}: no run in this log (no {META} record)")
    command = meta.get("command", "run")
    if command != "run":
        raise ValueError(
            f"{log}: a `twin {command}` log; twin replay reads the logs of campaigns "
            f"(twin run, with or without --rig)"
            + ("; the check's results are in check.json beside it" if command == "check" else "")
        )
    sc = None
    if report or scenario is not None:
        sc = run_scenario_of(meta, scenario, log, force=force, warn=warn)
    elif meta.get("scenario_file") or meta.get("scenario_path"):
        # The run's own pixel pitch (kappa1 in 1/mm^2), where its scenario can still be found.
        with contextlib.suppress(ValueError, OSError):
            sc = run_scenario_of(meta, None, log)
    if model != "tsai":
        messages = refit(messages, model)
    arguments = {"log": str(log), "model": model}
    folder = claim_folder(Path(out_dir), "replay", REPLAY_OUTPUTS, arguments, overwrite=overwrite)
    out = folder.path
    pixel_size = sc.campaign.pixel_size_mm if sc is not None else 0.015
    results = results_from_log(messages, pixel_size)
    if adjust is not None:
        settings = adjustment_settings(sc) if sc is not None else {"pixel_size_mm": pixel_size}
        results.update(adjusted_results(messages, cameras=adjust, **settings))
    results["replayed_from"] = str(log)
    results["model"] = model
    write_text_atomic(out / "results.json", json.dumps(results, indent=2, allow_nan=False) + "\n")
    # The run's scenario as its log records it (a log of an older run: its name alone).
    identity = {k: str(meta[k]) for k in IDENTITY_KEYS if meta.get(k)}
    write_cameras(results, messages, out / "cameras", identity)
    if report and sc is not None:
        write_report(sc, results, out)
    folder.finished(calibrations=len(results["calibrations"]))
    return results


def run_scenario_of(
    meta: dict[str, Any],
    scenario: Scenario | str | Path | None,
    log: str | Path,
    *,
    force: bool = False,
    warn: Callable[[str], None] | None = None,
) -> Scenario:
    """The scenario of the log's run, as it ran (with the seed and the noise the log's run
    record ``meta`` names).

    ``scenario`` (a scenario or its file) if given; else the file the run record names,
    looked for at its recorded absolute path, then (as given to the run) against the log's
    folder and against the working folder. Its digest
    (:func:`twin.scenario.digest.scenario_digest`) is checked against the one recorded; a
    log of an older version records none, and ``warn`` says so.

    Raises:
        ValueError: no scenario given and none found where the record says (the message
            says how to go on).
        ScenarioMismatch: the scenario's digest is not the recorded one, unless ``force``
            (then ``warn`` says so).
        twin.scenario.ScenarioError: the scenario cannot be read.
    """
    say = warn or (lambda _: None)
    recorded = meta.get("scenario_digest")
    run_name = meta.get("scenario") or "?"
    if scenario is not None:
        sc = _as_run(scenario if isinstance(scenario, Scenario) else load_scenario(scenario), meta)
        where = str(scenario) if not isinstance(scenario, Scenario) else sc.source or sc.name
        found = [(where, sc)]
    else:
        places = _scenario_places(meta, log)
        if not places:
            raise ValueError(f"{log}: the log names no scenario file; {ASK_SCENARIO}")
        found = [(str(p), _as_run(load_scenario(p), meta)) for p in places if p.is_file()]
        if not found:
            tried = ", ".join(str(p) for p in places)
            raise ValueError(
                f"{log}: its scenario {meta.get('scenario_file') or meta.get('scenario_path')} "
                f"was not found (looked for {tried}); {ASK_SCENARIO}"
            )
    if recorded is None:
        where, sc = found[0]
        say(
            f"{log} records no scenario digest (written by an older version): cannot check "
            f"that {where} is the run's scenario"
        )
        return sc
    for _, sc in found:
        if scenario_digest(sc) == recorded:
            return sc
    where, sc = found[0]
    differs = (
        f"the scenario {where} ({sc.name!r}, digest {scenario_digest(sc)}) is not the run's "
        f"({run_name!r} from {meta.get('scenario_file') or '?'}, digest {recorded})"
    )
    if force:
        say(f"{differs}; replayed with it all the same (--force)")
        return sc
    if scenario is None:
        raise ScenarioMismatch(
            f"{log}: {differs}: it changed since the run; {ASK_SCENARIO}, or pass --force to "
            "use it all the same"
        )
    raise ScenarioMismatch(f"{log}: {differs}; pass --force to use it all the same")


def _as_run(sc: Scenario, meta: dict[str, Any]) -> Scenario:
    """``sc`` with the seed and the noise the log's run record names (``twin run --seed``,
    ``run_scenario(noise=False)``)."""
    seed = meta.get("seed")
    if isinstance(seed, int) and not isinstance(seed, bool) and seed != sc.seed:
        sc = sc.model_copy(update={"seed": seed})
    if meta.get("noise") is False:
        sc = sc.without_noise()
    return sc


def _scenario_places(meta: dict[str, Any], log: str | Path) -> list[Path]:
    """Where the run's scenario may be: its recorded absolute path, then the file as given
    to the run against the log's folder and against the working folder (each once)."""
    places = []
    if meta.get("scenario_path"):
        places.append(Path(meta["scenario_path"]))
    given = meta.get("scenario_file")
    if given:
        given = Path(given)
        places += [given] if given.is_absolute() else [Path(log).parent / given, Path.cwd() / given]
    out: list[Path] = []
    seen: set[str] = set()
    for place in places:
        key = os.path.abspath(place)
        if key not in seen:
            seen.add(key)
            out.append(place)
    return out


def refit(messages: list[LogMessage], model: str) -> list[LogMessage]:
    """``messages`` with every calibration fitted again in ``model`` from its visit's
    points (the first ``points`` logged for that camera and visit, as the campaign used)."""
    fit = calibrate_opencv if model == "opencv" else calibrate_tsai
    points = [m.data for m in messages if m.topic == POINT and m.data["dataset"] == "visit"]
    out = []
    for m in messages:
        if m.topic != CALIBRATION:
            out.append(m)
            continue
        rec = m.data
        mine = [p for p in points if p["camera"] == rec["camera"] and p["visit"] == rec["visit"]]

        pts, pix, _ = point_arrays(mine)
        pts, pix = pts[: rec["points"]], pix[: rec["points"]]
        size = camera_from_dict(rec["camera_model"], "calibration").image_size
        result = fit(pts, pix, size)
        data = dict(rec)
        data.update(
            camera_model=camera_to_dict(result.camera),
            parameters=dict(result.parameters),
            std=dict(result.std_by_name),
            sigma_px=result.sigma_px,
        )
        out.append(dataclasses.replace(m, data=data))
    return out


FOXGLOVE_OPTION = "--foxglove"


def foxglove_log(
    log: str | Path,
    out: str | Path,
    *,
    scenario: Scenario | str | Path | None = None,
    force: bool = False,
    overwrite: bool = False,
    warn: Callable[[str], None] | None = None,
) -> dict[str, int]:
    """Write ``out``: the records of ``log`` and the Foxglove channels a run writes today
    (:mod:`twin.record.foxglove`), derived from them, for a log of any version.

    The site, the route and the stations come from the run's scenario (``scenario``, or
    the file the log names, as :func:`run_scenario_of` finds it); without one they are left
    out, and ``warn`` says so, as it says what else the log lacks (a real run's or an older
    log's: no truth, so no camera as built, no true instrument track and no robots' true
    frames).

    Returns:
        The Foxglove messages written, by topic.

    Raises:
        twin.outputs.OutputError: ``out`` cannot be written, is the log itself, or exists
            (and not ``overwrite``); nothing is written.
        ValueError: a log that holds no run. ScenarioMismatch: as :func:`run_scenario_of`.
    """
    from calib.io.atomic import atomic_file
    from twin.output_files import OutputError, check_file_target
    from twin.record.foxglove import FoxgloveStream
    from twin.record.foxglove.stream import TRUTH_CAMERA, TRUTH_INSTRUMENT, TRUTH_ROBOT

    say = warn or (lambda _: None)
    out = check_file_target(Path(out), FOXGLOVE_OPTION)
    if out.exists() and os.path.samefile(out, log):
        raise OutputError(f"{FOXGLOVE_OPTION} {out}: is the log itself; name another file")
    if out.exists() and not overwrite:
        raise OutputError(
            f"{FOXGLOVE_OPTION} {out}: exists; name a new file or pass --overwrite to replace it"
        )
    messages = read_log(log).messages
    meta = next((m.data for m in messages if m.topic == META), None)
    if meta is None:
        raise ValueError(f"{log}: no run in this log (no {META} record)")
    sc = None
    try:
        sc = run_scenario_of(meta, scenario, log, force=force, warn=warn)
    except ScenarioMismatch:
        raise
    except ValueError as exc:
        if scenario is not None:
            raise
        say(f"{exc}; the site, the route and the stations are left out of {out}")
    topics = {m.topic for m in messages}
    if TRUTH_CAMERA not in topics:
        say(f"{log} holds no cameras as built (/truth/camera): only the calibrated ones are drawn")
    if TRUTH_INSTRUMENT not in topics:
        say(f"{log} holds no instrument truth (/truth/instrument): no true track is drawn")
    if TRUTH_ROBOT not in topics:
        say(f"{log} holds no robots' true poses (/truth/robot): only their estimates are drawn")
    stream = FoxgloveStream(sc)
    with atomic_file(out) as tmp, McapRecorder(tmp, foxglove=stream) as recorder:
        for m in messages:
            recorder.record(m.topic, m.data, m.timestamp)
        counts = recorder.foxglove_counts
    return counts
