// A project (a mesh printed in panels): the panel map, drawn from project.json's outlines (each
// panel's flat outline in its own front print coordinates, set side by side), coloured by the state
// of the job printing it, numbered; the panel list; what the operator does next.

const esc = (s) => String(s ?? "").replace(/[&<>"']/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" })[c]);
const ON_PRINTER = new Set(["heating", "printing_front", "printing_back", "awaiting_flip", "aligning", "fitted", "paused", "awaiting_check"]);

/** The colour class of a panel: done, printing, waiting (for the operator), queued, stopped, ready. */
export function panelClass(q) {
  if (q.state === "done") return "done";
  if (["cancelled", "failed", "interrupted", "deleted"].includes(q.state)) return "stopped";
  if (q.at_gate || (q.waits_for_operator && ON_PRINTER.has(q.state))) return "waiting";
  if (ON_PRINTER.has(q.state)) return "printing";
  if (q.queued) return "queued";
  return "ready";
}

export const CLASS_TEXT = { done: "done", printing: "printing", waiting: "waits for you", queued: "queued",
  stopped: "cancelled", ready: "not started" };

/** The panel map: each panel's outline, side by side (rows of up to 4), numbered. */
export function panelMapSVG(p, { compact = false } = {}) {
  const panels = (p.panels || []).filter((q) => (q.outline || []).length >= 3);
  if (!panels.length) return `<p class="muted">The panel map appears once the panels are compiled.</p>`;
  const gap = 14, perRow = Math.min(panels.length, compact ? 6 : 4);
  const boxes = panels.map((q) => {
    const xs = q.outline.map((v) => v[0]), ys = q.outline.map((v) => v[1]);
    return { q, x0: Math.min(...xs), y0: Math.min(...ys), w: Math.max(...xs) - Math.min(...xs), h: Math.max(...ys) - Math.min(...ys) };
  });
  const cell = Math.max(...boxes.map((b) => Math.max(b.w, b.h)));
  const rows = Math.ceil(boxes.length / perRow);
  const W = perRow * cell + (perRow + 1) * gap, H = rows * cell + (rows + 1) * gap;
  const font = Math.max(10, cell * (compact ? 0.34 : 0.26));
  const shapes = boxes.map((b, i) => {
    const ox = gap + (i % perRow) * (cell + gap) + (cell - b.w) / 2;
    const oy = gap + Math.floor(i / perRow) * (cell + gap) + (cell - b.h) / 2;
    // print y is up, SVG y is down
    const pts = b.q.outline.map(([x, y]) => `${(ox + x - b.x0).toFixed(1)},${(oy + b.y0 + b.h - y).toFixed(1)}`).join(" ");
    const cls = panelClass(b.q);
    const now = b.q.index === p.current_panel ? " now" : "";
    return `<g class="panel ${cls}${now}" data-panel="${b.q.index}">
      <title>panel ${b.q.index}: ${esc(CLASS_TEXT[cls])} (${esc(b.q.state)})</title>
      <polygon points="${pts}"/>
      <text x="${(ox + b.w / 2).toFixed(1)}" y="${(oy + b.h / 2).toFixed(1)}" font-size="${font.toFixed(1)}"
        text-anchor="middle" dominant-baseline="central">${b.q.index}</text></g>`;
  }).join("");
  return `<svg class="panelmap${compact ? " compact" : ""}" viewBox="0 0 ${W.toFixed(1)} ${H.toFixed(1)}" role="img"
    aria-label="panel map: ${panels.map((q) => `panel ${q.index} ${CLASS_TEXT[panelClass(q)]}`).join(", ")}">${shapes}</svg>`;
}

export function legendHTML() {
  return `<p class="legend">${["done", "printing", "waiting", "queued", "ready", "stopped"].map((c) =>
    `<span><i class="sw ${c}"></i>${CLASS_TEXT[c]}</span>`).join("")}</p>`;
}

/** The home page's card of one project in progress. */
export function projectCardHTML(p) {
  const n = p.panel_count;
  const head = n ? (p.current_panel ? `panel ${p.current_panel} of ${n}` : `${p.panels_done} of ${n} panels done`) : p.state;
  return `<a class="project-link" href="#/project/${esc(p.id)}"><h3>${esc(p.mesh_name)} — ${esc(head)} →</h3></a>
    <p class="instruction next-step${p.state === "waiting" ? " waits" : ""}">${esc(p.next.instruction)}</p>
    ${panelMapSVG(p, { compact: true })}`;
}

/** The project page's panel list. */
export function panelListHTML(p) {
  return `<ol class="panel-list">${(p.panels || []).map((q) => {
    const cls = panelClass(q);
    const size = (q.flat_size_mm || []).length === 2 ? `${q.flat_size_mm[0].toFixed(0)} × ${q.flat_size_mm[1].toFixed(0)} mm` : "";
    const pct = cls === "printing" || (cls === "waiting" && !q.at_gate) ? ` ${Math.round((q.progress || 0) * 100)} %` : "";
    const job = q.job_id ? `<a href="#/job/${esc(q.job_id)}">job ${esc(q.job_id)}</a>` : "no job";
    const label = q.at_gate ? "waits for a fresh frame" : q.state.replace("_", " ");
    return `<li class="${cls}"><i class="sw ${cls}"></i><b>Panel ${q.index}</b> <span class="state ${esc(q.at_gate ? "awaiting_flip" : q.state)}">${esc(label)}${pct}</span>
      <span class="muted">${esc(size)}</span> ${job}</li>`;
  }).join("")}</ol>`;
}

export function seamsHTML(p) {
  if (!(p.seams || []).length) return "";
  return `<p class="muted">Seams (${p.seam_allowance_mm} mm allowance): ${p.seams.map((s) => {
    const t = s.length_mm?.target;
    return `${esc(s.label)} joins panels ${s.panels.map(Number).join(" and ")}${typeof t === "number" ? `, ${t.toFixed(0)} mm` : ""}`;
  }).join("; ")}</p>`;
}
