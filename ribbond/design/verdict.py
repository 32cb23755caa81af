"""The design's verdict: a few plain sentences on whether the design can be trusted, from the
``design.json`` report alone (issue 22 item 4).

One function, ``verdict_lines``, shared by every place a design is shown (``ribbonctl design``,
``ribbonctl submit``, ``ribbonctl status JOB``, ``GET /jobs/{id}``'s ``verdict``, the dashboard), so
the operator reads the same words wherever they look. Pure: plain dicts in, strings out; it imports
nothing of the engine (the daemon reads it on every status).

What it says, in this order:

- the stretch bounds: kept everywhere, kept but for the solver's tolerance, or broken on a share
  of faces (then the printed surface departs from the target there: the fabric cannot stretch so);
- ribbons whose thickness the curvature table clamped (their curvature is not the one wanted);
- ribbons dropped as too short or trimmed where they turned off the field;
- the prediction of the deployed shape, and, when the bounds are badly broken, that its small
  deviation is no sign of success: it releases the flattening as computed, stretches outside what
  the fabric can take included.
"""

from __future__ import annotations

from typing import Any

#: Deviations from the bounds below this are the flattening's convergence tolerance, not a misfit
#: of the surface.
SLIGHT_DEVIATION = 0.005
#: Bounds broken (beyond the tolerance) on more than this share of faces, %: "badly" broken, the
#: prediction then says nothing about success.
BADLY_BROKEN_PCT = 10.0
#: Ribbons clamped by the table beyond this share, %: a design the table does not cover.
MANY_CLAMPED_PCT = 20.0


def bounds_line(report: dict[str, Any]) -> str:
    """One sentence on whether the flattening keeps to the stretch bounds."""
    bad = max(float(report.get("sigma1_bad_pct") or 0.0), float(report.get("sigma2_bad_pct") or 0.0))
    dev = max(float(report.get("sigma1_max_dev") or 0.0), float(report.get("sigma2_max_dev") or 0.0))
    if bad == 0:
        return "within the stretch bounds everywhere (to 1e-3)"
    if dev < SLIGHT_DEVIATION:
        return (f"within the stretch bounds but for {bad:.2f} % of faces, outside by at most {dev:.4f} "
                "(the solver's tolerance; a tighter [solver] tolerance removes it)")
    return (f"OUTSIDE the stretch bounds on {bad:.1f} % of faces, by up to {dev:.3f}: the fabric cannot "
            "stretch as this surface needs there, so the printed surface will deviate (a smaller or "
            "flatter surface, or cuts, would fit)")


def badly_broken(report: dict[str, Any]) -> bool:
    """The bounds are broken beyond the tolerance on more than ``BADLY_BROKEN_PCT`` of faces."""
    bad = max(float(report.get("sigma1_bad_pct") or 0.0), float(report.get("sigma2_bad_pct") or 0.0))
    dev = max(float(report.get("sigma1_max_dev") or 0.0), float(report.get("sigma2_max_dev") or 0.0))
    return dev >= SLIGHT_DEVIATION and bad > BADLY_BROKEN_PCT


def _ribbon_lines(ribbons: dict[str, Any], parameters: dict[str, Any]) -> list[str]:
    total = int(ribbons.get("front") or 0) + int(ribbons.get("back") or 0)
    table = parameters.get("curvature_table", "?")
    lines = []
    clamped = int(ribbons.get("thickness_clamped") or 0)
    if clamped:
        share = 100.0 * clamped / total if total else 100.0
        lines.append(
            f"{clamped} of {total} ribbon thicknesses clamped to the range of table {table!r}: those "
            "ribbons will not curve as the design needs"
            + (" (a table measured over a wider range, or a flatter surface, would fit)"
               if share > MANY_CLAMPED_PCT else ""))
    dropped, trimmed = int(ribbons.get("dropped_short") or 0), int(ribbons.get("trimmed_angle") or 0)
    if dropped or trimmed:
        parts = []
        if dropped:
            parts.append(f"{dropped} ribbon{'s' if dropped != 1 else ''} dropped (shorter than "
                         f"{float(parameters.get('min_ribbon_length', 0)):g} mm)")
        if trimmed:
            parts.append(f"{trimmed} trimmed (turned more than {float(parameters.get('max_trim_angle', 0)):g}° "
                         "off the field)")
        lines.append("; ".join(parts) + ": the surface is not driven there")
    return lines


def _prediction_line(report: dict[str, Any]) -> list[str]:
    deployed = report.get("deployed")
    if not deployed:
        return []
    dev = deployed["deviation_pct"]
    if deployed.get("verdict"):                       # format 3: released from the flat sheet, measured
        text = f"prediction ({deployed.get('model') or 'homogenized'} model): the layout {deployed['verdict']}"
    else:
        text = (f"prediction: the released layout deviates from the target by {dev['mean']:.1f} % of the "
                f"diagonal on average, {dev['max']:.1f} % at most")
    if badly_broken(report):
        text += ("; NOT a sign of success here: it releases the flattening as computed, stretches outside "
                 "what the fabric can take included, so with the bounds broken this badly the print will "
                 "not take the predicted shape")
    return [text]


def deployed_parts(deployed: dict[str, Any]) -> list[tuple[str, str]]:
    """The prediction's figures (``report.deployed`` as a dict, format 2 or 3) as (label, text): reached
    first, then the intrinsic measures, the spread, and the deviation last; fields an older report
    lacks are left out."""
    parts = []
    if deployed.get("reached") is not None:
        parts.append(("reached", "yes: it will take the target's shape" if deployed["reached"]
                      else "NO: it will NOT take the target's shape"))
    k = deployed.get("total_gaussian_curvature")
    if k:
        parts.append(("curvature", f"∫K {k['predicted']:+.2f} (total Gaussian curvature), target {k['target']:+.2f}"))
    if deployed.get("area_ratio") is not None:
        parts.append(("area", f"{100 * deployed['area_ratio']:.0f} % of the target's"))
    sp = deployed.get("spread")
    if sp:
        parts.append(("spread", f"over {sp['releases']} releases: mean deviation {sp['mean'][0]:.2f}–"
                                f"{sp['mean'][1]:.2f} %, max {sp['max'][0]:.2f}–{sp['max'][1]:.2f} %"))
    dev = deployed["deviation_pct"]
    parts.append(("deviation", f"mean {dev['mean']:.2f} %, p99 {dev['p99']:.2f} %, max {dev['max']:.2f} % of the "
                               "diagonal"))
    return parts


def deployed_figures(deployed: dict[str, Any]) -> str:
    """``deployed_parts`` on one line."""
    return "; ".join(f"{label} {text}" for label, text in deployed_parts(deployed))


def _panels_line(report: dict[str, Any]) -> list[str]:
    """What ``--panels auto`` would make of a surface one sheet cannot (issue 26)."""
    n = report.get("panels_suggested")
    if n is None:
        return []
    if n == 0:
        return ["not even the most panels --panels auto tries would each keep to the bounds: make the "
                "surface smaller or smoother"]
    return [f"one sheet cannot make it: --panels auto would cut it into about {n} panels, each within the "
            "stretch bounds and the frame, to be sewn together (a quick search on a copy of at most 6,000 "
            "faces; on the whole mesh it may find fewer)"]


def verdict_lines(design: dict[str, Any]) -> list[str]:
    """The verdict of a design (``design.json`` as a dict: its ``report`` and ``parameters``), one
    sentence per line: the stretch bounds, clamped thicknesses, ribbons dropped or trimmed, the
    prediction."""
    report = design.get("report") or {}
    parameters = design.get("parameters") or {}
    lines = [bounds_line(report)] + _panels_line(report)
    ribbons = report.get("ribbons")
    if ribbons:
        lines += _ribbon_lines(ribbons, parameters)
    return lines + _prediction_line(report)
