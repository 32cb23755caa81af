// The daemon's REST API, the same one ribbonctl uses; the token (when the daemon asks for one) goes
// in the Authorization header only, never in a URL. Server-sent events are read with fetch (an
// EventSource cannot send the header).

const KEY = "ribbond.token";

export function token() { return localStorage.getItem(KEY); }
export function setToken(t) { if (t) localStorage.setItem(KEY, t); else localStorage.removeItem(KEY); }

export class ApiError extends Error {
  constructor(status, data) {
    const detail = data && data.detail;
    super(typeof detail === "string" ? detail : (detail ? JSON.stringify(detail) : `HTTP ${status}`));
    this.status = status;
    this.data = data || {};
  }
}

let onUnauthorized = () => {};
export function whenUnauthorized(fn) { onUnauthorized = fn; }

function headers(extra = {}) {
  const h = { ...extra };
  const t = token();
  if (t) h.Authorization = `Bearer ${t}`;
  return h;
}

/** One request; resolves to the JSON answer (or null), rejects with an ApiError. */
export async function call(method, path, body) {
  const init = { method, headers: headers(body === undefined ? {} : { "Content-Type": "application/json" }) };
  if (body !== undefined) init.body = JSON.stringify(body);
  const r = await fetch(path, init);
  const text = await r.text();
  let data = null;
  try { data = text ? JSON.parse(text) : null; } catch { data = { detail: text }; }
  if (r.status === 401) onUnauthorized();
  if (!r.ok) throw new ApiError(r.status, data);
  return data;
}

export const get = (p) => call("GET", p);
export const post = (p, b) => call("POST", p, b === undefined ? undefined : b);

/** A job file as an object URL (images need the header too), or null when it is not there. */
export async function fileURL(jobId, name, kind = "jobs") {
  const r = await fetch(`/${kind}/${encodeURIComponent(jobId)}/files/${name}`, { headers: headers() });
  if (!r.ok) return null;
  return URL.createObjectURL(await r.blob());
}

/** A job file's text (an OBJ), or null when it is not there. */
export async function fileText(jobId, name) {
  const r = await fetch(`/jobs/${encodeURIComponent(jobId)}/files/${name}`, { headers: headers() });
  return r.ok ? r.text() : null;
}

export async function fileJSON(jobId, name) {
  const r = await fetch(`/jobs/${encodeURIComponent(jobId)}/files/${name}`, { headers: headers() });
  return r.ok ? r.json() : null;
}

/** POST a multipart form with upload progress (fetch has none): resolves to the JSON answer. */
export function upload(path, form, onProgress) {
  return new Promise((resolve, reject) => {
    const xhr = new XMLHttpRequest();
    xhr.open("POST", path);
    const t = token();
    if (t) xhr.setRequestHeader("Authorization", `Bearer ${t}`);
    xhr.upload.onprogress = (e) => { if (e.lengthComputable) onProgress(e.loaded / e.total); };
    xhr.onload = () => {
      let data = null;
      try { data = JSON.parse(xhr.responseText); } catch { data = { detail: xhr.responseText }; }
      if (xhr.status === 401) onUnauthorized();
      if (xhr.status >= 200 && xhr.status < 300) resolve(data); else reject(new ApiError(xhr.status, data));
    };
    xhr.onerror = () => reject(new ApiError(0, { detail: "the daemon did not answer (network error)" }));
    xhr.send(form);
  });
}

/** Read /events until ``signal`` aborts; ``onEvent(type, data)`` for each event, ``onOpen`` once
 * the stream is up. Rejects when the stream ends (the caller reconnects). */
export async function events(onEvent, onOpen, signal) {
  const r = await fetch("/events", { headers: headers({ Accept: "text/event-stream" }), signal, cache: "no-store" });
  if (r.status === 401) onUnauthorized();
  if (!r.ok || !r.body) throw new ApiError(r.status, { detail: "no event stream" });
  onOpen();
  const reader = r.body.pipeThrough(new TextDecoderStream()).getReader();
  let buffer = "";
  for (;;) {
    const { value, done } = await reader.read();
    if (done) throw new Error("the event stream ended");
    buffer += value;
    let cut;
    while ((cut = buffer.indexOf("\n\n")) >= 0) {
      const block = buffer.slice(0, cut);
      buffer = buffer.slice(cut + 2);
      let type = "message";
      const data = [];
      for (const line of block.split("\n")) {
        if (line.startsWith("event:")) type = line.slice(6).trim();
        else if (line.startsWith("data:")) data.push(line.slice(5).trimStart());
      }
      if (data.length) {
        try { onEvent(type, JSON.parse(data.join("\n"))); } catch (e) { console.error("event", e); }
      }
    }
  }
}
