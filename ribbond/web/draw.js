// Drawings of a design (design.json: ribbons in fabric coordinates as seen from the front, and the
// registration marks): the layout with its numbered marks, and the flip (which way to turn the frame).

const NS = "http://www.w3.org/2000/svg";

function bounds(design, extraX = []) {
  const xs = [...extraX], ys = [];
  for (const r of design.ribbons || []) for (const [x, y] of r.points) { xs.push(x); ys.push(y); }
  for (const [x, y] of design.registration_marks || []) { xs.push(x); ys.push(y); }
  if (!xs.length || !ys.length) return [0, 0, 100, 100];
  return [Math.min(...xs), Math.min(...ys), Math.max(...xs), Math.max(...ys)];
}

const path = (pts, mirror) => pts.map(([x, y], i) => `${i ? "L" : "M"}${(mirror(x)).toFixed(2)} ${(-y).toFixed(2)}`).join("");

/** One panel: ribbons of ``sides`` (others faint), marks numbered; ``mirror`` maps x (the flip). */
function panel(design, { x0, y0, w, h, mirror, strong, faint, highlight, axis, title }) {
  const g = [], fs = Math.max(w, h) / 16;
  g.push(`<rect class="fabric" x="${x0}" y="${-(y0 + h)}" width="${w}" height="${h}" rx="3"/>`);
  for (const r of design.ribbons || []) {
    const cls = strong.includes(r.side) ? `rib ${r.side}` : (faint.includes(r.side) ? `rib faint` : null);
    if (cls) g.push(`<path class="${cls}" d="${path(r.points, mirror)}"/>`);
  }
  (design.registration_marks || []).forEach(([x, y], i) => {
    const k = i + 1, cx = mirror(x), cy = -y, on = highlight === k;
    g.push(`<g class="mark${on ? " current" : ""}" data-mark="${k}"><circle cx="${cx}" cy="${cy}" r="${(on ? 0.45 : 0.3) * fs}"/>` +
           `<text x="${cx + fs * 0.45}" y="${cy - fs * 0.35}" font-size="${fs}">${k}</text></g>`);
  });
  if (axis !== undefined) {
    g.push(`<line class="axis" x1="${axis}" x2="${axis}" y1="${-(y0 + h) - 6}" y2="${-y0 + 6}"/>`);
  }
  if (title) g.push(`<text class="title" x="${x0 + w / 2}" y="${-y0 + fs * 1.6}" font-size="${fs * 0.9}" text-anchor="middle">${title}</text>`);
  return g.join("");
}

/** The layout as seen from the front: front ribbons, back ribbons dashed, marks numbered. */
export function layoutSVG(design, highlight) {
  const [a, b, c, d] = bounds(design);
  const m = 10, x0 = a - m, y0 = b - m, w = c - a + 2 * m, h = d - b + 2 * m;
  const body = panel(design, { x0, y0, w, h, mirror: (x) => x, strong: ["front", "back"], faint: [], highlight });
  return `<svg xmlns="${NS}" class="drawing" viewBox="${x0 - 4} ${-(y0 + h) - 4} ${w + 16} ${h + 8}" role="img"
    aria-label="layout: front ribbons solid, back ribbons dashed, registration marks numbered">${body}</svg>`;
}

/** The flip: now (front up, the axis drawn) and after turning (the back ribbons, mirrored, and the marks). */
export function flipSVG(design, axisX, highlight) {
  const [a, b, c, d] = bounds(design, axisX === null ? [] : [axisX]);
  const ax = axisX === null ? (a + c) / 2 : axisX;
  // the fabric as the frame holds it: symmetric about the axis, so both panels have the same size
  const half = Math.max(ax - a, c - ax) + 12;
  const x0 = ax - half, w = 2 * half, y0 = b - 12, h = d - b + 24, gap = 36;
  const mirror = (x) => 2 * ax - x;
  const shift = w + gap;
  const left = panel(design, { x0, y0, w, h, mirror: (x) => x, strong: ["front"], faint: ["back"], axis: ax,
                               title: "now: front up" });
  const right = panel(design, { x0: x0 + shift, y0, w, h, mirror: (x) => mirror(x) + shift, strong: ["back"], faint: [],
                                highlight, axis: ax + shift, title: "after: back up" });
  const top = -(y0 + h), mid = -(y0 + h / 2);
  // the turn: an arrow over the axis, from one side to the other
  const arrow = `<path class="turn" d="M${ax - half * 0.5} ${top - 2} Q ${ax} ${top - 26} ${ax + half * 0.5} ${top - 2}" marker-end="url(#head)"/>` +
                `<path class="turn" d="M${x0 + w + 6} ${mid} L ${x0 + w + gap - 6} ${mid}" marker-end="url(#head)"/>`;
  return `<svg xmlns="${NS}" class="drawing flip" viewBox="${x0 - 4} ${top - 30} ${2 * w + gap + 12} ${h + 30 + (Math.max(w, h) / 16) * 2.2}" role="img"
    aria-label="turn the frame over about the dashed line; after the flip the back ribbons are mirrored">
    <defs><marker id="head" viewBox="0 0 10 10" refX="8" refY="5" markerWidth="5" markerHeight="5" orient="auto-start-reverse">
    <path d="M0 0 L10 5 L0 10 z" class="arrowhead"/></marker></defs>${left}${right}${arrow}</svg>`;
}

/** After the flip, seen from above: the back ribbons (mirrored) and the marks, mark ``highlight`` filled. */
export function backSVG(design, axisX, highlight) {
  const [a, b, c, d] = bounds(design, axisX === null ? [] : [axisX]);
  const ax = axisX === null ? (a + c) / 2 : axisX;
  const half = Math.max(ax - a, c - ax) + 12;
  const x0 = ax - half, w = 2 * half, y0 = b - 12, h = d - b + 24;
  const body = panel(design, { x0, y0, w, h, mirror: (x) => 2 * ax - x, strong: ["back"], faint: [], highlight, axis: ax });
  return `<svg xmlns="${NS}" class="drawing marks" viewBox="${x0 - 4} ${-(y0 + h) - 8} ${w + 8} ${h + 16}" role="img"
    aria-label="the frame back up: registration marks numbered, the current one filled">${body}</svg>`;
}
