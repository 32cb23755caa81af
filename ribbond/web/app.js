// The dashboard: the printer, the jobs, a job's page with the flip and the alignment steps.
// Live over /events (jobs, progress, the printer's state and temperatures); GET /printer is read
// at start and while the events are down.
import * as api from "./api.js";
import { drawChart } from "./chart.js";
import { layoutSVG, flipSVG, backSVG } from "./draw.js";
import { panelMapSVG, legendHTML, projectCardHTML, panelListHTML, seamsHTML } from "./project.js";
import { CameraView } from "./camera.js";
import { loadNotify, takeDelivery } from "./notify.js";
import { ShapeCard, printWarningHTML } from "./shapecard.js";
import { sortJobs, endedDuration, downloads } from "./joblist.js";
import { initAdjust, renderAdjust } from "./adjust.js";

const $ = (id) => document.getElementById(id);
const esc = (s) => String(s ?? "").replace(/[&<>"']/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" })[c]);
const ENDED = new Set(["done", "cancelled", "failed", "interrupted"]);
const STREAMS = new Set(["heating", "printing_front", "printing_back"]);
/** States of a print under way in which a person acts: no side is printing, no time left is told. */
const PERSON = new Set(["awaiting_flip", "aligning", "fitted", "paused", "awaiting_check"]);
const STAGES = ["load", "curvature", "flatten", "stripes", "ribbons", "gcode", "deploy", "preview", "write"];
const LABEL = { submitted: "submitted", compiling: "compiling", ready: "ready", heating: "heating",
  printing_front: "printing front", awaiting_flip: "flip the frame", aligning: "aligning", fitted: "check the fit",
  printing_back: "printing back", paused: "paused", done: "done", cancelled: "cancelled", failed: "failed",
  interrupted: "interrupted", awaiting_check: "check the frame" };

const state = {
  printer: null, jobs: new Map(), filter: "all", route: { page: "home" }, temps: [], live: false,
  designs: new Map(), files: new Map(), busy: new Set(), align: new Map(), alignMark: new Map(), compileInfo: new Map(),
  predicted: new Map(), projects: new Map(), camera: null,
};

// ------------------------------------------------------------------ small helpers

let toastTimer = 0;
function toast(message, kind = "info") {
  const t = $("toast");
  t.textContent = message;
  t.className = `toast ${kind}`;
  t.hidden = false;
  clearTimeout(toastTimer);
  toastTimer = setTimeout(() => { t.hidden = true; }, kind === "error" ? 9000 : 4000);
}

$("toast").addEventListener("click", () => { $("toast").hidden = true; });

async function act(what, fn) {
  try { return await fn(); } catch (e) { toast(`${what}: ${e.message}`, "error"); throw e; }
}

const quiet = (p) => p.catch(() => {});

function duration(s) {
  if (s === null || s === undefined || !isFinite(s)) return "–";
  s = Math.max(0, Math.round(s));
  const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), sec = s % 60;
  return h ? `${h} h ${m} min` : m ? `${m} min ${sec} s` : `${sec} s`;
}
const when = (t) => (t ? new Date(t * 1000).toLocaleString([], { month: "short", day: "numeric", hour: "2-digit", minute: "2-digit" }) : "–");
const mm = (v, d = 1) => (v === null || v === undefined ? "–" : `${Number(v).toFixed(d)}`);
const commandsOf = (job) => (job.next?.commands || []).map((c) => c.split(" ")[1]);

// ------------------------------------------------------------------ access

let loginResolve = null;
api.whenUnauthorized(() => askToken());
function askToken(message) {
  const dlg = $("login");
  $("login-error").hidden = !message;
  $("login-error").textContent = message || "";
  if (!dlg.open) dlg.showModal();
  $("login-token").focus();
  return new Promise((resolve) => { loginResolve = resolve; });
}
$("login-form").addEventListener("submit", async (e) => {
  e.preventDefault();
  api.setToken($("login-token").value.trim());
  try {
    await api.get("/printer");
  } catch (err) {
    api.setToken(null);
    $("login-error").hidden = false;
    $("login-error").textContent = err.status === 401 ? "That token was refused." : err.message;
    return;
  }
  $("login").close();
  $("login-token").value = "";
  if (loginResolve) { loginResolve(); loginResolve = null; }
  restartEvents();
  refreshAll();
});

// ------------------------------------------------------------------ the printer

function heater(h) {
  if (!h) return "–";
  const tgt = h.target ? ` / ${h.target.toFixed(0)}` : "";
  return `${h.current.toFixed(0)}${tgt} °C`;
}

/** The frame on the printer: fresh (confirmed, nothing printed on it since) or used. */
const frameText = (f) => (!f ? "" : f.state === "fresh" ? "Frame: fresh (nothing printed on it since it was loaded)"
  : `Frame: used${f.waiting_job ? ": a job waits for a fresh one" : ""}`);

/** The head's position per axis; an axis not homed says so (as Mainsail does): its number means nothing. */
function positionText(pos, homed) {
  if (!pos && (!homed || homed.length === 3)) return "–";         // not known (halted, disconnected)
  return ["x", "y", "z"].map((a, i) => (homed && !homed.includes(a) ? `${a} not homed`
    : pos ? `${a} ${mm(pos[i], 2)}` : `${a} –`)).join("  ") + (pos && (!homed || homed.length) ? " mm" : "");
}

function renderPrinter() {
  const p = state.printer;
  const s = p ? p.state : "unknown";
  const conn = $("conn");
  conn.textContent = s;
  conn.className = `pill ${s}`;
  $("p-state").textContent = s;
  $("p-firmware").textContent = p?.firmware || "–";
  $("p-position").textContent = positionText(p?.head || p?.position, p?.homed);
  $("t-nozzle").textContent = heater(p?.heaters?.T);
  $("t-bed").textContent = heater(p?.heaters?.B);
  $("p-note").textContent = [p?.note, frameText(p?.frame)].filter(Boolean).join(" · ");
  $("p-link").textContent = p?.window_advice || "";   // the link found the board's buffer smaller
  const prof = p?.profile;
  if (prof) {
    const [x0, y0, x1, y1] = prof.frame.bounds;
    const [cx, cy] = prof.frame.center;
    $("profile").textContent = `${prof.name}: frame ${mm(x1 - x0, 0)} × ${mm(y1 - y0, 0)} mm ` +
      `(x ${mm(x0, 0)}–${mm(x1, 0)}, y ${mm(y0, 0)}–${mm(y1, 0)}), flipped about its ${prof.frame.flip_axis} axis ` +
      `(${prof.frame.flip_axis === "y" ? `x = ${mm(cx, 0)}` : `y = ${mm(cy, 0)}`})`;
  }
  const halted = s === "halted";
  $("halted").hidden = !halted;
  if (halted) $("halted-text").textContent = `The printer is halted${p.last_error ? ` (${p.last_error})` : ""}. Check the machine, then recover.`;
  // manual control: not while a program streams
  const streaming = [...state.jobs.values()].find((j) => STREAMS.has(j.state));
  const live = s === "ready" || s === "paused";
  const manual = live && !streaming;
  for (const el of document.querySelectorAll("#manual button, #manual input, #heat, #cool")) el.disabled = !manual;
  // the console stays open beside a running program: the daemon takes only the adjustments and M105/M114 then
  for (const el of document.querySelectorAll("#console-form input, #console-form button")) el.disabled = !(manual || (streaming && s === "streaming"));
  $("manual-note").textContent = manual ? "" : streaming ? `A program is streaming (${streaming.mesh_name}): pause it to move the head; ` +
    "the console takes M220, M221, M104, M140, M105 and M114 meanwhile." : `The printer is ${s}.`;
  renderAdjust($("adjust"), p, streaming);
  for (const el of document.querySelectorAll(".jogpad .pos")) el.textContent = $("p-position").textContent;
  drawChart($("chart"), state.temps);
}

/** Take a printer status (from an event or GET /printer): keep 30 minutes of temperatures (as the daemon does). */
function takePrinter(status) {
  state.printer = status;
  const h = status.heaters || {};
  if (h.T || h.B) {
    state.temps.push({ t: Date.now() / 1000, T: h.T?.current, Tt: h.T?.target, B: h.B?.current, Bt: h.B?.target });
    const cut = Date.now() / 1000 - TEMPS_SPAN_S;
    while (state.temps.length && state.temps[0].t < cut) state.temps.shift();
  }
  renderPrinter();
}

async function pollPrinter() {
  try {
    takePrinter(await api.get("/printer"));
  } catch (e) {
    if (e.status !== 401) state.printer = { state: "unreachable", note: e.message };
    renderPrinter();
  }
}

$("estop").addEventListener("click", async () => {
  try {
    state.printer = await api.post("/printer/emergency-stop");
    toast("Emergency stop sent: the printer is halted.", "error");
  } catch (e) { toast(`Emergency stop: ${e.message}`, "error"); }
  renderPrinter();
});
$("recover").addEventListener("click", () => act("Recover", async () => {
  state.printer = await api.post("/printer/recover");
  toast("The printer restarted.");
  renderPrinter();
}));
$("heat").addEventListener("click", () => act("Heat", async () => { state.printer = await api.post("/printer/heat", {}); renderPrinter(); }));
$("cool").addEventListener("click", () => act("Cool", async () => { state.printer = await api.post("/printer/cool"); renderPrinter(); }));
$("home-axes").addEventListener("click", () => act("Home", async () => { await api.post("/printer/home"); await pollPrinter(); }));
$("goto-centre").addEventListener("click", () => act("Go to the frame's centre", async () => {
  const [x, y] = state.printer?.profile?.frame?.center ?? [];
  if (x === undefined) throw new Error("the printer's frame is not known yet");
  await api.post("/printer/goto", { x, y });
  await pollPrinter();
}));

initAdjust($("adjust"), (r) => { if (r.printer) takePrinter(r.printer); });

// ------------------------------------------------------------------ the jog pad

function jogPad(container) {
  container.innerHTML = `
    <div class="steps" role="radiogroup" aria-label="step">
      ${[0.1, 1, 10].map((s, i) => `<label data-step="${s}"><input type="radio" name="${container.id}-step" value="${s}" ${i === 1 ? "checked" : ""}>${s} mm</label>`).join("")}
    </div>
    <div class="pad">
      <button data-jog="y+" class="up" aria-label="y plus">Y+</button>
      <button data-jog="x-" class="left" aria-label="x minus">X−</button>
      <button data-jog="x+" class="right" aria-label="x plus">X+</button>
      <button data-jog="y-" class="down" aria-label="y minus">Y−</button>
      <button data-jog="z+" class="zup" aria-label="z up">Z↑</button>
      <button data-jog="z-" class="zdown" aria-label="z down">Z↓</button>
    </div>
    <p class="pos muted"></p>`;
  container.dataset.pending = "0";
  let chain = Promise.resolve();
  container.addEventListener("click", (e) => {
    const b = e.target.closest("button[data-jog]");
    if (!b) return;
    const step = Number(container.querySelector("input[type=radio]:checked").value);
    const [axis, sign] = [b.dataset.jog[0], b.dataset.jog[1] === "+" ? 1 : -1];
    const body = { dx: 0, dy: 0, dz: 0 };
    body[`d${axis}`] = sign * step;
    container.dataset.pending = String(Number(container.dataset.pending) + 1);
    chain = chain.then(async () => {
      try {
        const r = await api.post("/printer/jog", body);
        if (state.printer && r.position) Object.assign(state.printer, { head: r.position, homed: r.homed });
        renderPrinter();
      } catch (err) { toast(`Jog: ${err.message}`, "error"); }
      finally { container.dataset.pending = String(Number(container.dataset.pending) - 1); }
    });
  });
}
jogPad($("manual-jog"));
jogPad($("align-jog"));

// ------------------------------------------------------------------ the console

$("console-form").addEventListener("submit", async (e) => {
  e.preventDefault();
  const line = $("console-in").value.trim();
  if (!line) return;
  const out = $("console-out");
  const add = (text, cls) => { const d = document.createElement("div"); d.className = cls; d.textContent = text; out.append(d); out.scrollTop = out.scrollHeight; };
  add(`> ${line}`, "sent");
  $("console-in").value = "";
  try {
    const r = await api.post("/printer/gcode", { commands: [line] });
    for (const a of r.answers) {
      if (a.sent) add(`sent as: ${a.sent}`, "note");
      for (const l of a.answer) add(l, "answer");
    }
    for (const n of r.notes || []) add(`note: ${n}`, "note");   // clamped feeds, G90 restored, unchecked
  } catch (err) { add(err.message, "error"); }
});

// ------------------------------------------------------------------ the job list

const FILTERS = {
  all: () => true,
  active: (j) => !ENDED.has(j.state),
  done: (j) => j.state === "done",
  failed: (j) => ["failed", "cancelled", "interrupted"].includes(j.state),
};
for (const b of document.querySelectorAll("[data-filter]")) {
  b.addEventListener("click", () => {
    state.filter = b.dataset.filter;
    for (const o of document.querySelectorAll("[data-filter]")) o.classList.toggle("on", o === b);
    renderJobs();
  });
}

function sizeOf(j) {
  if (j.kind === "gcode") return "G-code";
  const d = j.parameters?.size?.bbox_diagonal;
  return d ? `${Number(d).toFixed(0)} mm` : "fit";
}

function percent(j) { return `${Math.round((j.progress || 0) * 100)} %`; }

let jobsSoon = 0;
/** Draw the list again once the runs' starts are read (one redraw for many). */
function renderJobsSoon() { if (!jobsSoon) jobsSoon = setTimeout(() => { jobsSoon = 0; renderJobs(); }, 50); }

function renderJobs() {
  const jobs = sortJobs([...state.jobs.values()].filter(FILTERS[state.filter]), renderJobsSoon);
  if (!jobs.length) { $("job-list").innerHTML = `<p class="muted">No jobs${state.filter === "all" ? " yet" : " here"}.</p>`; return; }
  $("job-list").innerHTML = `<table class="jobs"><thead><tr><th>Name</th><th>State</th><th>Size</th><th>Created</th><th>Finished</th><th>Duration</th></tr></thead><tbody>${
    jobs.map((j) => {
      const ended = ENDED.has(j.state);
      const dur = ended ? endedDuration(j, renderJobsSoon) : (j.elapsed_s ?? null);
      const st = STREAMS.has(j.state) || j.state === "compiling" ? `${labelOf(j)} ${percent(j)}` : labelOf(j);
      return `<tr data-job="${esc(j.id)}" class="${j.waits_for_operator ? "waits" : ""}">
        <td><a href="#/job/${esc(j.id)}">${esc(j.mesh_name)}</a>${j.project ? ` <span class="muted">panel ${j.panel}/${j.panels}</span>` : ""}</td>
        <td><span class="state ${esc(j.state)}">${esc(st)}</span></td><td>${esc(sizeOf(j))}</td>
        <td>${when(j.created)}</td><td>${ended ? when(j.updated) : "–"}</td><td>${duration(dur)}</td></tr>`;
    }).join("")}</tbody></table>`;
  const waiting = [...state.jobs.values()].find((j) => (["awaiting_flip", "aligning", "fitted"].includes(j.state) || atGate(j)) && j.waits_for_operator);
  const banner = $("needs-you");
  const panelGate = waiting && waiting.project && atGate(waiting);       // between panels: the project's page says it
  const here = waiting && ((state.route.page === "job" && state.route.id === waiting.id)
    || (panelGate && state.route.page === "project" && state.route.id === waiting.project));
  banner.hidden = !waiting || here;
  if (waiting && !here) {
    banner.href = panelGate ? `#/project/${waiting.project}` : `#/job/${waiting.id}`;
    const what = atGate(waiting) ? "load a fresh frame"
      : { awaiting_flip: "turn the frame over", aligning: "align the marks", fitted: "check the fit" }[waiting.state];
    const who = waiting.project ? `${waiting.mesh_name}, panel ${waiting.panel} of ${waiting.panels}` : waiting.mesh_name;
    banner.textContent = `${who}: ${what} →`;
  }
}

// ------------------------------------------------------------------ projects (a mesh in panels)

const PROJECT_OVER = new Set(["done", "failed", "cancelled"]);
function renderProjects() {
  const live = [...state.projects.values()].filter((p) => !PROJECT_OVER.has(p.state)).sort((a, b) => b.created - a.created);
  $("projects").hidden = !live.length;
  $("project-cards").innerHTML = live.map((p) => `<div class="project" data-project="${esc(p.id)}">${projectCardHTML(p)}</div>`).join("");
}

function projectActions(p) {
  const cur = (p.panels || []).find((q) => q.index === p.current_panel);
  const out = [];
  if (cur && cur.at_gate) out.push(`<button class="primary huge" data-pact="frame-ready">Fresh frame loaded (panel ${cur.index})</button>`);
  else if (cur && cur.job_id) out.push(`<a class="button primary" href="#/job/${esc(cur.job_id)}">Panel ${cur.index}: open its job (flip, alignment, pause)</a>`);
  if (["ready", "cancelled"].includes(p.state)) out.push(`<button data-pact="start">Print the panels left</button>`);
  if (!PROJECT_OVER.has(p.state)) out.push(`<button class="warn" data-pact="cancel">Cancel the project</button>`);
  return out.join("");
}

function renderProjectPage() {
  if (state.route.page !== "project") return;
  const p = state.projects.get(state.route.id);
  if (!p) { $("pj-title").textContent = "No such project"; return; }
  const n = p.panel_count;
  $("pj-title").textContent = `${p.mesh_name}: ${n ? `${n} panels` : "panels"}`;
  $("pj-state").textContent = p.current_panel && n ? `${p.state}: panel ${p.current_panel} of ${n}` : p.state;
  $("pj-state").className = `state ${p.state === "waiting" ? "awaiting_flip" : p.state === "printing" ? "printing_front" : p.state}`;
  $("pj-stage").textContent = n ? `${p.panels_done} of ${n} done` : (p.stage || "");
  $("pj-next").textContent = p.next.instruction;
  $("pj-next").classList.toggle("waits", p.state === "waiting");
  $("pj-error").hidden = !p.error;
  $("pj-error").textContent = p.error || "";
  $("pj-actions").innerHTML = projectActions(p);
  $("pj-map").innerHTML = panelMapSVG(p);
  $("pj-legend").innerHTML = (p.panels || []).length ? legendHTML() : "";
  $("pj-panels").innerHTML = panelListHTML(p);
  $("pj-seams").innerHTML = seamsHTML(p);
  if (p.folder && !state.files.has(`project:${p.id}`)) {
    state.files.set(`project:${p.id}`, null);
    quiet(api.fileURL(p.id, "panels.png", "projects").then((u) => { state.files.set(`project:${p.id}`, u); renderProjectPage(); }));
  }
  const img = state.files.get(`project:${p.id}`);
  $("pj-fig").hidden = !img;
  if (img && $("pj-img").src !== img) $("pj-img").src = img;
  renderProjectPrediction(p);
}

/** The project's verdict (the bad lines in red) and the sewn prediction's picture (issue 36). */
function renderProjectPrediction(p) {
  const lines = p.verdict || [];
  $("pj-prediction").hidden = !lines.length;
  $("pj-verdict").innerHTML = lines.map((l) => `<li class="${/NOT|not known/.test(l) ? "bad" : ""}">${esc(l)}</li>`).join("");
  const key = `project-deployed:${p.id}`;
  if (p.has_deployed && !state.files.has(key)) {
    state.files.set(key, null);
    quiet(api.fileURL(p.id, "deployed.png", "projects").then((u) => { state.files.set(key, u); renderProjectPage(); }));
  }
  const img = state.files.get(key);
  $("pj-dfig").hidden = !img;
  if (img && $("pj-dimg").src !== img) $("pj-dimg").src = img;
}

$("pj-actions").addEventListener("click", async (e) => {
  const b = e.target.closest("[data-pact]");
  if (!b) return;
  const id = state.route.id, what = b.dataset.pact;
  if (what === "cancel" && !confirm("Cancel the project: the panel on the printer stops (heaters off, head up) and the panels left are cancelled?")) return;
  b.disabled = true;
  await act({ "frame-ready": "Fresh frame loaded", start: "Print the panels left", cancel: "Cancel the project" }[what], async () => {
    if (what === "frame-ready") await api.post("/printer/frame-ready");
    else state.projects.set(id, await api.post(`/projects/${id}/${what}`));
    await loadProject(id);
  });
  b.disabled = false;
});

async function loadProject(id) {
  const p = await api.get(`/projects/${encodeURIComponent(id)}`);
  state.projects.set(p.id, p);
  renderProjects();
  renderProjectPage();
}

async function loadProjects() {
  const list = await api.get("/projects?limit=50");
  state.projects = new Map(list.map((p) => [p.id, p]));
  renderProjects();
  renderProjectPage();
}

const projectReload = new Map();
function reloadProjectSoon(id) {
  if (projectReload.has(id)) return;
  projectReload.set(id, setTimeout(() => { projectReload.delete(id); quiet(loadProject(id)); }, 250));
}

async function loadJobs() {
  const list = await api.get("/jobs?limit=200");
  state.jobs = new Map(list.map((j) => [j.id, j]));
  renderJobs();
  renderJobPage();
}

// ------------------------------------------------------------------ submitting

let chosen = null;
function choose(file) {
  chosen = file;
  $("drop-text").textContent = file ? `${file.name} (${Math.max(1, Math.round(file.size / 1024))} kB): tap to choose another`
    : "Choose a mesh (OBJ, PLY, STL, OFF) or a G-code file: tap here, or drop it here";
  const gcode = file && /\.(gcode|gco|g|nc)$/i.test(file.name);
  $("design-params").hidden = !!gcode;
  $("submit-btn").textContent = gcode ? "Upload G-code" : "Upload mesh";
}
$("file").addEventListener("change", () => choose($("file").files[0] || null));
$("panels").addEventListener("change", () => {
  const panels = $("panels").value;
  $("seam-row").hidden = !panels;
  // a project keeps one scale: without a size the mesh's units are read as mm
  $("size").placeholder = panels ? "the mesh's own units, as mm" : "largest the frame and the plastic allow";
});
const drop = $("drop");
drop.addEventListener("dragover", (e) => { e.preventDefault(); drop.classList.add("over"); });
drop.addEventListener("dragleave", () => drop.classList.remove("over"));
drop.addEventListener("drop", (e) => { e.preventDefault(); drop.classList.remove("over"); if (e.dataTransfer.files[0]) choose(e.dataTransfer.files[0]); });

$("submit-form").addEventListener("submit", async (e) => {
  e.preventDefault();
  const err = $("submit-error");
  err.hidden = true;
  if (!chosen) { err.textContent = "Choose a file first."; err.hidden = false; return; }
  if (!chosen.size) { err.textContent = `${chosen.name} is empty (0 bytes): choose the file that holds the mesh or the program.`; err.hidden = false; return; }
  const gcode = /\.(gcode|gco|g|nc)$/i.test(chosen.name);
  const panels = gcode ? "" : $("panels").value;
  const form = new FormData();
  form.append(gcode ? "gcode" : "mesh", chosen, chosen.name);
  if (!gcode) {
    const params = {};
    const num = (id) => { const v = $(id).value.trim(); return v === "" ? null : Number(v); };
    if (num("size") !== null) params.size = { bbox_diagonal: num("size") };
    if ($("table").value.trim() && $("table").value.trim() !== "tpu95a-lycra-default") params.curvature_table = $("table").value.trim();
    if (num("ribbon_width") !== null) params.ribbon_width = num("ribbon_width");
    if (num("prestretch") !== null) params.prestretch = num("prestretch");
    form.append("parameters", JSON.stringify(params));
  }
  form.append("start", $("start-now").checked ? "true" : "false");
  if (panels) { form.append("panels", panels); form.append("seam_allowance", $("seam_allowance").value || "6"); }
  const bar = $("upload-progress");
  bar.hidden = false; bar.value = 0;
  $("submit-btn").disabled = true;
  try {
    const made = await api.upload(panels ? "/projects" : "/jobs", form, (f) => { bar.value = f; });
    if (panels) {
      state.projects.set(made.id, made);
      renderProjects();
      location.hash = `#/project/${made.id}`;
    } else {
      state.jobs.set(made.id, made);
      renderJobs();
      location.hash = `#/job/${made.id}`;
    }
    $("file").value = ""; choose(null);
  } catch (x) {
    err.textContent = x.status === 413 || x.status === 422 || x.status === 409 ? `Refused: ${x.message}` : x.message;
    err.hidden = false;
  } finally {
    bar.hidden = true;
    $("submit-btn").disabled = false;
  }
});

// ------------------------------------------------------------------ a job's page

/** The flip line from the daemon's instruction ("... about its y axis (the line x = 110) ..."):
 * the API names the profile's frame nowhere else. */
function axisFrom(instruction) {
  const m = /the line ([xy]) = (-?[\d.]+)/.exec(instruction || "");
  return m ? { line: m[1], c: Number(m[2]) } : null;
}

async function loadDesign(job) {
  if (job.kind !== "design" || !job.design_dir || state.designs.has(job.id)) return;
  state.designs.set(job.id, null);
  const design = await api.fileJSON(job.id, "design.json");
  if (!design) { state.designs.delete(job.id); return; }
  state.designs.set(job.id, design);
  const [preview, deployed] = await Promise.all([api.fileURL(job.id, "preview.png"), api.fileURL(job.id, "deployed.png")]);
  state.files.set(job.id, { preview, deployed });
  renderJobPage();
}

function summary(design) {
  const r = design.report || {}, p = design.parameters || {}, pr = r.print || {};
  const rows = [];
  const add = (k, v) => rows.push(`<dt>${esc(k)}</dt><dd>${esc(v)}</dd>`);
  add("Faces", r.faces ?? design.faces?.length ?? "–");
  add("Size", p.size?.bbox_diagonal ? `${Number(p.size.bbox_diagonal).toFixed(1)} mm diagonal` : "–");
  const b = (x) => (x ? `${Number(x[0]).toFixed(2)} – ${Number(x[1]).toFixed(2)}` : "–");
  add("σ1 bounds", `${b(p.sigma1_bounds)} (${mm(r.sigma1_bad_pct, 1)} % of faces outside)`);
  add("σ2 bounds", `${b(p.sigma2_bounds)} (${mm(r.sigma2_bad_pct, 1)} % of faces outside)`);
  add("Ribbons", `${r.ribbons?.front ?? "–"} front, ${r.ribbons?.back ?? "–"} back`);
  for (const side of ["front", "back"]) {
    const s = pr[side];
    if (s && s.lines) add(`Print ${side}`, `${duration(s.time_s)}, ${mm(s.filament_mm / 1000, 2)} m filament`);
  }
  add("Printer profile", p.printer_profile || "–");
  add("Curvature table", p.curvature_table || "–");
  return rows.join("");
}

function progressText(j) {
  const parts = [];
  if (j.state === "compiling") {
    parts.push(`compiling: ${j.stage || "…"}`);
    const it = state.compileInfo.get(j.id);
    if (it && it.iteration !== undefined) parts.push(`iteration ${it.iteration}`);
  } else if (j.waiting_for && !ENDED.has(j.state)) {
    // a wait for a person is not progress: what it waits for, no side printing, no time left
    parts.push(`waiting for ${j.waiting_for}`, percent(j));
  } else {
    // the program being printed: a plain job's program, a resumed side's (its lines are not the whole side's)
    if (j.kind === "gcode" && STREAMS.has(j.state)) parts.push("program");
    else if (j.program && j.program.includes("resumed") && j.print_side === j.side && STREAMS.has(j.state)) parts.push(j.program);
    else if (j.print_side && j.kind === "design" && !PERSON.has(j.state)) parts.push(`${j.print_side} side`);
    parts.push(percent(j));
    if (j.ribbon && j.ribbons) parts.push(`ribbon ${j.ribbon} of ${j.ribbons}`);
    if (j.eta_s !== null && j.eta_s !== undefined && !ENDED.has(j.state)) parts.push(`${duration(j.eta_s)} left`);
    if (j.elapsed_s) parts.push(`${duration(j.elapsed_s)} elapsed`);
  }
  return parts.join(" · ");
}

const ACTIONS = {
  start: (j) => (ENDED.has(j.state) ? "Print again" : ["submitted", "compiling"].includes(j.state) ? "Print when compiled" : "Print"),
  pause: () => "Pause", resume: (j) => (j.state === "interrupted" ? "Resume where it stopped" : "Resume"),
  "frame-ok": () => "Frame is checked", "frame-ready": () => "Fresh frame loaded", cancel: () => "Cancel", delete: () => "Delete",
};

/** The job is queued and waits for the operator to load a fresh stretched frame (the daemon's gate). */
const atGate = (j) => j.state === "ready" && j.start_when_ready && j.stage === "waiting for a fresh frame";

function renderActions(j) {
  const box = $("j-actions");
  const cmds = commandsOf(j).filter((c) => ACTIONS[c] && !(c === "start" && j.start_when_ready && !ENDED.has(j.state)));
  // while a request of this page is in flight, and while a pause is still parking the head (the
  // daemon refuses a resume until then), the buttons wait
  const busy = state.busy.has(j.id);
  const parking = j.state === "paused" && j.stage === "paused";
  const warning = cmds.includes("start") ? printWarningHTML(state.designs.get(j.id)) : "";
  const key = `${j.id}:${cmds.join(",")}:${j.state}:${busy}:${parking}:${warning}`;
  if (box.dataset.key === key) return;
  box.dataset.key = key;
  box.innerHTML = cmds.map((c) => `<button data-action="${c}" ${busy || (parking && c === "resume") ? "disabled" : ""}
    class="${c === "cancel" || c === "delete" ? "warn" : c === "start" || c === "frame-ready" ? "primary" : ""}">${ACTIONS[c](j)}</button>`).join("")
    + optionButtons(j, cmds, busy) + warning;
}
$("j-actions").addEventListener("click", async (e) => {
  const b = e.target.closest("button[data-action]");
  if (!b) return;
  const id = state.route.id, c = b.dataset.action;
  if (c === "delete" && !confirm("Delete this job and its files?")) return;
  if (c === "cancel" && !confirm("Cancel this job? The heaters go off and the head lifts.")) return;
  state.busy.add(id);
  renderActions(state.jobs.get(id));
  try {
    if (c === "delete") {
      await api.call("DELETE", `/jobs/${id}`);
      state.jobs.delete(id);
      location.hash = "#/";
    } else if (c === "frame-ready") {
      // the frame is the printer's, not the job's: the waiting job goes on once it is confirmed
      await api.post("/printer/frame-ready");
      const j = await api.get(`/jobs/${id}`);
      state.jobs.set(j.id, j);
      renderJobPage();
    } else {
      const j = await api.post(`/jobs/${id}/${c}`, b.dataset.body ? JSON.parse(b.dataset.body) : undefined);
      // an event may have brought a newer state already (a started job reaching the frame gate)
      const cur = state.jobs.get(j.id);
      if (!cur || (j.updated ?? 0) >= (cur.updated ?? 0)) state.jobs.set(j.id, { ...cur, ...j });
      renderJobPage();
    }
  } catch (err) { toast(`${b.textContent}: ${err.message}`, "error"); }
  finally {
    state.busy.delete(id);
    if (state.jobs.has(id)) renderJobPage();
  }
});

function alignResultHTML(res) {
  if (!res) return "";
  if (res.refused) {
    const unit = res.refused === "rotation" ? "°" : " mm";
    const numbers = res.value !== undefined ? `The ${esc(res.refused)} is ${mm(res.value, 3)}${unit}; the limit is ${mm(res.limit, 3)}${unit}.` : "";
    return `<div class="result refused"><h3>Alignment refused</h3><p>${esc(res.detail)}</p>
      <p>${numbers} The marks are measured again below; the frame stays back side up.</p></div>`;
  }
  if (res.fit) {
    const f = res.fit;
    const review = res.review && !res.accepted;
    return `<div class="result ${review ? "fitted" : "accepted"}"><h3>${review ? "Check the fit" : "Alignment accepted"}</h3><dl class="facts">
      <dt>Rotation</dt><dd>${mm(f.rotation_deg, 3)}°</dd>
      <dt>Offset</dt><dd>x ${mm(f.offset[0], 3)}, y ${mm(f.offset[1], 3)} mm</dd>
      <dt>Residual</dt><dd>${mm(f.max_residual_mm, 3)} mm max, ${mm(f.rms_mm, 3)} mm rms</dd></dl>
      ${review ? `<p>Within the limits. Accept to print the back side with this correction, or re-seat the
      frame on its pins and measure the marks again.</p>
      <div class="actions"><button id="fit-accept" class="primary huge" type="button">Accept, print the back</button>
      <button id="fit-reseat" class="huge" type="button">Re-seat the frame</button></div>`
      : "<p>The back side is printed with this correction.</p>"}</div>`;
  }
  return "";
}

const marksText = (ms) => (ms.length === 1 ? `mark ${ms[0]}` : `marks ${ms.slice(0, -1).join(", ")} and ${ms[ms.length - 1]}`);

/** After a refused fit or a re-seat: what it means for the frame and the marks (the frame is back
 * side up already: it is never turned over again). */
function reseatText(j) {
  const a = j.alignment;
  if (!a || !a.remeasure?.length) return "";
  if (a.remeasure.length === a.marks) return "Re-seat the frame, back side up (do not turn it over again): every mark is measured again. ";
  const kept = marksText(a.kept);
  return `The frame stays back side up (do not turn it over again). ${kept[0].toUpperCase()}${kept.slice(1)} fitted and ${a.kept.length > 1 ? "are" : "is"} kept: measure ${marksText(a.remeasure)} again. `;
}

/** What to do next, in the page's words (the daemon's instruction names ribbonctl commands). */
function nextText(j) {
  const text = j.next?.instruction || "";
  switch (j.state) {
    case "submitted": case "compiling":
      return j.start_when_ready ? "Compiling; it prints when compiled." : "Compiling; then press Print.";
    case "ready":
      if (atGate(j)) return "Waiting for a fresh frame: load a fresh stretched frame, then press “Fresh frame loaded”. Nothing heats until then.";
      return j.start_when_ready ? text.replace(/^queued/, "Queued") : "Ready to print: press Print.";
    case "paused":
      if (j.stage === "paused") return "Pausing: the head is parking…";
      return "Paused, the head parked. Move it with Manual control if needed, then press Resume (it reheats first).";
    case "printing_front": case "printing_back": return "";       // the progress line says it
    case "awaiting_flip": return "The front is printed: turn the frame over (below).";
    case "aligning": return "Align the back side on the registration marks (below).";
    case "fitted": return "Check the alignment's fit (below): accept it, or re-seat the frame.";
    case "done": return "Done. Print it again, or delete it.";
    case "awaiting_check":
      return j.stage === "check the frame"
        ? "Resuming: check that the frame is seated, the right side up and nothing is in the way, then press “Frame is checked” (the back side's marks are measured again)."
        : "Resuming: the printer is homing and heating…";
    case "interrupted":
      if (commandsOf(j).includes("resume"))
        return "Interrupted. Resume where the print was proven to stand (a ribbon begun and not proven printed is skipped), print it again from the start, or delete it.";
      // falls through
    case "cancelled": case "failed":
      return commandsOf(j).includes("start") ? "Print it again, or delete it."
        : "Nothing to print: the file did not compile (the reason is above). Correct it or choose another file under New job, or delete this job.";
    default: return text;
  }
}

function renderJobPage() {
  const home = state.route.page === "home";
  $("home").hidden = !home;
  $("jobpage").hidden = state.route.page !== "job";
  $("projectpage").hidden = state.route.page !== "project";
  renderProjectPage();
  renderJobs();
  renderTitle();
  placeCamera();
  if (state.route.page !== "job") return;
  const j = state.jobs.get(state.route.id);
  if (!j) { $("j-title").textContent = "No such job"; return; }
  loadDesign(j);
  $("j-title").textContent = j.mesh_name;
  $("j-state").textContent = labelOf(j);
  $("j-state").className = `state ${j.state}`;
  const stage = j.stage && !["compiling", "awaiting_flip", "aligning", "fitted"].includes(j.state) ? j.stage : "";
  $("j-stage").textContent = stage.replace(/_/g, " ") === labelOf(j) ? "" : stage;
  $("j-next").textContent = nextText(j);
  $("j-next").hidden = !$("j-next").textContent;
  $("j-error").hidden = !j.error || ["awaiting_flip", "aligning"].includes(j.state);     // the step says it
  $("j-error").textContent = j.error || "";
  const showProgress = !["submitted", "ready"].includes(j.state) || j.progress > 0;
  $("j-progress").hidden = !showProgress;
  $("j-bar").value = j.progress || 0;
  $("j-progress-text").textContent = progressText(j);
  const stages = $("j-stages");
  stages.hidden = j.state !== "compiling";
  if (j.state === "compiling") {
    const at = STAGES.indexOf(j.stage);
    stages.innerHTML = STAGES.map((s, i) => `<li class="${i < at ? "done" : i === at ? "now" : ""}">${s}</li>`).join("");
  }
  renderActions(j);

  const design = state.designs.get(j.id);
  const axis = axisFrom(j.next?.instruction) ?? axisFrom(state.lastFlipText);
  if (j.state === "awaiting_flip") state.lastFlipText = j.next.instruction;
  // the flip step
  $("flip").hidden = j.state !== "awaiting_flip";
  if (j.state === "awaiting_flip") {
    const res = state.align.get(j.id);
    let words = j.next.instruction.replace(/, then run: ribbonctl flip-done \S+/, ", then press “Frame is flipped”.");
    if (res && res.refused) words = words.replace(/^the alignment was refused \(.*\); (?=the front is printed)/, "");
    $("flip-text").textContent = words.charAt(0).toUpperCase() + words.slice(1);
    const key = `${j.id}:${design ? 1 : 0}:${JSON.stringify(axis)}`;
    if ($("flip-picture").dataset.key !== key) {
      $("flip-picture").dataset.key = key;
      $("flip-picture").innerHTML = design ? flipSVG(design, axis) : "";
    }
    let r = $("flip").querySelector(".result");
    if (r) r.remove();
    if (res && res.refused) $("flip-text").insertAdjacentHTML("afterend", alignResultHTML(res));
  }
  // a step that waits for the operator comes into view when it begins (on a phone it is below the fold)
  if (state.shownState !== `${j.id}:${j.state}`) {
    const step = j.state === "awaiting_flip" ? $("flip") : ["aligning", "fitted"].includes(j.state) ? $("align") : null;
    state.shownState = `${j.id}:${j.state}`;
    if (step) requestAnimationFrame(() => step.scrollIntoView({ block: "start", behavior: "instant" }));
  }
  // the alignment step
  $("align").hidden = !["aligning", "fitted"].includes(j.state) && !(state.align.get(j.id)?.fit && j.state === "printing_back");
  if (!$("align").hidden) {
    const m = /(?:^|\. )mark (\d+) of (\d+):/.exec(j.next?.instruction || "");
    const k = m ? Number(m[1]) : state.alignMark.get(j.id)?.mark;
    const n = m ? Number(m[2]) : state.alignMark.get(j.id)?.marks;
    const ready = j.state === "aligning" && j.waits_for_operator && k;
    $("align-text").textContent = j.state !== "aligning" ? "" : reseatText(j) + (ready
      ? `The head is above mark ${k} of ${n}. Jog the nozzle onto the mark, then press “Nozzle is on the mark”.`
      : `The head is on its way above mark ${k || 1}…`);
    $("align-text").dataset.mark = ready ? String(k) : "";
    $("align-here").disabled = !ready;
    $("align-here").hidden = j.state !== "aligning";
    $("align-jog").hidden = j.state !== "aligning";
    // (after a reload the fit under review, or the refusal, comes with the job)
    const res = state.align.get(j.id) ?? (j.state === "fitted" && j.fit ? { fit: j.fit, review: true }
      : j.state === "aligning" && j.error ? { refused: "fit", detail: j.error.replace(/^alignment refused: /, "") } : undefined);
    const rkey = JSON.stringify([res, j.state]);
    if ($("align-result").dataset.key !== rkey) {
      $("align-result").dataset.key = rkey;
      $("align-result").innerHTML = alignResultHTML(res);
    }
    const akey = `${j.id}:${design ? 1 : 0}:${ready ? k : 0}:${j.state}`;
    if ($("align-picture").dataset.key !== akey) {
      $("align-picture").dataset.key = akey;
      $("align-picture").innerHTML = design && j.state === "aligning" ? backSVG(design, axis, ready ? k : undefined) : "";
    }
  }
  // pictures and the summary
  const files = state.files.get(j.id);
  $("j-pictures").hidden = j.kind !== "design" || !design;
  const highlight = j.state === "aligning" ? (/(?:^|\. )mark (\d+) of/.exec(j.next?.instruction || "") || [])[1] : undefined;
  const lkey = `${j.id}:${design ? 1 : 0}:${highlight}:${j.state === "aligning"}`;
  if ($("j-layout").dataset.key !== lkey) {
    $("j-layout").dataset.key = lkey;
    $("j-layout").innerHTML = design ? layoutSVG(design) : "";
  }
  $("fig-preview").hidden = !files?.preview;
  if (files?.preview && $("img-preview").src !== files.preview) $("img-preview").src = files.preview;
  $("fig-deployed").hidden = !files?.deployed;
  if (files?.deployed && $("img-deployed").src !== files.deployed) $("img-deployed").src = files.deployed;
  $("cap-deployed").textContent = deployedCaption(design?.report?.deployed);
  const gcode = j.kind === "gcode";
  $("j-summary-card").hidden = !design && !gcode;
  $("j-summary-card").querySelector("h2").textContent = gcode ? "Program" : "Design";
  if (design) $("j-summary").innerHTML = summary(design);
  else if (gcode) {
    $("j-summary").innerHTML = `<dt>Commands</dt><dd>${esc(j.lines_total ?? "–")}</dd>` +
      `<dt>Estimated time</dt><dd>${duration(j.estimate_s?.front)}</dd><dt>Runs before this one</dt><dd>${j.runs?.length ?? 0}</dd>`;
  }
  renderOperatorView(j);
}

$("flip-done").addEventListener("click", async () => {
  const id = state.route.id;
  $("flip-done").disabled = true;
  try {
    state.align.delete(id);
    const j = await api.post(`/jobs/${id}/flip-done`);
    state.jobs.set(j.id, j);
    renderJobPage();
  } catch (e) { toast(`Frame is flipped: ${e.message}`, "error"); }
  finally { $("flip-done").disabled = false; }
});

$("align-here").addEventListener("click", async () => {
  const id = state.route.id;
  const pad = $("align-jog");
  // the jogs queued on the pad reach the printer first
  while (pad.dataset.pending !== "0") await new Promise((r) => setTimeout(r, 50));
  $("align-here").disabled = true;
  try {
    // review: the last mark's fit waits for Accept or Re-seat (state fitted)
    const res = await api.post(`/jobs/${id}/align`, { here: true, review: true });
    if (res.fit) state.align.set(id, res);
    else {
      if (state.align.get(id)?.refused) state.align.delete(id);     // acted on: the refusal is old news
      toast(`Mark ${res.mark} measured (off by ${mm(res.offset[0], 2)}, ${mm(res.offset[1], 2)} mm).`);
    }
  } catch (e) {
    if (e.data && e.data.refused) state.align.set(id, { ...e.data });
    else toast(`Nozzle is on the mark: ${e.message}`, "error");
  }
  renderJobPage();
});

$("align-result").addEventListener("click", async (ev) => {
  const button = ev.target.closest("#fit-accept, #fit-reseat");
  if (!button) return;
  const id = state.route.id;
  const accept = button.id === "fit-accept";
  button.disabled = true;
  const shown = state.align.get(id) ?? { fit: state.jobs.get(id)?.fit, review: true };
  try {
    const j = await api.post(`/jobs/${id}/${accept ? "accept" : "re-seat"}`);
    state.jobs.set(j.id, j);
    if (accept && shown.fit) state.align.set(id, { ...shown, accepted: true });
    else state.align.delete(id);
  } catch (e) { toast(`${button.textContent}: ${e.message}`, "error"); button.disabled = false; }
  renderJobPage();
});

// ------------------------------------------------------------------ what the operator sees (issue 22)

const TEMPS_SPAN_S = 1800;
/** States in which a job's page shows the temperatures: it heats, prints, or is about to. */
const HOT = new Set([...STREAMS, "paused", "awaiting_check"]);

/** A job's state in words; a plain G-code job prints a program, not a front. */
function labelOf(j) {
  if (j.kind === "gcode" && j.state === "printing_front") return "printing program";
  return LABEL[j.state] ?? j.state;
}

/** The chart starts from the daemon's last 30 minutes, not empty. */
async function loadTemperatures() {
  const history = await api.get("/printer/temperatures");
  const since = state.temps.length ? state.temps[0].t : Infinity;
  state.temps = [...history.samples.filter((p) => p.t < since), ...state.temps];
  renderPrinter();
}

/** The tab's title: the job of the page (or the one holding the printer) with its state and progress. */
function renderTitle() {
  const shown = state.route.page === "job" ? state.jobs.get(state.route.id)
    : [...state.jobs.values()].find((j) => STREAMS.has(j.state) || j.state === "paused");
  if (!shown) { document.title = "ribbond"; return; }
  const progress = STREAMS.has(shown.state) || shown.state === "compiling" || shown.state === "paused";
  document.title = `${progress ? `${percent(shown)} ` : ""}${labelOf(shown)} — ribbond`;
}

function renderTemps(j) {
  const h = state.printer?.heaters || {};
  const show = HOT.has(j.state) && (h.T || h.B);
  $("j-temps").hidden = !show;
  if (show) $("j-temps").textContent = `Nozzle ${heater(h.T)} · Bed ${heater(h.B)}`;
}

function renderVerdict(j) {
  const lines = j.verdict || [];
  const box = $("j-verdict");
  box.hidden = !lines.length;
  const key = JSON.stringify(lines);
  if (box.dataset.key === key) return;
  box.dataset.key = key;
  // the bad lines in red; "where the shape is lost" (issue 34) set apart, its step to look at in red
  const cls = (l) => [/^where the shape is lost/.test(l) ? "chain" : "",
    /OUTSIDE|NOT a sign|clamped|step to look at/.test(l) ? "bad" : ""].filter(Boolean).join(" ");
  box.innerHTML = lines.map((l) => `<li class="${cls(l)}">${esc(l)}</li>`).join("");
}

// ------------------------------------------------------------------ the prediction (issue 23)

/** The picture's caption: what it shows, and whether the shape is reached; the figures are in the card. */
function deployedCaption(d) {
  if (!d) return "Predicted deployed shape";
  if (d.reached === undefined) return "Predicted deployed shape";
  return `Predicted deployed shape: ${d.reached ? "takes" : "does NOT take"} the target's shape`;
}

const range = (r, d = 1) => (Array.isArray(r) ? `${mm(r[0], d)}–${mm(r[1], d)}` : "–");

/** The figures of report.deployed, intrinsic first, the mean deviation last; format 2 has only the deviations. */
function predictionFacts(d) {
  const rows = [];
  const add = (k, v) => rows.push(`<dt>${esc(k)}</dt><dd>${esc(v)}</dd>`);
  const k = d.total_gaussian_curvature;
  if (k) add("Total Gaussian curvature", `${mm(k.predicted, 2)} predicted, ${mm(k.target, 2)} target`);
  if (d.area_ratio !== undefined && d.area_ratio !== null) add("Area, predicted / target", mm(d.area_ratio, 3));
  const sp = d.spread;
  if (sp) add("Spread over releases", `mean ${range(sp.mean)} %, max ${range(sp.max)} % (${sp.releases} releases)`);
  const dev = d.deviation_pct || {};
  add("Deviation from the target", `${mm(dev.mean, 1)} % mean, ${mm(dev.p99, 1)} % p99, ${mm(dev.max, 1)} % max of the diagonal`);
  add("Model", `${d.model || "homogenized"}${d.table ? `, table ${d.table}` : ""}; ${d.faces ?? "–"} faces, ${mm(d.time_s, 1)} s`);
  return rows.join("");
}

let tablesAsked = false;
async function loadTables() {
  if (tablesAsked) return;
  tablesAsked = true;
  try {
    const tables = await api.get("/tables");
    $("pr-table").innerHTML = `<option value="">the design's</option>` +
      tables.map((t) => `<option value="${esc(t.name)}">${esc(t.name)}</option>`).join("");
  } catch { tablesAsked = false; }
}

function renderPrediction(j) {
  const design = state.designs.get(j.id);
  const d = design?.report?.deployed;
  const p = j.prediction;
  const box = $("j-prediction");
  box.hidden = j.kind !== "design" || !design || (!d && !p);
  if (box.hidden) return;
  loadTables();
  // a prediction that just ended: read the design again (its report and picture changed)
  const seen = state.predicted.get(j.id);
  state.predicted.set(j.id, p?.state);
  if (seen === "running" && p?.state === "done") { reloadDesign(j); return; }
  const reached = $("pr-reached");
  reached.hidden = !d || d.reached === undefined;
  if (d && d.reached !== undefined) {
    reached.textContent = d.reached ? "Will take the target's shape" : "Will NOT take the target's shape";
    reached.className = `reached ${d.reached ? "yes" : "no"}`;
  }
  $("pr-line").hidden = !d?.verdict;
  $("pr-line").textContent = d?.verdict || "";
  $("pr-facts").innerHTML = d ? predictionFacts(d) : "";
  $("pr-old").hidden = !d || d.reached !== undefined;
  const running = p?.state === "running";
  const blocked = ["submitted", "compiling"].includes(j.state) || STREAMS.has(j.state) || ["paused", "awaiting_flip",
    "aligning", "fitted", "awaiting_check"].includes(j.state);
  $("pr-run").disabled = running || blocked || state.busy.has(`predict:${j.id}`);
  $("pr-run").title = blocked ? "not while the job compiles or holds the printer" : "";
  $("pr-progress").hidden = !running;
  if (running) {
    $("pr-bar").value = p.fraction || 0;
    $("pr-text").textContent = `${Math.round((p.fraction || 0) * 100)} % · ${p.message || ""}`;
  }
  $("pr-error").hidden = p?.state !== "failed";
  $("pr-error").textContent = p?.state === "failed" ? `The prediction failed: ${p.error}` : "";
}

function reloadDesign(j) {
  for (const url of Object.values(state.files.get(j.id) || {})) if (url) URL.revokeObjectURL(url);
  state.designs.delete(j.id);
  state.files.delete(j.id);
  quiet(loadDesign(j));
}

$("pr-run").addEventListener("click", async () => {
  const id = state.route.id;
  const key = `predict:${id}`;
  const body = {};
  if ($("pr-table").value) body.table = $("pr-table").value;
  state.busy.add(key);
  $("pr-run").disabled = true;
  try {
    const j = await api.post(`/jobs/${encodeURIComponent(id)}/predict`, body);
    state.jobs.set(j.id, j);
    state.predicted.set(j.id, "running");
  } catch (e) { toast(`Predict again: ${e.message}`, "error"); }
  finally { state.busy.delete(key); renderJobPage(); }
});

function renderFiles(j) {
  const shown = downloads(j, state.designs.get(j.id));
  const box = $("j-files");
  box.hidden = !shown.length;
  const key = `${j.id}:${shown.join(",")}`;
  if (box.dataset.key === key) return;
  box.dataset.key = key;
  box.innerHTML = "Download: " + shown.map((n) =>
    `<a href="/jobs/${encodeURIComponent(j.id)}/files/${n}" download="${esc(j.id)}-${n}" data-file="${n}">${n}</a>`).join("");
}
// with a token the files need the header: fetched, then saved from an object URL
$("j-files").addEventListener("click", async (e) => {
  const a = e.target.closest("a[data-file]");
  if (!a || !api.token()) return;
  e.preventDefault();
  const url = await api.fileURL(state.route.id, a.dataset.file);
  if (!url) { toast(`${a.dataset.file}: not there (yet)`, "error"); return; }
  const save = Object.assign(document.createElement("a"), { href: url, download: a.getAttribute("download") });
  save.click();
  setTimeout(() => URL.revokeObjectURL(url), 10000);
});

/** Resume options the daemon takes: reprint the ribbon begun (interrupted), keep the alignment (frame not moved). */
function optionButtons(j, cmds, busy) {
  const extra = [];
  if (j.state === "interrupted" && cmds.includes("resume"))
    extra.push(["resume", { partial: "reprint" }, "Resume, reprinting the ribbon begun"]);
  if (cmds.includes("frame-ok") && j.side === "back" && j.correction)
    extra.push(["frame-ok", { keep_alignment: true }, "Frame not moved: keep the alignment"]);
  return extra.map(([c, body, text]) => `<button data-action="${c}" data-body='${esc(JSON.stringify(body))}'
    ${busy ? "disabled" : ""}>${text}</button>`).join("");
}

const shapeCard = new ShapeCard();
function renderOperatorView(j) {
  shapeCard.update(j, state.designs.get(j.id));
  renderPrediction(j);
  renderVerdict(j);
  renderTemps(j);
  renderFiles(j);
  renderSnapshots(j);
}

// ------------------------------------------------------------------ the camera (issue 27)

const camera = new CameraView($("camera-img"), $("camera-note"));
/** Job states in which the camera is shown: the printer heats or prints the job, or its back is aligned. */
const WATCHED = new Set([...STREAMS, "aligning", "fitted"]);
const ALIGNING = new Set(["aligning", "fitted"]);
const SNAP_CAPTION = { "snapshot-front.jpg": "The front, printed", "snapshot-back.jpg": "The back, printed",
  "snapshot-program.jpg": "The program, printed" };

async function loadCamera() {
  state.camera = await api.get("/camera");
  placeCamera();
}

/** The camera's card where the operator looks: in the alignment step beside the jog pad, under the
 * job printing, or under the printer at home while a job prints; hidden (the stream closed) otherwise. */
function placeCamera() {
  const card = $("camera"), page = state.route.page;
  const j = page === "job" ? state.jobs.get(state.route.id) : null;
  let slot = null;
  if (state.camera?.configured) {
    if (j && ALIGNING.has(j.state)) slot = $("align-camera");
    else if (j && WATCHED.has(j.state)) slot = $("jobpage").querySelector("section.card");
    else if (page === "home" && [...state.jobs.values()].some((x) => WATCHED.has(x.state))) slot = $("printer");
  }
  card.hidden = !slot;
  camera.watch(!!slot);
  if (!slot) return;
  const inset = slot === $("align-camera");
  card.classList.toggle("inset", inset);
  if (inset ? card.parentElement !== slot : slot.nextElementSibling !== card) {
    if (inset) slot.append(card); else slot.after(card);
  }
}

/** The camera's snapshots kept at each side's end, fetched with the token as the other files are. */
function renderSnapshots(j) {
  const snaps = j.snapshots || [];
  $("j-snapshots").hidden = !snaps.length;
  const box = $("j-snaps");
  const key = `${j.id}:${snaps.map((s) => `${s.name}@${s.taken}`).join(",")}`;
  if (box.dataset.key === key) return;
  box.dataset.key = key;
  box.innerHTML = snaps.map((s) => `<figure><img data-snap="${esc(s.name)}" alt="${esc(SNAP_CAPTION[s.name] || s.name)}">
    <figcaption>${esc(SNAP_CAPTION[s.name] || s.name)} · ${when(s.taken)}</figcaption></figure>`).join("");
  for (const img of box.querySelectorAll("img[data-snap]")) {
    quiet(api.fileURL(j.id, img.dataset.snap).then((url) => {
      if (!url) return;
      img.addEventListener("load", () => URL.revokeObjectURL(url), { once: true });
      img.src = url;
    }));
  }
}

// ------------------------------------------------------------------ live events

function onEvent(type, ev) {
  if (type === "project" && ev.project) {
    state.projects.set(ev.project.id, ev.project);
    renderProjects();
  } else if (type === "job" && ev.job) {
    state.jobs.set(ev.job.id, ev.job);
    if (ev.job.project) reloadProjectSoon(ev.job.project);
    if (ev.progress_event) state.compileInfo.set(ev.job.id, ev.progress_event);
  } else if (type === "progress" && state.jobs.has(ev.job_id)) {
    const j = state.jobs.get(ev.job_id);
    const { type: _t, job_id: _id, side, line, lines, ...info } = ev;
    state.jobs.set(ev.job_id, { ...j, ...info, last_acked_line: line, lines_total: lines, print_side: info.print_side ?? side });
  } else if (type === "deleted") {
    state.jobs.delete(ev.job_id);
    for (const p of state.projects.values()) if ((p.panels || []).some((q) => q.job_id === ev.job_id)) reloadProjectSoon(p.id);
  } else if (type === "alignment") {
    state.alignMark.set(ev.job_id, ev);
  } else if (type === "notice") {
    toast(ev.message);
  } else if (type === "frame" && ev.frame) {
    if (state.printer) state.printer = { ...state.printer, frame: ev.frame };
    renderPrinter();
  } else if (type === "notification" && ev.notification) {
    takeDelivery($("notify-line"), ev.notification);
    return;
  } else if (type === "printer" && ev.printer) {
    takePrinter(ev.printer);
    if (state.route.page === "job" && state.jobs.has(state.route.id)) renderTemps(state.jobs.get(state.route.id));
    return;
  }
  renderJobPage();
}

let events = null;
function restartEvents() {
  if (events) events.abort();
  events = new AbortController();
  const signal = events.signal;
  (async () => {
    while (!signal.aborted) {
      try {
        await api.events(onEvent, () => {
          state.live = true; $("live").textContent = "live"; $("live").className = "pill ready"; quiet(loadJobs()); quiet(loadProjects()); quiet(loadNotify($("notify-line")));
        }, signal);
      } catch (e) {
        if (signal.aborted) return;
      }
      state.live = false;
      $("live").textContent = "offline";
      $("live").className = "pill quiet";
      await new Promise((r) => setTimeout(r, 2000));
    }
  })();
}

// ------------------------------------------------------------------ routing and start

function route() {
  const pm = /^#\/project\/(.+)$/.exec(location.hash);
  if (pm) {
    state.route = { page: "project", id: decodeURIComponent(pm[1]) };
    quiet(loadProject(state.route.id));
    renderJobPage();
    window.scrollTo(0, 0);
    return;
  }
  if (location.hash === "#/new") {                 // the bar's "New job": the form, in view (a phone's is far below)
    state.route = { page: "home" };
    renderJobPage();
    $("submit").scrollIntoView({ block: "start" });
    $("file").focus({ preventScroll: true });
    return;
  }
  const m = /^#\/job\/(.+)$/.exec(location.hash);
  state.route = m ? { page: "job", id: decodeURIComponent(m[1]) } : { page: "home" };
  if (m && !state.jobs.has(state.route.id)) quiet(api.get(`/jobs/${state.route.id}`).then((j) => { state.jobs.set(j.id, j); renderJobPage(); }));
  renderJobPage();
  window.scrollTo(0, 0);
}
window.addEventListener("hashchange", () => { $("toast").hidden = true; route(); });
$("new-job").addEventListener("click", (e) => { if (location.hash === "#/new") { e.preventDefault(); route(); } });

function refreshAll() { quiet(loadJobs()); quiet(loadProjects()); quiet(loadTemperatures()); quiet(loadCamera()); pollPrinter(); }

async function main() {
  try {
    await api.get("/printer");
  } catch (e) {
    if (e.status === 401) await askToken(api.token() ? "The stored token was refused." : "");
  }
  route();
  restartEvents();
  refreshAll();
  // the printer's status comes with the events; read it only while they are down
  setInterval(() => { if (!state.live) pollPrinter(); }, 2000);
  setInterval(() => { for (const j of state.jobs.values()) if (!ENDED.has(j.state)) { renderJobs(); break; } }, 5000);
}
main();
