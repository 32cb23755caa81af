// The notifications line on the printer card: what was last sent to the operator's services and
// what last failed (and why), from GET /notifications, kept live by the "notification" events.
import * as api from "./api.js";

let view = null;

const clock = (t) => new Date(t * 1000).toLocaleTimeString([], { hour: "2-digit", minute: "2-digit" });

/** The line's parts as [text, kind] pairs (kind "error": the last failure is not behind the last send). */
export function notifyParts(v) {
  if (!v || !v.enabled) return [];
  const parts = [["Notifications: ", ""]];
  const sent = v.last_sent, failed = v.last_failed;
  parts.push([sent ? `last sent ${clock(sent.at)} “${sent.title}”` : "none sent yet", "muted"]);
  if (failed) {
    // red while it concerns the latest notice (or a later one); muted once a later one went out
    const kind = !sent || failed.id >= sent.id ? "error" : "muted";
    parts.push([`${failed.status} ${clock(failed.at)} to ${failed.url}: ${failed.error || "no reason given"}`, `${kind} fail`]);
  }
  return parts;
}

export function renderNotify(el) {
  const parts = notifyParts(view);
  el.hidden = parts.length === 0;
  el.replaceChildren(...parts.map(([text, kind]) => Object.assign(document.createElement("span"),
    { textContent: text, className: kind })));
}

/** Read GET /notifications (at start and whenever the events reconnect). */
export async function loadNotify(el) {
  view = await api.get("/notifications");
  renderNotify(el);
}

/** A "notification" event: one delivery, sent or not. */
export function takeDelivery(el, d) {
  if (!view) return;
  if (d.status === "sent") { view.last_sent = d; view.sent += 1; } else { view.last_failed = d; view.failed += 1; }
  renderNotify(el);
}
