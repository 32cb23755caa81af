"""The design's verdict: a few plain sentences on whether the design can be trusted, from the
``design.json`` report alone (issue 22 item 4; issue 34 item 3).

One function, ``verdict_lines``, shared by every place a design is shown (``ribbonctl design``,
``ribbonctl submit``, ``ribbonctl status JOB``, ``GET /jobs/{id}``'s ``verdict``, the dashboard), so
the operator reads the same words wherever they look. Pure: plain dicts in, strings out; it imports
nothing of the engine (the daemon reads it on every status).

What it says, in this order:

- the stretch bounds: kept everywhere, kept but for a few faces, or OUTSIDE them. One rule: OUTSIDE
  when the misfit is both widespread (more than ``PANEL_BAD_PCT`` of faces out by more than 1e-3, the
  share ``--panels`` allows a panel) and large (more than ``SLIGHT_DEVIATION``). A converged flattening's
  residual is not the solver's tolerance (a bowl 1.6 % out by 0.004 stays so at ``tolerance = 1e-9``),
  so a tighter tolerance is never promised; only a flattening stopped at its iteration cap is told
  that more iterations may lower it. The stretch bounds do not change with size: no size is advised;
- what ``--panels auto`` would make of it, in words that agree with the line above;
- ribbons whose thickness the curvature table clamped, with which end (too flat for the thinnest
  plastic, too curved for the thickest) and the size at which the fewest would clamp, when the report
  has them (a smaller surface is more curved: curvature goes as 1/size);
- ribbons dropped as too short or trimmed where they turned off the field;
- where the shape is lost: the flattening keeps N % of the target's ∫K, the layout realizes its
  metric within M %, the prediction keeps K %, and the step that loses the most is named;
- the prediction of the deployed shape, and, when the surface is OUTSIDE the bounds on more than
  ``BADLY_BROKEN_PCT`` of faces, that its small deviation is no sign of success: it releases the
  flattening as computed, stretches outside what the fabric can take included.
"""

from __future__ import annotations

from typing import Any

#: Stretches outside the bounds by less than this (0.3–0.5 % of a stretch of 1.0–1.5, an order below
#: what the printed plastic realizes, ``report.realization``) are a small misfit, whatever their share.
SLIGHT_DEVIATION = 0.005
#: Faces outside the bounds (by > 1e-3) beyond this share, %: the surface is OUTSIDE the bounds when
#: the deviation is not slight either. The share ``--panels`` allows each panel (project.MAX_BAD_PCT).
PANEL_BAD_PCT = 1.0
#: Bounds broken (beyond the tolerance) on more than this share of faces, %: "badly" broken, the
#: prediction then says nothing about success.
BADLY_BROKEN_PCT = 10.0
#: Ribbons clamped by the table beyond this share, %: a design the table does not cover.
MANY_CLAMPED_PCT = 20.0
#: A step "loses the shape" when its figure is this far, %, from keeping it all (100 % of ∫K, 0 % of
#: metric error); the largest such loss is named.
SHAPE_LOSS_PCT = 10.0
#: |∫K| of a target below this is nearly developable: ratios to it mean nothing (agreement.py's
#: REACHED_CURVATURE_ABS).
NEARLY_DEVELOPABLE = 0.1


def _misfit(report: dict[str, Any]) -> tuple[float, float]:
    """(% of faces outside the bounds by more than 1e-3, the largest deviation)."""
    bad = max(float(report.get("sigma1_bad_pct") or 0.0), float(report.get("sigma2_bad_pct") or 0.0))
    dev = max(float(report.get("sigma1_max_dev") or 0.0), float(report.get("sigma2_max_dev") or 0.0))
    return bad, dev


def outside_bounds(report: dict[str, Any]) -> bool:
    """The one rule: OUTSIDE the bounds when more than ``PANEL_BAD_PCT`` of faces are out and the
    deviation is more than ``SLIGHT_DEVIATION``."""
    bad, dev = _misfit(report)
    return bad > PANEL_BAD_PCT and dev > SLIGHT_DEVIATION


def _not_converged(report: dict[str, Any]) -> str:
    if report.get("converged") is False:
        return (f"; the flattening stopped at its iteration cap ({int(report.get('iterations') or 0)} "
                "iterations, not converged): more [solver] max_iterations may lower it")
    return ""


def bounds_line(report: dict[str, Any]) -> str:
    """One sentence on whether the flattening keeps to the stretch bounds."""
    bad, dev = _misfit(report)
    if bad == 0:
        return "within the stretch bounds everywhere (to 1e-3)"
    if not outside_bounds(report):
        where = "a few faces" if bad <= PANEL_BAD_PCT else "many faces"
        size = "small misfit" if dev <= SLIGHT_DEVIATION else "local misfit: the printed surface departs there"
        return (f"within the stretch bounds but for {bad:.2f} % of faces, outside by at most {dev:.4f} "
                f"({where}, a {size})" + _not_converged(report))
    return (f"OUTSIDE the stretch bounds on {bad:.1f} % of faces, by up to {dev:.3f}: the fabric cannot "
            "stretch as this surface needs there, so the printed surface will deviate (the bounds do not "
            "change with size: a shallower surface, or panels, would fit)" + _not_converged(report))


def badly_broken(report: dict[str, Any]) -> bool:
    """OUTSIDE the bounds (``outside_bounds``) on more than ``BADLY_BROKEN_PCT`` of faces."""
    return outside_bounds(report) and _misfit(report)[0] > BADLY_BROKEN_PCT


def _clamp_advice(ribbons: dict[str, Any], parameters: dict[str, Any], share: float) -> str:
    """What would make the clamped thicknesses fit, in brackets: the end they clamp at (a surface too
    flat for the thinnest plastic wants to be smaller, too curved for the thickest larger) and the
    report's ``thickness_fit``, the size at which the fewest clamp; without those fields no size is
    advised."""
    flat, curved = ribbons.get("thickness_clamped_flat"), ribbons.get("thickness_clamped_curved")
    fit = ribbons.get("thickness_fit")
    total = int(ribbons.get("front") or 0) + int(ribbons.get("back") or 0)
    ends = ""
    if flat is not None and curved is not None:
        others = int(ribbons.get("thickness_clamped") or 0) - int(flat) - int(curved)
        ends = ", ".join([f"{flat} flatter than the thinnest plastic curls", f"{curved} more curved than the thickest"]
                         + ([f"{others} at a spacing μ2 outside the table's"] if others > 0 else []))
    advice = ""
    if share > MANY_CLAMPED_PCT and fit is None:
        advice = "a curvature table measured over a wider range would fit"
    elif share > MANY_CLAMPED_PCT:
        scale, left = float(fit["scale"]), int(fit["clamped"])
        size = (parameters.get("size") or {}).get("bbox_diagonal")
        at = f"{scale * float(size):.0f} mm" if size else f"{scale:.2f}× this size"
        if left >= int(ribbons.get("thickness_clamped") or 0) or abs(scale - 1.0) < 0.05:
            advice = ("no size does better (curvature goes as 1/size): a curvature table measured over a "
                      "wider range would fit")
        else:
            advice = (f"a {'larger' if scale > 1.0 else 'smaller'} surface would fit better, curvature going "
                      f"as 1/size: at {at}, {left} of {total} would clamp (if the frame takes it); or a "
                      "curvature table measured over a wider range")
    inside = ": ".join(part for part in (ends, advice) if part)
    return f" ({inside})" if inside else ""


def _ribbon_lines(ribbons: dict[str, Any], parameters: dict[str, Any]) -> list[str]:
    total = int(ribbons.get("front") or 0) + int(ribbons.get("back") or 0)
    table = parameters.get("curvature_table", "?")
    lines = []
    clamped = int(ribbons.get("thickness_clamped") or 0)
    if clamped:
        share = 100.0 * clamped / total if total else 100.0
        lines.append(
            f"{clamped} of {total} ribbon thicknesses clamped to the range of table {table!r}: those "
            "ribbons will not curve as the design needs" + _clamp_advice(ribbons, parameters, share))
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
    """What ``--panels auto`` would make of a surface one sheet cannot (issue 26), in words that agree
    with ``bounds_line``: a small misfit is not told that one sheet cannot make it."""
    n = report.get("panels_suggested")
    if n is None:
        return []
    if n == 0:
        return ["not even the most panels --panels auto tries would each keep to the bounds: a shallower "
                "or smoother surface would"]
    search = ("(a quick search on a copy of at most 6,000 faces; on the whole mesh it may find fewer)")
    if not outside_bounds(report):
        return [f"one sheet will do with a misfit this small; to keep every face within the stretch bounds, "
                f"--panels auto would cut it into about {n} panels {search}"]
    return [f"one sheet cannot make it: --panels auto would cut it into about {n} panels, each within the "
            f"stretch bounds and the frame, to be sewn together {search}"]


def _ratio(part: float, whole: float) -> float | None:
    """100 part / whole, or None where the whole is nearly developable (the ratio means nothing)."""
    return 100.0 * part / whole if abs(whole) >= NEARLY_DEVELOPABLE else None


def _bounds_status(report: dict[str, Any]) -> str:
    bad, _ = _misfit(report)
    if bad == 0:
        return "within the bounds"
    if outside_bounds(report):
        return f"OUTSIDE the bounds on {bad:.1f} % of faces: the fabric cannot give all of it"
    return f"within the bounds but for {bad:.2f} % of faces"


def shape_chain(report: dict[str, Any]) -> list[tuple[str, str, float]]:
    """The steps from the target to the prediction, each as (step, what it keeps, its loss in %):
    the flattening (∫K of the intended metric against the target's), the layout (how far the printed
    ribbons realize that metric: the largest |median| of along and across; and, where the report has it,
    ∫K of the realized metric against the target's), the release (the predicted
    ∫K against the target's; its loss is what it loses beyond the flattening). A step is left out when
    the report lacks its field (older reports, no prediction); a nearly developable target (|∫K| <
    ``NEARLY_DEVELOPABLE``) is compared in ∫K, not in %, and its loss is not ranked."""
    real, deployed = report.get("realization") or {}, report.get("deployed") or {}
    steps: list[tuple[str, str, float]] = []
    k = real.get("total_gaussian_curvature")
    kept = _ratio(k["intended"], k["target"]) if k else None
    if k:
        what = (f"keeps {kept:.0f} % of the target's curvature" if kept is not None else
                f"gives ∫K {k['intended']:+.2f} for the target's {k['target']:+.2f}")
        steps.append(("the flattening", f"{what} ({_bounds_status(report)})",
                      abs(100.0 - kept) if kept is not None else 0.0))
    metric = [(name, real[key]) for name, key in (("along", "along_pct"), ("across", "across_pct")) if real.get(key)]
    if metric:
        name, q = max(metric, key=lambda item: abs(item[1]["median"]))
        held = _ratio(k["realized"], k["target"]) if k and k.get("realized") is not None else None
        held_text = f", a metric that keeps {held:.0f} % of the target's curvature" if held is not None else ""
        steps.append(("the layout", f"realizes its metric within {abs(q['median']):.1f} % ({name} the ribbons: "
                      f"median {q['median']:+.1f} %, p5–p95 {q['p5']:+.1f} to {q['p95']:+.1f} %{held_text})",
                      abs(q["median"])))
    kd = deployed.get("total_gaussian_curvature")
    if kd:
        predicted = _ratio(kd["predicted"], kd["target"])
        what = (f"keeps {predicted:.0f} %" if predicted is not None else
                f"gives ∫K {kd['predicted']:+.2f} for the target's {kd['target']:+.2f}")
        loss = abs((kept if kept is not None else 100.0) - predicted) if predicted is not None else 0.0
        steps.append(("the prediction", what, loss))
    return steps


_WHY = {
    "the flattening": "the stretch bounds cannot hold the target's curvature: a shallower surface, or panels",
    "the layout": "the ribbons as printed miss the metric the flattening asks for (spacing, dashes, bare fabric)",
    "the prediction": ("the metric is there, but the released sheet does not bend into the shape: the "
                       "ribbons' curvature (clamped thicknesses, the table) or a floppy sheet"),
}


#: The layout realizes its metric when the median along and across is within this, % (bench/realization.py)…
REALIZED_MEDIAN_PCT = 1.0
#: … and p5 and p95 within this, %: a few % of systematic metric error is most of what makes Gaussian curvature.
REALIZED_SPAN_PCT = 5.0


def _layout_misses(report: dict[str, Any]) -> float | None:
    """How far the layout misses its metric (the worst |median| or, past the span, |p5|, |p95|), or None
    when it realizes it within the tolerances above."""
    real = report.get("realization") or {}
    qs = [real[k] for k in ("along_pct", "across_pct") if real.get(k)]
    worst_median = max((abs(q["median"]) for q in qs), default=0.0)
    worst_span = max((max(abs(q["p5"]), abs(q["p95"])) for q in qs), default=0.0)
    if worst_median > REALIZED_MEDIAN_PCT or worst_span > REALIZED_SPAN_PCT:
        return worst_median
    return None


def _metric_curvature_loss(report: dict[str, Any]) -> float | None:
    """How much of the target's ∫K the realized metric loses against the intended one, points of %
    (None where the report lacks them or the target is nearly developable)."""
    k = (report.get("realization") or {}).get("total_gaussian_curvature")
    if not k or k.get("realized") is None:
        return None
    intended, realized = _ratio(k["intended"], k["target"]), _ratio(k["realized"], k["target"])
    return None if intended is None or realized is None else abs(intended - realized)


def _shape_line(report: dict[str, Any]) -> list[str]:
    """Where the shape is lost (issue 34): each step's figure, then the first step, in the order of the
    chain, that misses what it was asked (a step's loss comes after the ones before it: a layout that
    misses its metric by a few % loses the curvature the release then lacks)."""
    steps = shape_chain(report)
    if not steps:
        return []
    text = "where the shape is lost: " + "; ".join(f"{step} {what}" for step, what, _ in steps)
    if (report.get("deployed") or {}).get("reached"):
        # the prediction takes the shape: nothing to look at, but say what the layout still misses
        miss = _layout_misses(report)
        return [text + ". The prediction reaches the shape" + (
            f"; the layout still misses its own metric by {miss:.1f} % (the released sheet's bending and "
            "stretching make up the rest)" if miss is not None else "")]
    metric_loss = _metric_curvature_loss(report)
    for step, _, loss in steps:
        if step == "the layout" and _layout_misses(report) is not None:
            return [text + f". The step to look at: the layout (its metric off by {loss:.1f} %: {_WHY[step]})"]
        if step == "the layout" and metric_loss is not None and metric_loss > SHAPE_LOSS_PCT:
            return [text + f". The step to look at: the layout (its metric loses {metric_loss:.0f} % of the target's "
                    "curvature that the flattening's keeps, though its medians are within "
                    f"{REALIZED_MEDIAN_PCT:g} %: a metric's total curvature is decided along the outline "
                    "(Gauss–Bonnet), where the ribbons meet the cut)"]
        if step != "the layout" and loss > SHAPE_LOSS_PCT:
            lost = "the release" if step == "the prediction" else step
            return [text + f". The step to look at: {lost} ({loss:.0f} % lost there: {_WHY[step]})"]
    return [text + f". No step loses more than {SHAPE_LOSS_PCT:.0f} %"]


def verdict_lines(design: dict[str, Any]) -> list[str]:
    """The verdict of a design (``design.json`` as a dict: its ``report`` and ``parameters``), one
    sentence per line: the stretch bounds, panels, clamped thicknesses, ribbons dropped or trimmed,
    where the shape is lost, the prediction."""
    report = design.get("report") or {}
    parameters = design.get("parameters") or {}
    lines = [bounds_line(report)] + _panels_line(report)
    ribbons = report.get("ribbons")
    if ribbons:
        lines += _ribbon_lines(ribbons, parameters)
    return lines + _shape_line(report) + _prediction_line(report)


#: The sewn prediction lands within this mean deviation, % of the whole target's diagonal, for a
#: project to be told it takes the target's shape: the one sheet's rule (``agreement.REACHED_MEAN_PCT``,
#: kept equal by tests/design/test_verdict.py; not imported: this module imports nothing of the engine).
SEWN_REACHED_MEAN_PCT = 2.0


def _panel_reached(panel: dict[str, Any]) -> bool | None:
    """A panel's prediction takes its target's shape (``deployed.reached``; an older project.json:
    its verdict's words), None without a prediction."""
    deployed = panel.get("deployed") or {}
    if deployed.get("reached") is not None:
        return bool(deployed["reached"])
    text = deployed.get("verdict") or ""
    return True if text.startswith("will take") else False if text.startswith("will NOT") else None


def project_reached(project: dict[str, Any]) -> bool | None:
    """A project (``project.json`` as a dict) takes the target's shape: every panel's prediction
    does, and the panels as predicted and sewn land within ``SEWN_REACHED_MEAN_PCT`` of the whole
    target on average. None when it was compiled without predictions."""
    panels = [_panel_reached(q) for q in project.get("panels") or []]
    sewn = ((project.get("report") or {}).get("deployed") or {}).get("deviation_pct")
    if not panels or any(r is None for r in panels) or not sewn:
        return None
    return all(panels) and float(sewn["mean"]) <= SEWN_REACHED_MEAN_PCT


def project_verdict_lines(project: dict[str, Any]) -> list[str]:
    """The verdict of a project (``project.json`` as a dict), one sentence per line: reached or not,
    the panels predicted NOT to take their shape (each with its verdict), the sewn prediction's
    deviation. The same lines in ``ribbonctl design --panels``, ``ribbonctl submit --panels``, ``GET
    /projects/{id}`` (``verdict``) and the project page (issue 36 item 7)."""
    reached = project_reached(project)
    panels = project.get("panels") or []
    if reached is None:
        return ["reached: not known: compiled without a prediction of the deployed shape (whether the sewn "
                "panels take the target's shape is not predicted)"]
    missed = [q for q in panels if _panel_reached(q) is False]
    dev = project["report"]["deployed"]["deviation_pct"]
    sewn = (f"the {len(panels)} panels predicted and sewn land {float(dev['mean']):.2f} % of the diagonal from the "
            f"target on average (p99 {float(dev['p99']):.2f} %, max {float(dev['max']):.2f} %)")
    if reached:
        lines = [f"reached: yes: the sewn panels will take the target's shape: every panel will take its shape, "
                 f"and {sewn}"]
    else:
        why = [f"panel{'s' if len(missed) > 1 else ''} {', '.join(str(q['index']) for q in missed)} will NOT take "
               f"{'their' if len(missed) > 1 else 'its'} shape"] if missed else []
        if float(dev["mean"]) > SEWN_REACHED_MEAN_PCT:
            why.append(f"sewn, they land more than {SEWN_REACHED_MEAN_PCT:g} % from the target on average")
        lines = [f"reached: NO: the sewn panels will NOT take the target's shape: {'; '.join(why)}", sewn]
    lines += [f"panel {q['index']}: {(q.get('deployed') or {}).get('verdict')}" for q in missed
              if (q.get("deployed") or {}).get("verdict")]
    return lines
