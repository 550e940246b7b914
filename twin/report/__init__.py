"""Figures and a Markdown report of a calibration campaign, beside the paper's results.

The input is a campaign's results, the content of its ``results.json`` (a dict; any field
may be missing in older or partial runs)::

    scenario, scenario_file, fidelity, seed, complete, wall_time_s, timings_s{stage: s},
    reference_sets[{camera, points}],
    calibrations[{camera, visit, station, distance_travelled_m, points,
                  parameters{f_px, cx, cy, sx, kappa1_px, kappa1_per_mm2, position_mm,
                             rotation_deg},
                  errors{world{pixel_mean, error_3d_mean_mm, points} | null,
                         local{pixel_mean, error_3d_mean_mm, points}},
                  truth{position_error_mm, rotation_error_deg},
                  residuals_px[[du, dv]], data_points_xy[[x, y]]}],
    skipped_visits[{camera, visit, station, reason, message}],
    repeatability_mm{camera: [dx, dy, dz]}, parent_final_error_mm,
    parent_track{estimated[[x, y]], true[[x, y]]}, failures{kind: count},
    events{kind: count} (the campaign's recoveries: a child turned, the parent stepped aside)

``visit`` counts the visits of one camera (1: its first calibration). The paper's
published numbers are in :mod:`twin.report.paper`, keyed the same way.

* :func:`write_report` writes ``report.md`` and ``figures/*.png`` into a folder;
* :func:`top_view`, :func:`error_vs_distance`, :func:`residuals` write one figure each.
"""

from twin.report import paper
from twin.report.figures import error_vs_distance, residuals, top_view
from twin.report.markdown import render_markdown, write_report

__all__ = [
    "error_vs_distance",
    "paper",
    "render_markdown",
    "residuals",
    "top_view",
    "write_report",
]
