// Drawings of a design (design.json: ribbons in fabric coordinates as seen from the front, and the
// registration marks): the layout with its numbered marks, the flip (which way to turn the frame)
// and the frame back up with the mark the head is above. The flip axis is a line x = c (a turn about
// the frame's y axis) or y = c (about its x axis); ``flip`` is {line: "x" | "y", c}, or null (unknown:
// the design's centre, x).

const NS = "http://www.w3.org/2000/svg";

function extent(design) {
  const xs = [], ys = [];
  for (const r of design.ribbons || []) for (const [x, y] of r.points) { xs.push(x); ys.push(y); }
  for (const [x, y] of design.registration_marks || []) { xs.push(x); ys.push(y); }
  if (!xs.length) return [0, 0, 100, 100];
  return [Math.min(...xs), Math.min(...ys), Math.max(...xs), Math.max(...ys)];
}

/** The fabric's rectangle: the design with a margin, symmetric about the flip line. */
function fabric(design, flip) {
  let [a, b, c, d] = extent(design);
  const f = flip || { line: "x", c: (a + c) / 2 };
  if (f.line === "x") { const h = Math.max(f.c - a, c - f.c); a = f.c - h; c = f.c + h; }
  else { const h = Math.max(f.c - b, d - f.c); b = f.c - h; d = f.c + h; }
  const m = 12;
  return { f, x0: a - m, y0: b - m, w: c - a + 2 * m, h: d - b + 2 * m };
}

const mirrorOf = (f) => (f.line === "x" ? ([x, y]) => [2 * f.c - x, y] : ([x, y]) => [x, 2 * f.c - y]);
const same = (p) => p;

/** One panel (SVG y down: machine y is negated), shifted right by ``dx``. */
function panel(design, { box, map, strong, faint, highlight, axis, title, dx = 0 }) {
  const { x0, y0, w, h } = box;
  const fs = Math.max(w, h) / 16;
  const P = (p) => { const [x, y] = map(p); return [x + dx, -y]; };
  const g = [`<rect class="fabric" x="${x0 + dx}" y="${-(y0 + h)}" width="${w}" height="${h}" rx="3"/>`];
  for (const r of design.ribbons || []) {
    const cls = strong.includes(r.side) ? `rib ${r.side}` : (faint.includes(r.side) ? "rib faint" : null);
    if (!cls) continue;
    const d = r.points.map((p, i) => { const [x, y] = P(p); return `${i ? "L" : "M"}${x.toFixed(2)} ${y.toFixed(2)}`; }).join("");
    g.push(`<path class="${cls}" d="${d}"/>`);
  }
  (design.registration_marks || []).forEach((p, i) => {
    const k = i + 1, [cx, cy] = P(p), on = highlight === k;
    g.push(`<g class="mark${on ? " current" : ""}" data-mark="${k}"><circle cx="${cx}" cy="${cy}" r="${(on ? 0.45 : 0.3) * fs}"/>` +
           `<text x="${cx + fs * 0.45}" y="${cy - fs * 0.35}" font-size="${fs}">${k}</text></g>`);
  });
  if (axis) {
    const e = 6;
    g.push(axis.line === "x"
      ? `<line class="axis" x1="${axis.c + dx}" x2="${axis.c + dx}" y1="${-(y0 + h) - e}" y2="${-y0 + e}"/>`
      : `<line class="axis" x1="${x0 + dx - e}" x2="${x0 + dx + w + e}" y1="${-axis.c}" y2="${-axis.c}"/>`);
  }
  if (title) g.push(`<text class="title" x="${x0 + dx + w / 2}" y="${-y0 + fs * 1.6}" font-size="${fs * 0.9}" text-anchor="middle">${title}</text>`);
  return g.join("");
}

/** The layout as seen from the front: front ribbons solid, back ribbons dashed, marks numbered. */
export function layoutSVG(design) {
  const box = fabric(design, null);
  const [a, b, c, d] = extent(design);
  Object.assign(box, { x0: a - 10, y0: b - 10, w: c - a + 20, h: d - b + 20 });
  const body = panel(design, { box, map: same, strong: ["front", "back"], faint: [] });
  return `<svg xmlns="${NS}" class="drawing layout" viewBox="${box.x0 - 4} ${-(box.y0 + box.h) - 4} ${box.w + 16} ${box.h + 8}" role="img"
    aria-label="layout: front ribbons solid, back ribbons dashed, registration marks numbered">${body}</svg>`;
}

/** The flip: now (front up, the flip line drawn, a turn arrow across it) and after (the back up:
 * its ribbons and the marks mirrored about the line). */
export function flipSVG(design, flip, highlight) {
  const box = fabric(design, flip);
  const { f, x0, y0, w, h } = box;
  const gap = 36, shift = w + gap, fs = Math.max(w, h) / 16;
  const left = panel(design, { box, map: same, strong: ["front"], faint: ["back"], axis: f, title: "now: front up" });
  const right = panel(design, { box, map: mirrorOf(f), strong: ["back"], faint: [], highlight, axis: f, dx: shift,
                                title: "after: back up" });
  const top = -(y0 + h), mid = -(y0 + h / 2);
  // the turn: an arc across the flip line (over the top for a line x = c, beside it for y = c)
  const turn = f.line === "x"
    ? `M${f.c - w * 0.25} ${top - 2} Q ${f.c} ${top - 26} ${f.c + w * 0.25} ${top - 2}`
    : `M${x0 - 2} ${-f.c + h * 0.25} Q ${x0 - 22} ${-f.c} ${x0 - 2} ${-f.c - h * 0.25}`;
  const arrows = `<path class="turn" d="${turn}" marker-end="url(#head)"/>` +
                 `<path class="turn" d="M${x0 + w + 6} ${mid} L ${x0 + w + gap - 6} ${mid}" marker-end="url(#head)"/>`;
  const left0 = x0 - (f.line === "y" ? 26 : 4);
  return `<svg xmlns="${NS}" class="drawing flip" viewBox="${left0} ${top - 30} ${2 * w + gap + (x0 - left0) + 8} ${h + 30 + fs * 2.2}" role="img"
    aria-label="turn the frame over about the dashed line; after the flip the back ribbons are mirrored">
    <defs><marker id="head" viewBox="0 0 10 10" refX="8" refY="5" markerWidth="5" markerHeight="5" orient="auto-start-reverse">
    <path d="M0 0 L10 5 L0 10 z" class="arrowhead"/></marker></defs>${left}${right}${arrows}</svg>`;
}

/** The frame back up, seen from above: the back ribbons and the marks (mirrored), mark ``highlight`` filled. */
export function backSVG(design, flip, highlight) {
  const box = fabric(design, flip);
  const body = panel(design, { box, map: mirrorOf(box.f), strong: ["back"], faint: [], highlight, axis: box.f });
  return `<svg xmlns="${NS}" class="drawing marks" viewBox="${box.x0 - 8} ${-(box.y0 + box.h) - 8} ${box.w + 16} ${box.h + 16}" role="img"
    aria-label="the frame back up: registration marks numbered, the current one filled">${body}</svg>`;
}
