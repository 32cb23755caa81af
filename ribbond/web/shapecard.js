// The job page's card "Predicted shape in 3D" (issue 36 item 11): the design's target.obj and
// deployed.obj in the WebGL view (view3d.js), the prediction coloured by each vertex's distance to the
// target (GET /jobs/{id}/deviation: measured by the daemon, as report.deployed.deviation_pct is), the
// legend of the colours, and beside them the verdict: whether the target's shape is reached, and why.
import * as api from "./api.js";
import { ShapeView, parseOBJ, deviationColors, legendTop, viridisCSS } from "./view3d.js";

const $ = (id) => document.getElementById(id);
const esc = (s) => String(s ?? "").replace(/[&<>"']/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" })[c]);
const pct = (v) => (Number.isFinite(Number(v)) ? `${Number(v).toFixed(1)} %` : "–");

/** Whether a design's prediction says it takes the target's shape: true, false, or undefined
 * (no prediction, or a format 2 report without a verdict). */
export const reachedOf = (design) => design?.report?.deployed?.reached;

/** The words beside "Print" for a design predicted NOT to take its shape (else ""). */
export function printWarningHTML(design) {
  const d = design?.report?.deployed;
  if (!d || d.reached !== false) return "";
  const why = String(d.verdict || "").replace(/^will NOT take the target's shape:\s*/i, "");
  return `<span class="print-warning" id="print-warning"><strong>Predicted NOT to take the target's shape</strong>` +
    `${why ? `: ${esc(why)}` : ""} (<a href="#j-shape" data-goto="j-shape">see it in 3D</a>).</span>`;
}

/** The colour bar: 0 to ``vmax`` % of the diagonal, five ticks, the diagonal in mm. */
function legendHTML(vmax, diagonal) {
  const ticks = [0, 0.25, 0.5, 0.75, 1].map((t) => `<span style="left:${100 * t}%">${(t * vmax).toFixed(1)} %</span>`).join("");
  return `<div class="bar" style="background:${viridisCSS()}"></div><div class="ticks">${ticks}</div>
    <p class="muted">distance of the prediction to the target, % of the target's bounding-box diagonal
    (${Number(diagonal).toFixed(1)} mm); the top colour: ${vmax.toFixed(1)} % or more</p>`;
}

const LABELS = { target: "target", deployed: "prediction", both: "prediction, the target's edges over it" };

export class ShapeCard {
  constructor() {
    this.view = new ShapeView($("shape-canvas"));
    this.key = "";
    this.view.onDraw = (panes) => {                 // each pane named in its corner
      const key = JSON.stringify(panes);
      if ($("shape-labels").dataset.key === key) return;
      $("shape-labels").dataset.key = key;
      $("shape-labels").innerHTML = panes.map((p) => `<span style="left:${p.left}px;top:${p.top}px">${LABELS[p.what]}</span>`).join("");
    };
    // "see it in 3D" beside Print: a scroll, not a route (the page's routes live in the hash)
    document.addEventListener("click", (e) => {
      const a = e.target.closest("a[data-goto]");
      if (!a) return;
      e.preventDefault();
      $(a.dataset.goto).scrollIntoView({ block: "start" });
    });
    $("shape-modes").addEventListener("click", (e) => {
      const b = e.target.closest("button[data-mode]");
      if (!b) return;
      if (b.dataset.mode === "reset") { this.view.reset(); return; }
      this.view.setMode(b.dataset.mode);
      $("shape-canvas").classList.toggle("side", b.dataset.mode === "side");
      for (const o of $("shape-modes").querySelectorAll("button[data-mode]")) o.classList.toggle("on", o === b);
    });
  }

  /** Show the card for a design job with a prediction; (re)load its meshes when the prediction changed. */
  update(job, design) {
    const d = design?.report?.deployed;
    const card = $("j-shape");
    card.hidden = job.kind !== "design" || !d;
    if (card.hidden) return;
    this.verdict(d);
    const key = `${job.id}:${d.time_s}:${JSON.stringify(d.deviation_pct)}`;
    if (key === this.key) return;
    this.key = key;
    this.load(job.id, key).catch((e) => this.note(`The 3D view could not be drawn: ${e.message}`));
  }

  verdict(d) {
    const r = $("shape-reached");
    r.hidden = d.reached === undefined;
    r.textContent = d.reached ? "Will take the target's shape" : "Will NOT take the target's shape";
    r.className = `reached ${d.reached ? "yes" : "no"}`;
    $("shape-verdict").hidden = !d.verdict;
    $("shape-verdict").textContent = d.verdict || "";
    const dev = d.deviation_pct || {};
    $("shape-figures").textContent = `Deviation from the target: ${pct(dev.mean)} mean, ${pct(dev.p99)} p99, ${pct(dev.max)} max of the diagonal`;
  }

  note(text) {
    $("shape-note").hidden = !text;
    $("shape-note").textContent = text || "";
  }

  async load(id, key) {
    this.note("");
    if (!this.view.ok) { this.note("This browser cannot draw 3D (no WebGL): the picture under Layout shows the prediction."); return; }
    $("shape-legend").innerHTML = "";
    const [t, p, dev] = await Promise.all([api.fileText(id, "target.obj"), api.fileText(id, "deployed.obj"),
      api.get(`/jobs/${encodeURIComponent(id)}/deviation`)]);
    if (key !== this.key) return;                                  // another job or prediction since
    if (!t || !p) throw new Error("target.obj or deployed.obj is not there");
    const target = parseOBJ(t), deployed = parseOBJ(p);
    if (dev.distance_mm.length !== deployed.positions.length / 3)
      throw new Error(`the deviation has ${dev.distance_mm.length} vertices, deployed.obj ${deployed.positions.length / 3}`);
    const vmax = legendTop(dev.deviation_pct);
    this.view.show(target, deployed, deviationColors(dev.distance_mm, dev.diagonal_mm, vmax));
    $("shape-legend").innerHTML = legendHTML(vmax, dev.diagonal_mm);
  }
}
