// Adjusting a print (issue 36): the feed override (M220), the flow (M221) and the heater targets,
// while a job prints or between prints, through POST /printer/adjust (the console's checker: the
// profile's [adjust] ranges and temperature limits; a refusal names the limit). The speed and flow
// shown are the ones the printer reported back (M220 / M221 without words), not the ones asked for.
import * as api from "./api.js";

const FIELDS = [
  // [body key, label, unit, the limits from the profile's status]
  ["speed", "Speed", "%", (a) => a.speed_percent],
  ["flow", "Flow", "%", (a) => a.flow_percent],
  ["nozzle", "Nozzle", "°C", (a, printing) => [printing ? a.nozzle_min : 0, a.nozzle_max]],
  ["bed", "Bed", "°C", (a) => [0, a.bed_max]],
];

/** Build the panel's form in ``el`` once; ``onDone(result)`` gets the daemon's answer. */
export function initAdjust(el, onDone, onError) {
  el.querySelector("form").innerHTML = FIELDS.map(([key, label, unit]) => `
    <label class="adjust-field">${label}, ${unit}
      <span class="row"><input id="adj-${key}" type="number" step="any" inputmode="decimal">
      <button type="submit" data-key="${key}">Set</button></span></label>`).join("");
  el.querySelector("form").addEventListener("submit", async (e) => {
    e.preventDefault();
    const key = e.submitter?.dataset.key;
    const input = key && el.querySelector(`#adj-${key}`);
    if (!input || input.value === "") return;
    const out = el.querySelector(".adjust-out");
    try {
      const r = await api.post("/printer/adjust", { [key]: Number(input.value) });
      out.className = "adjust-out muted";
      out.textContent = `Sent ${r.answers.map((a) => a.command).join(", ")}` +
        (r.printing ? ` beside job ${r.printing}'s program.` : ".");
      input.value = "";
      onDone(r);
    } catch (err) {
      out.className = "adjust-out error";
      out.textContent = err.message;
      if (onError) onError(err);
    }
  });
}

/** Show the printer's reported speed and flow and the limits; enabled while the printer is live. */
export function renderAdjust(el, printer, printingJob) {
  const live = ["ready", "paused", "streaming"].includes(printer?.state);
  const limits = printer?.profile?.adjust;
  el.hidden = !live || !limits;
  if (el.hidden) return;
  const pct = (v) => (v === null || v === undefined ? "–" : `${v} %`);
  el.querySelector(".adjust-now").textContent =
    `Speed ${pct(printer.speed_percent)} · flow ${pct(printer.flow_percent)}` +
    (printer.speed_percent === null || printer.speed_percent === undefined ? " (the printer reports them once one is set)" : "");
  el.querySelector(".adjust-when").textContent = printingJob
    ? `Adjusts the print of ${printingJob.mesh_name || printingJob.id} now (no moves while it prints).`
    : "Between prints: the printer keeps these for the next job until changed or restarted.";
  for (const [key, , unit, range] of FIELDS) {
    const [lo, hi] = range(limits, Boolean(printingJob));
    const input = el.querySelector(`#adj-${key}`);
    input.min = String(lo);
    input.max = String(hi);
    input.placeholder = `${lo}–${hi}`;
    input.title = `${lo}–${hi} ${unit}`;
  }
}
