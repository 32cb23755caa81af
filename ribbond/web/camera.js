// The printer's camera (issue 27). The daemon serves it as /camera/stream: MJPEG, one JPEG per part,
// each with its Content-Length. It is read with fetch, as /events is (the token goes in the header,
// which an <img src> cannot send), and each frame is shown in the <img> as an object URL. The stream
// is read only while the panel is shown and the tab visible: hidden, the request is aborted, and the
// daemon stops reading the camera once no page asks for frames.
import { token } from "./api.js";

const CRLF2 = [13, 10, 13, 10];
const RETRY_MS = 3000;

function indexOf(buf, pattern, from = 0) {
  outer: for (let i = from; i <= buf.length - pattern.length; i++) {
    for (let k = 0; k < pattern.length; k++) if (buf[i + k] !== pattern[k]) continue outer;
    return i;
  }
  return -1;
}

function join(a, b) {
  const out = new Uint8Array(a.length + b.length);
  out.set(a);
  out.set(b, a.length);
  return out;
}

/** Read the daemon's MJPEG body until it ends or ``signal`` aborts; ``onFrame(bytes)`` per JPEG. */
async function readFrames(signal, onFrame) {
  const headers = token() ? { Authorization: `Bearer ${token()}` } : {};
  const r = await fetch("/camera/stream", { headers, signal, cache: "no-store" });
  if (!r.ok || !r.body) {
    let detail = `HTTP ${r.status}`;
    try { detail = (await r.json()).detail || detail; } catch { /* not JSON */ }
    throw new Error(detail);
  }
  const reader = r.body.getReader();
  let buf = new Uint8Array(0);
  for (;;) {
    const { value, done } = await reader.read();
    if (done) throw new Error("the camera's stream ended");
    buf = join(buf, value);
    for (;;) {
      const end = indexOf(buf, CRLF2);
      if (end < 0) break;
      const head = new TextDecoder().decode(buf.subarray(0, end));
      const m = /content-length:\s*(\d+)/i.exec(head);
      if (!m) throw new Error("a camera frame without its length");
      const start = end + 4, stop = start + Number(m[1]);
      if (buf.length < stop) break;
      onFrame(buf.slice(start, stop));
      buf = buf.slice(stop);
    }
  }
}

/** The camera panel: ``watch(on)`` starts or stops the stream; frames go to ``img``, words to ``note``. */
export class CameraView {
  constructor(img, note) {
    this.img = img;
    this.note = note;
    this.ctrl = null;
    this.wanted = false;
    this.next = null;            // the newest frame not yet shown (older ones are dropped)
    this.painting = false;
    this.shown = 0;
    img.addEventListener("load", () => this.painted());
    img.addEventListener("error", () => this.painted());
    document.addEventListener("visibilitychange", () => this.watch(this.wanted));
  }

  watch(on) {
    this.wanted = on;
    const run = on && !document.hidden;
    if (run && !this.ctrl) this.start();
    else if (!run && this.ctrl) { this.ctrl.abort(); this.ctrl = null; }
  }

  start() {
    const ctrl = (this.ctrl = new AbortController());
    (async () => {
      while (!ctrl.signal.aborted) {
        this.note.textContent = this.shown ? "reconnecting…" : "connecting to the camera…";
        this.connecting = true;
        try {
          await readFrames(ctrl.signal, (jpeg) => this.frame(jpeg));
        } catch (e) {
          if (ctrl.signal.aborted) return;
          this.note.textContent = `The camera is not answering (${e.message}); trying again…`;
        }
        await new Promise((r) => setTimeout(r, RETRY_MS));
      }
    })();
  }

  frame(jpeg) {
    if (this.connecting) { this.note.textContent = "live"; this.connecting = false; }
    this.shown += 1;
    this.next = jpeg;
    if (!this.painting) this.paint();
  }

  paint() {
    const jpeg = this.next;
    this.next = null;
    this.painting = true;
    this.old = this.img.src;
    this.img.src = URL.createObjectURL(new Blob([jpeg], { type: "image/jpeg" }));
  }

  painted() {
    if (this.old && this.old.startsWith("blob:")) URL.revokeObjectURL(this.old);
    this.old = null;
    this.painting = false;
    this.img.dataset.frames = String(this.shown);
    if (this.next) this.paint();
  }
}
