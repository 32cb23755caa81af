// The predicted shape in 3D (issue 36 item 11): the target and the prediction of a design in one
// WebGL view, turned by dragging (mouse or one finger), zoomed by the wheel or a pinch, the
// prediction coloured by its distance to the target (viridis, as deployed.png) with its legend.
// Plain WebGL (2, else 1 with 32-bit indices), no library: a mesh, normals and two shaders.

/** Viridis at 9 stops (matplotlib's table, sampled at 0, 1/8, … 1): the colours of deployed.png. */
const VIRIDIS = [[68, 1, 84], [71, 44, 122], [59, 81, 139], [44, 113, 142], [33, 144, 141],
  [39, 173, 129], [92, 200, 99], [170, 220, 50], [253, 231, 37]];

/** The colour of t in [0, 1] (clamped) as [r, g, b] in 0–1. */
export function viridis(t) {
  const x = Math.min(1, Math.max(0, Number.isFinite(t) ? t : 0)) * (VIRIDIS.length - 1);
  const i = Math.min(VIRIDIS.length - 2, Math.floor(x)), f = x - i;
  return VIRIDIS[i].map((c, k) => (c + f * (VIRIDIS[i + 1][k] - c)) / 255);
}

/** The CSS gradient of the legend (the same stops). */
export const viridisCSS = () => `linear-gradient(to right, ${VIRIDIS.map((c, i) =>
  `rgb(${c.join(",")}) ${(100 * i) / (VIRIDIS.length - 1)}%`).join(", ")})`;

/** An OBJ's vertices (Float32Array, 3 a vertex) and triangles (Uint32Array, 3 a face; polygons
 * fanned, 1-based and negative indices resolved). Throws naming the line of a bad face. */
export function parseOBJ(text) {
  const v = [], f = [];
  const lines = text.split("\n");
  for (let n = 0; n < lines.length; n++) {
    const s = lines[n].trim();
    if (s.startsWith("v ")) {
      const p = s.split(/\s+/);
      v.push(Number(p[1]), Number(p[2]), Number(p[3]));
    } else if (s.startsWith("f ")) {
      const count = v.length / 3;
      const idx = s.split(/\s+/).slice(1).map((w) => { const k = parseInt(w, 10); return k < 0 ? count + k : k - 1; });
      if (idx.length < 3 || idx.some((k) => !(k >= 0 && k < count))) throw new Error(`OBJ line ${n + 1}: a face with a vertex the file does not have`);
      for (let k = 1; k + 1 < idx.length; k++) f.push(idx[0], idx[k], idx[k + 1]);
    }
  }
  if (!f.length) throw new Error("OBJ: no faces");
  return { positions: Float32Array.from(v), faces: Uint32Array.from(f) };
}

/** Area-weighted vertex normals (Float32Array, 3 a vertex). */
function vertexNormals(P, F) {
  const N = new Float32Array(P.length);
  for (let t = 0; t < F.length; t += 3) {
    const a = 3 * F[t], b = 3 * F[t + 1], c = 3 * F[t + 2];
    const ux = P[b] - P[a], uy = P[b + 1] - P[a + 1], uz = P[b + 2] - P[a + 2];
    const wx = P[c] - P[a], wy = P[c + 1] - P[a + 1], wz = P[c + 2] - P[a + 2];
    const nx = uy * wz - uz * wy, ny = uz * wx - ux * wz, nz = ux * wy - uy * wx;
    for (const i of [a, b, c]) { N[i] += nx; N[i + 1] += ny; N[i + 2] += nz; }
  }
  for (let i = 0; i < N.length; i += 3) {
    const l = Math.hypot(N[i], N[i + 1], N[i + 2]) || 1;
    N[i] /= l; N[i + 1] /= l; N[i + 2] /= l;
  }
  return N;
}

/** Each edge of the triangles once (Uint32Array, 2 an edge): the target's wireframe. */
function edgesOf(F) {
  const seen = new Set(), out = [];
  for (let t = 0; t < F.length; t += 3) {
    for (let k = 0; k < 3; k++) {
      const a = F[t + k], b = F[t + ((k + 1) % 3)];
      const key = a < b ? a * 4294967296 + b : b * 4294967296 + a;
      if (!seen.has(key)) { seen.add(key); out.push(a, b); }
    }
  }
  return Uint32Array.from(out);
}

/** The target's centre and its principal axes (the largest extent first): the view looks down the
 * smallest one, as deployed.png does, whatever the mesh's placement. Jacobi on the 3×3 covariance. */
export function principalFrame(P) {
  const n = P.length / 3, c = [0, 0, 0];
  for (let i = 0; i < P.length; i += 3) for (let k = 0; k < 3; k++) c[k] += P[i + k] / n;
  const A = [[0, 0, 0], [0, 0, 0], [0, 0, 0]];
  for (let i = 0; i < P.length; i += 3) {
    const d = [P[i] - c[0], P[i + 1] - c[1], P[i + 2] - c[2]];
    for (let r = 0; r < 3; r++) for (let s = 0; s < 3; s++) A[r][s] += d[r] * d[s];
  }
  const V = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];
  for (let sweep = 0; sweep < 30; sweep++) {
    for (const [p, q] of [[0, 1], [0, 2], [1, 2]]) {
      if (Math.abs(A[p][q]) < 1e-12 * (Math.abs(A[p][p]) + Math.abs(A[q][q]) + 1e-300)) continue;
      const th = 0.5 * Math.atan2(2 * A[p][q], A[q][q] - A[p][p]), cs = Math.cos(th), sn = Math.sin(th);
      for (let k = 0; k < 3; k++) {                              // A <- J^T A J, V <- V J
        const akp = A[k][p], akq = A[k][q];
        A[k][p] = cs * akp - sn * akq; A[k][q] = sn * akp + cs * akq;
      }
      for (let k = 0; k < 3; k++) {
        const apk = A[p][k], aqk = A[q][k];
        A[p][k] = cs * apk - sn * aqk; A[q][k] = sn * apk + cs * aqk;
      }
      for (let k = 0; k < 3; k++) {
        const vkp = V[k][p], vkq = V[k][q];
        V[k][p] = cs * vkp - sn * vkq; V[k][q] = sn * vkp + cs * vkq;
      }
    }
  }
  const order = [0, 1, 2].sort((a, b) => A[b][b] - A[a][a]);
  const axes = order.map((j) => [V[0][j], V[1][j], V[2][j]]);
  const [x, y] = axes;                                           // right-handed: z = x × y
  axes[2] = [x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]];
  return { centre: c, axes };
}

// ------------------------------------------------------------------ small matrices (column-major 4×4)

const rotX = (a) => { const c = Math.cos(a), s = Math.sin(a); return [1, 0, 0, 0, c, s, 0, -s, c]; };
const rotY = (a) => { const c = Math.cos(a), s = Math.sin(a); return [c, 0, -s, 0, 1, 0, s, 0, c]; };
const rotZ = (a) => { const c = Math.cos(a), s = Math.sin(a); return [c, s, 0, -s, c, 0, 0, 0, 1]; };
/** 3×3 column-major product a·b. */
function mul3(a, b) {
  const o = new Array(9);
  for (let c = 0; c < 3; c++) for (let r = 0; r < 3; r++) o[3 * c + r] = a[r] * b[3 * c] + a[3 + r] * b[3 * c + 1] + a[6 + r] * b[3 * c + 2];
  return o;
}

function perspective(fovy, aspect, near, far) {
  const f = 1 / Math.tan(fovy / 2), nf = 1 / (near - far);
  return [f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * nf, -1, 0, 0, 2 * far * near * nf, 0];
}

// ------------------------------------------------------------------ GL

const VERTEX = `attribute vec3 position; attribute vec3 normal; attribute vec3 color;
uniform mat4 projection; uniform mat3 rotation; uniform float scale;
varying vec3 vNormal; varying vec3 vColor;
void main() {
  vec3 p = rotation * (position * scale);
  vNormal = rotation * normal; vColor = color;
  gl_Position = projection * vec4(p.xy, p.z - 3.2, 1.0);
}`;
// lit from the camera, both faces of the sheet alike (a sheet has no inside)
const FRAGMENT = `precision mediump float; varying vec3 vNormal; varying vec3 vColor; uniform float lit; uniform float alpha;
void main() {
  float k = mix(1.0, 0.35 + 0.65 * abs(normalize(vNormal).z), lit);
  gl_FragColor = vec4(vColor * k, alpha);
}`;

function program(gl) {
  const shader = (type, src) => {
    const s = gl.createShader(type);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  };
  const p = gl.createProgram();
  gl.attachShader(p, shader(gl.VERTEX_SHADER, VERTEX));
  gl.attachShader(p, shader(gl.FRAGMENT_SHADER, FRAGMENT));
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
  return p;
}

/** A WebGL context (2, else 1 with 32-bit indices) or null. */
function context(canvas) {
  const opts = { antialias: true, preserveDrawingBuffer: true };
  const gl2 = canvas.getContext("webgl2", opts);
  if (gl2) return gl2;
  const gl = canvas.getContext("webgl", opts);
  return gl && gl.getExtension("OES_element_index_uint") ? gl : null;
}

function buffer(gl, target, data) {
  const b = gl.createBuffer();
  gl.bindBuffer(target, b);
  gl.bufferData(target, data, gl.STATIC_DRAW);
  return b;
}

/** A mesh on the GPU: positions, normals, colours (Float32Array, 3 a vertex), triangles, edges. */
function upload(gl, mesh) {
  return { position: buffer(gl, gl.ARRAY_BUFFER, mesh.positions), normal: buffer(gl, gl.ARRAY_BUFFER, mesh.normals),
    color: buffer(gl, gl.ARRAY_BUFFER, mesh.colors), faces: buffer(gl, gl.ELEMENT_ARRAY_BUFFER, mesh.faces),
    edges: buffer(gl, gl.ELEMENT_ARRAY_BUFFER, mesh.edges), nFaces: mesh.faces.length, nEdges: mesh.edges.length };
}

// ------------------------------------------------------------------ the view

const GREY = [0.74, 0.75, 0.78], LINE = [0.15, 0.16, 0.2];
const fill = (n, rgb) => { const c = new Float32Array(3 * n); for (let i = 0; i < c.length; i++) c[i] = rgb[i % 3]; return c; };

/** The prediction's colours: each vertex's distance as % of the diagonal over [0, vmax]. */
export function deviationColors(distance, diagonal, vmax) {
  const c = new Float32Array(3 * distance.length);
  for (let i = 0; i < distance.length; i++) c.set(viridis((100 * distance[i]) / diagonal / vmax), 3 * i);
  return c;
}

/** The colour bar's top: the p99 of the deviation, at least 0.5 % (deployed.png's scale). */
export const legendTop = (pct) => Math.max(Number(pct?.p99) || 0, 0.5);

export class ShapeView {
  /** ``canvas``: where it draws (no WebGL: ``ok`` is false and nothing is drawn). */
  constructor(canvas) {
    this.canvas = canvas;
    this.gl = context(canvas);
    this.mode = "side";
    this.meshes = {};
    this.reset();
    if (!this.gl) return;
    const gl = this.gl;
    this.prog = program(gl);
    this.loc = Object.fromEntries(["position", "normal", "color"].map((a) => [a, gl.getAttribLocation(this.prog, a)]));
    this.uni = Object.fromEntries(["projection", "rotation", "scale", "lit", "alpha"].map((u) => [u, gl.getUniformLocation(this.prog, u)]));
    this.listen();
    new ResizeObserver(() => this.draw()).observe(canvas);
  }

  get ok() { return !!this.gl; }

  reset() {
    // the target's principal frame, seen from 28° above its plane, turned 30° (deployed.png's camera)
    this.turn = mul3(rotX(-Math.PI / 2 + (28 * Math.PI) / 180), rotZ(Math.PI / 6));
    this.zoom = 1;
    this.draw();
  }

  /** Show ``target`` and ``deployed`` ({positions, faces}) with the prediction's ``colors``. */
  show(target, deployed, colors) {
    const gl = this.gl;
    if (!gl) return;
    const { centre, axes } = principalFrame(target.positions);
    const frame = (P) => {                                         // into the target's principal frame
      const out = new Float32Array(P.length);
      for (let i = 0; i < P.length; i += 3) {
        const d = [P[i] - centre[0], P[i + 1] - centre[1], P[i + 2] - centre[2]];
        for (let k = 0; k < 3; k++) out[i + k] = d[0] * axes[k][0] + d[1] * axes[k][1] + d[2] * axes[k][2];
      }
      return out;
    };
    const T = frame(target.positions), D = frame(deployed.positions);
    let r = 0;
    for (const P of [T, D]) for (let i = 0; i < P.length; i += 3) r = Math.max(r, Math.hypot(P[i], P[i + 1], P[i + 2]));
    this.scale = 1 / (r || 1);
    for (const m of Object.values(this.meshes)) for (const b of Object.values(m)) if (b instanceof WebGLBuffer) gl.deleteBuffer(b);
    this.meshes = {
      target: upload(gl, { positions: T, normals: vertexNormals(T, target.faces), colors: fill(T.length / 3, GREY), faces: target.faces, edges: edgesOf(target.faces) }),
      targetLines: null,
      deployed: upload(gl, { positions: D, normals: vertexNormals(D, deployed.faces), colors: colors, faces: deployed.faces, edges: new Uint32Array(0) }),
    };
    this.meshes.targetLines = { ...this.meshes.target, color: buffer(gl, gl.ARRAY_BUFFER, fill(T.length / 3, LINE)) };
    this.reset();
  }

  /** ``side`` (the target beside the prediction), ``both`` (the prediction, the target's edges over
   * it), ``deployed`` or ``target``. */
  setMode(mode) { this.mode = mode; this.draw(); }

  draw() {
    if (!this.gl || this.frame) return;
    this.frame = requestAnimationFrame(() => { this.frame = 0; this.render(); });
  }

  /** The parts of the canvas drawn: side by side (the target, then the prediction; one above the
   * other on a tall canvas), or one view of the whole. [x, y, w, h, what] in device pixels, y up. */
  panes(w, h) {
    if (this.mode !== "side") return [[0, 0, w, h, this.mode]];
    if (w >= h) { const a = Math.floor(w / 2); return [[0, 0, a, h, "target"], [a, 0, w - a, h, "deployed"]]; }
    const b = Math.floor(h / 2);
    return [[0, h - b, w, b, "target"], [0, 0, w, h - b, "deployed"]];
  }

  render() {
    const gl = this.gl, c = this.canvas;
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(c.clientWidth * dpr)), h = Math.max(1, Math.round(c.clientHeight * dpr));
    if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
    gl.viewport(0, 0, w, h);
    gl.clearColor(1, 1, 1, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    if (!this.meshes.target) return;
    gl.enable(gl.DEPTH_TEST);
    gl.useProgram(this.prog);
    gl.uniformMatrix3fv(this.uni.rotation, false, this.turn);
    gl.uniform1f(this.uni.scale, this.scale * this.zoom);
    const panes = this.panes(w, h);
    for (const [x, y, pw, ph, what] of panes) this.pane(x, y, pw, ph, what);
    this.onDraw?.(panes.map(([x, y, pw, ph, what]) => ({ left: x / dpr, top: (h - y - ph) / dpr, what })));
    c.dataset.frames = String(Number(c.dataset.frames || 0) + 1);     // drawn (the browser tests wait for it)
  }

  pane(x, y, w, h, what) {
    const gl = this.gl, aspect = w / h;
    gl.viewport(x, y, w, h);
    // the unit sphere fills the shorter side at zoom 1 (camera 3.2 away, 36° on the shorter side)
    const fovy = aspect >= 1 ? 0.63 : 2 * Math.atan(Math.tan(0.315) / aspect);
    gl.uniformMatrix4fv(this.uni.projection, false, perspective(fovy, aspect, 0.1, 20));
    gl.disable(gl.BLEND);
    this.mesh(what === "target" ? this.meshes.target : this.meshes.deployed, false, 1, 1);
    if (what === "both") {                         // the target's edges, faint, over the prediction
      gl.enable(gl.BLEND);
      gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA);
      this.mesh(this.meshes.targetLines, true, 0, 0.3);
    }
  }

  mesh(m, lines, lit, alpha) {
    const gl = this.gl;
    for (const a of ["position", "normal", "color"]) {
      gl.bindBuffer(gl.ARRAY_BUFFER, m[a]);
      gl.enableVertexAttribArray(this.loc[a]);
      gl.vertexAttribPointer(this.loc[a], 3, gl.FLOAT, false, 0, 0);
    }
    gl.uniform1f(this.uni.lit, lit);
    gl.uniform1f(this.uni.alpha, alpha);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, lines ? m.edges : m.faces);
    gl.drawElements(lines ? gl.LINES : gl.TRIANGLES, lines ? m.nEdges : m.nFaces, gl.UNSIGNED_INT, 0);
  }

  /** Turn by (dx, dy) px of drag; zoom by a factor, within 0.4–12×. */
  rotate(dx, dy) { this.turn = mul3(mul3(rotX(dy * 0.01), rotY(dx * 0.01)), this.turn); this.draw(); }
  zoomBy(f) { this.zoom = Math.min(12, Math.max(0.4, this.zoom * f)); this.draw(); }

  listen() {
    const c = this.canvas, pts = new Map();
    let pinch = 0;
    const spread = () => { const [a, b] = [...pts.values()]; return Math.hypot(a.x - b.x, a.y - b.y); };
    c.addEventListener("pointerdown", (e) => {
      c.setPointerCapture(e.pointerId);
      pts.set(e.pointerId, { x: e.clientX, y: e.clientY });
      if (pts.size === 2) pinch = spread();
    });
    c.addEventListener("pointermove", (e) => {
      const p = pts.get(e.pointerId);
      if (!p) return;
      const dx = e.clientX - p.x, dy = e.clientY - p.y;
      p.x = e.clientX; p.y = e.clientY;
      if (pts.size === 1) this.rotate(dx, dy);
      else if (pts.size === 2) { const s = spread(); if (pinch > 0) this.zoomBy(s / pinch); pinch = s; }
    });
    const up = (e) => { pts.delete(e.pointerId); pinch = pts.size === 2 ? spread() : 0; };
    c.addEventListener("pointerup", up);
    c.addEventListener("pointercancel", up);
    c.addEventListener("wheel", (e) => { e.preventDefault(); this.zoomBy(Math.exp(-e.deltaY * 0.0015)); }, { passive: false });
    c.addEventListener("keydown", (e) => {
      const k = { ArrowLeft: [-12, 0], ArrowRight: [12, 0], ArrowUp: [0, -12], ArrowDown: [0, 12] }[e.key];
      if (k) { e.preventDefault(); this.rotate(...k); } else if (e.key === "+" || e.key === "=") this.zoomBy(1.2);
      else if (e.key === "-") this.zoomBy(1 / 1.2);
    });
  }
}
