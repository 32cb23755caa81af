// The job list's order and times, and a job's files to download (issue 36 item 11): jobs that still
// need the printer or the operator come first, a re-run among them (it used to sink below the failed
// jobs, by its old creation time); a re-run's duration counts from its start, not the job's creation.
import * as api from "./api.js";

export const ENDED = new Set(["done", "cancelled", "failed", "interrupted"]);

/** When the job's current run began: the last "started again" transition of a re-run (read once per
 * job and run count from GET /jobs/{id}/transitions), else the job's creation. */
const restarts = new Map();
export function runStart(j, onLoaded) {
  if (!j.runs?.length) return j.created;
  const key = `${j.id}:${j.runs.length}`;
  if (!restarts.has(key)) {
    restarts.set(key, null);
    api.get(`/jobs/${encodeURIComponent(j.id)}/transitions`).then((ts) => {
      const again = ts.filter((t) => /^started again/.test(t.reason || "")).pop();
      restarts.set(key, again ? again.at : j.created);
      onLoaded();
    }).catch(() => restarts.delete(key));
  }
  return restarts.get(key) ?? null;
}

/** Active jobs first (the newest run first), then the ended ones (the latest to end first). */
export function sortJobs(jobs, onLoaded) {
  const active = (j) => !ENDED.has(j.state);
  const when = (j) => (active(j) ? runStart(j, onLoaded) ?? j.updated : j.updated);
  return [...jobs].sort((a, b) => (active(b) - active(a)) || (when(b) - when(a)) || (b.created - a.created));
}

/** An ended job's duration (s): from its run's start to its end; null while the start is read. */
export function endedDuration(j, onLoaded) {
  const start = runStart(j, onLoaded);
  return start === null ? null : j.updated - start;
}

/** A job's files to download: the design's (its target and prediction, the previews, the programs
 * that have lines) or the G-code job's program. */
export function downloads(j, design) {
  if (j.kind === "gcode") return ["program.gcode"];
  if (!j.design_dir) return [];
  const pr = design?.report?.print || {};
  const predicted = !!design?.report?.deployed;
  return ["design.json", "combined.gcode", "front.gcode", "back.gcode", "target.obj", "deployed.obj",
    "preview.png", "preview.svg", "deployed.png"].filter((n) => {
    if (/^(front|back)\.gcode$/.test(n)) return !!pr[n.split(".")[0]]?.lines;
    if (/^deployed\./.test(n)) return predicted;
    return true;
  });
}
