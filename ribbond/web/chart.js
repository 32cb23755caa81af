// The temperatures of the last 30 minutes on a canvas: nozzle and bed, targets dashed.

const SERIES = [["T", "#d9480f", false], ["Tt", "#d9480f", true], ["B", "#1c7ed6", false], ["Bt", "#1c7ed6", true]];

export function drawChart(canvas, points, span = 1800) {
  const dpr = window.devicePixelRatio || 1;
  const w = canvas.clientWidth || 300, h = canvas.clientHeight || 120;
  if (canvas.width !== Math.round(w * dpr)) { canvas.width = Math.round(w * dpr); canvas.height = Math.round(h * dpr); }
  const g = canvas.getContext("2d");
  g.setTransform(dpr, 0, 0, dpr, 0, 0);
  g.clearRect(0, 0, w, h);
  const now = Date.now() / 1000;
  let top = 60;
  for (const p of points) for (const [k] of SERIES) if (p[k] > top) top = p[k];
  top = Math.ceil((top + 10) / 50) * 50;
  const left = 30, x = (t) => left + (w - left - 4) * (1 - (now - t) / span), y = (v) => h - 14 - (h - 22) * (v / top);
  g.font = "10px system-ui, sans-serif";
  g.fillStyle = "#777";
  g.strokeStyle = "#e3e3e3";
  g.lineWidth = 1;
  for (let v = 0; v <= top; v += top > 200 ? 100 : 50) {
    g.beginPath(); g.moveTo(left, y(v)); g.lineTo(w - 4, y(v)); g.stroke();
    g.fillText(`${v}°`, 2, y(v) + 3);
  }
  g.fillText(`${Math.round(span / 60)} min ago`, left, h - 2);
  g.fillText("now", w - 24, h - 2);
  for (const [k, color, dashed] of SERIES) {
    g.strokeStyle = color;
    g.lineWidth = dashed ? 1 : 2;
    g.setLineDash(dashed ? [4, 3] : []);
    g.beginPath();
    let started = false;
    for (const p of points) {
      if (p[k] === undefined || p[k] === null) continue;
      if (!started) { g.moveTo(x(p.t), y(p[k])); started = true; } else g.lineTo(x(p.t), y(p[k]));
    }
    g.stroke();
  }
  g.setLineDash([]);
  // what is drawn, for people reading the page's source and for the tests
  canvas.dataset.points = String(points.length);
  canvas.dataset.oldest = points.length ? String(points[0].t) : "";
}
