"""The sheet map: which coupon is which (front-side view of the frame, y up).

Each coupon's cut rectangle, its number, side, τ and μ2; the ribbons (front red, back blue), the
printed labels, crop marks, registration marks (numbered from 1) and the flip axis.
"""

from __future__ import annotations

import io
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .plan import CalibrationPlan, Sheet

_COLOR = {"front": "#c0392b", "back": "#2c5fad"}


def sheet_svg(plan: "CalibrationPlan", sheet: "Sheet") -> bytes:
    """The map of ``sheet`` as SVG (mm units, y up as seen from the front)."""
    from .plan import coupon_ribbons

    x0, y0, x1, y1 = plan.profile.frame.bounds
    pad = 12.0
    W, H = x1 - x0 + 2 * pad, y1 - y0 + 2 * pad

    def X(x: float) -> float:
        return x - x0 + pad

    def Y(y: float) -> float:
        return y1 - y + pad

    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W * 4:.0f}" height="{H * 4:.0f}" '
           f'viewBox="0 0 {W:.3f} {H:.3f}" font-family="sans-serif">',
           f'<rect x="0" y="0" width="{W:.3f}" height="{H:.3f}" fill="white"/>',
           f'<rect x="{pad}" y="{pad}" width="{x1 - x0:.3f}" height="{y1 - y0:.3f}" fill="none" stroke="#888" '
           'stroke-width="0.3"/>',
           f'<text x="{pad}" y="{pad - 4:.2f}" font-size="4">calibration sheet {sheet.number} of '
           f'{len(plan.sheets)} (front-side view): coupon number, side, τ mm, μ2 mm</text>']
    axis = plan.profile.frame
    if axis.flip_axis == "y":
        cx = axis.center[0]
        out.append(f'<line x1="{X(cx):.3f}" y1="{pad}" x2="{X(cx):.3f}" y2="{H - pad:.3f}" stroke="#999" '
                   'stroke-width="0.25" stroke-dasharray="2,2"/>')
    else:
        cy = axis.center[1]
        out.append(f'<line x1="{pad}" y1="{Y(cy):.3f}" x2="{W - pad:.3f}" y2="{Y(cy):.3f}" stroke="#999" '
                   'stroke-width="0.25" stroke-dasharray="2,2"/>')
    for c in sheet.coupons:
        col = _COLOR[c.side]
        out.append(f'<rect x="{X(c.x):.3f}" y="{Y(c.y + c.height):.3f}" width="{c.width:.3f}" '
                   f'height="{c.height:.3f}" fill="none" stroke="black" stroke-width="0.2" '
                   'stroke-dasharray="1,0.6"/>')
        for line in coupon_ribbons(plan.spec, c):
            out.append(f'<line x1="{X(line[0, 0]):.3f}" y1="{Y(line[0, 1]):.3f}" x2="{X(line[1, 0]):.3f}" '
                       f'y2="{Y(line[1, 1]):.3f}" stroke="{col}" stroke-width="{plan.spec.ribbon_width:g}" '
                       'stroke-opacity="0.55"/>')
        tx, ty = X(c.x + c.width / 2), Y(c.y + c.height / 2)
        out.append(f'<text x="{tx:.3f}" y="{ty:.3f}" font-size="5" text-anchor="middle" font-weight="bold">'
                   f'{c.number}</text>')
        out.append(f'<text x="{tx:.3f}" y="{ty + 4:.3f}" font-size="3" text-anchor="middle">{c.side} '
                   f'τ {c.thickness:g} μ2 {c.spacing:g}</text>')
    for side, strokes in sheet.labels.items():
        for s in strokes:
            out.append(f'<line x1="{X(s[0, 0]):.3f}" y1="{Y(s[0, 1]):.3f}" x2="{X(s[1, 0]):.3f}" '
                       f'y2="{Y(s[1, 1]):.3f}" stroke="black" stroke-width="0.4"/>')
    for s in sheet.cuts:
        out.append(f'<line x1="{X(s[0, 0]):.3f}" y1="{Y(s[0, 1]):.3f}" x2="{X(s[1, 0]):.3f}" '
                   f'y2="{Y(s[1, 1]):.3f}" stroke="black" stroke-width="0.3"/>')
    for k, (mx, my) in enumerate(sheet.design.registration_marks or [], start=1):
        out.append(f'<path d="M{X(mx) - 2:.3f},{Y(my):.3f}h4M{X(mx):.3f},{Y(my) - 2:.3f}v4" stroke="green" '
                   'stroke-width="0.5"/>')
        out.append(f'<text x="{X(mx) + 2.5:.3f}" y="{Y(my) - 2.5:.3f}" font-size="3" fill="green">{k}</text>')
    out.append("</svg>")
    return ("\n".join(out) + "\n").encode()


def sheet_png(plan: "CalibrationPlan", sheet: "Sheet") -> bytes:
    """The same map as a PNG (matplotlib, Agg)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    from .plan import coupon_ribbons

    x0, y0, x1, y1 = plan.profile.frame.bounds
    fig = Figure(figsize=(7, 7 * (y1 - y0) / (x1 - x0) + 0.4), dpi=110)
    ax = fig.add_subplot(1, 1, 1)
    ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, edgecolor="#888"))
    for c in sheet.coupons:
        ax.add_patch(Rectangle((c.x, c.y), c.width, c.height, fill=False, edgecolor="black", ls="--", lw=0.6))
        for line in coupon_ribbons(plan.spec, c):
            ax.plot(line[:, 0], line[:, 1], color=_COLOR[c.side], lw=1.2, alpha=0.6, solid_capstyle="butt")
        ax.text(c.x + c.width / 2, c.y + c.height / 2, f"{c.number}\n{c.side[0]} τ{c.thickness:g} μ{c.spacing:g}",
                ha="center", va="center", fontsize=6, weight="bold")
    for s in sheet.cuts + [q for strokes in sheet.labels.values() for q in strokes]:
        ax.plot(s[:, 0], s[:, 1], color="black", lw=0.6)
    for k, (mx, my) in enumerate(sheet.design.registration_marks or [], start=1):
        ax.plot([mx], [my], marker="+", color="green", ms=8)
        ax.annotate(str(k), (mx, my), xytext=(3, 3), textcoords="offset points", color="green", fontsize=7)
    ax.set_xlim(x0 - 2, x1 + 2)
    ax.set_ylim(y0 - 2, y1 + 2)
    ax.set_aspect("equal")
    ax.set_title(f"calibration sheet {sheet.number} of {len(plan.sheets)} (front-side view; red front, blue back)",
                 fontsize=8)
    ax.tick_params(labelsize=6)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()
