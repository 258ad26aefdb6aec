"""The set-up page: one self-contained HTML document (inline CSS and JavaScript, no asset
from outside) that draws on /frame.jpg and talks to vtrack.setup.server.

Drawing: count lines and line gates take two clicks; polygons (gates, zones, the region of
interest) take a click per vertex and close by clicking the first vertex again, by a
double click, by Enter or by "Finish shape"; Escape drops the shape in progress. A
calibration point is one click, then its road-plane metres X, Y are typed in the list.
"Move points" drags any vertex. A count line's forward direction (INTERFACE.md: the sign
of c(p) = (x2-x1)(py-y1) - (y2-y1)(px-x1) going from negative to positive, i.e. the side
the normal (-(y2-y1), x2-x1) points to) is drawn as an arrow; "reverse" swaps its ends.
"""

PAGE_HTML = r"""<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>vtrack setup</title>
<style>
  body { margin: 0; font: 14px system-ui, sans-serif; display: flex; height: 100vh;
         background: #1e1f22; color: #ddd; }
  #view { flex: 1; overflow: hidden; padding: 8px; }
  #canvas { cursor: crosshair; display: block; background: #000; }
  #panel { width: 360px; overflow-y: auto; padding: 8px 12px; background: #2b2d31; }
  h2 { font-size: 13px; text-transform: uppercase; letter-spacing: .05em; color: #9aa;
       margin: 14px 0 4px; }
  button { background: #3c3f45; color: #eee; border: 1px solid #555; border-radius: 4px;
           padding: 4px 8px; margin: 2px 2px 2px 0; cursor: pointer; font: inherit; }
  button.active { background: #2f6fdb; border-color: #2f6fdb; }
  button.primary { background: #2e8b57; border-color: #2e8b57; }
  input { background: #1e1f22; color: #eee; border: 1px solid #555; border-radius: 3px;
          padding: 2px 4px; font: inherit; }
  input.name { width: 110px; }
  input.metre { width: 64px; }
  .item { display: flex; align-items: center; gap: 4px; margin: 3px 0; }
  .item .tag { width: 30px; color: #9aa; font-size: 12px; }
  .item button { padding: 1px 6px; }
  #fit.ok { color: #7fd37f; } #fit.bad { color: #ff8080; }
  #status { margin-top: 8px; min-height: 2em; white-space: pre-wrap; }
  #status.bad { color: #ff8080; } #status.ok { color: #7fd37f; }
  #hint { color: #aab; font-size: 12px; min-height: 2.5em; }
</style>
</head>
<body>
<div id="view"><canvas id="canvas"></canvas></div>
<div id="panel">
  <h2>Draw</h2>
  <div id="tools">
    <button id="tool-line" data-tool="line">Count line</button>
    <button id="tool-gate-line" data-tool="gate-line">Gate (line)</button>
    <button id="tool-gate-polygon" data-tool="gate-polygon">Gate (polygon)</button>
    <button id="tool-zone" data-tool="zone">Zone</button>
    <button id="tool-roi" data-tool="roi">Region of interest</button>
    <button id="tool-point" data-tool="point">Calibration point</button>
    <button id="tool-edit" data-tool="edit">Move points</button>
  </div>
  <button id="finish">Finish shape</button>
  <div id="hint"></div>
  <h2>Count lines</h2><div id="list-lines"></div>
  <h2>Gates</h2><div id="list-gates"></div>
  <h2>Zones</h2><div id="list-zones"></div>
  <h2>Region of interest</h2><div id="list-roi"></div>
  <h2>Calibration points (road metres X, Y)</h2><div id="list-points"></div>
  <div id="fit"></div>
  <h2>Files</h2>
  <button id="save" class="primary">Save</button>
  <button id="done">Done</button>
  <div id="status"></div>
</div>
<script>
"use strict";
const canvas = document.getElementById("canvas");
const ctx = canvas.getContext("2d");
const img = new Image();
let S = null;            // the drawing (see vtrack/setup/config_io.py)
let tool = "line";
let draft = [];          // vertices of the shape in progress
let mouse = null;        // last pointer position, image pixels
let drag = null;         // {list, index} of the vertex being moved
let dirty = false;
const HINTS = {
  "line": "Click the line's two ends. The arrow shows its forward direction.",
  "gate-line": "Click the gate line's two ends.",
  "gate-polygon": "Click the vertices; click the first one again, double-click or press Enter to close.",
  "zone": "Click the vertices; click the first one again, double-click or press Enter to close.",
  "roi": "Click the vertices of the region of interest (replaces the current one); close as a polygon.",
  "point": "Click a point on the road, then type its X, Y in metres in the list.",
  "edit": "Drag any vertex or calibration point.",
};
const COLOURS = { line: "#ff4040", gate: "#ff40ff", zone: "#40a0ff", roi: "#ffd640",
                  point: "#40ff70", draft: "#ffffff" };

function unit() { return Math.max(1, S.width / 640); }   // image px per screen-ish px

function toImage(ev) {
  const r = canvas.getBoundingClientRect();
  return [(ev.clientX - r.left) * S.width / r.width, (ev.clientY - r.top) * S.height / r.height];
}
function near(a, b, px) { return Math.hypot(a[0] - b[0], a[1] - b[1]) <= px * unit(); }

function uniqueName(prefix, list) {
  const names = new Set(list.map(x => x.name));
  for (let k = 1; ; k++) { if (!names.has(prefix + k)) return prefix + k; }
}

function setTool(t) {
  tool = t; draft = [];
  for (const b of document.querySelectorAll("#tools button"))
    b.classList.toggle("active", b.dataset.tool === t);
  document.getElementById("hint").textContent = HINTS[t];
  draw();
}

function changed(fit) { dirty = true; renderLists(); draw(); if (fit) scheduleFit(); }

function finishShape() {
  const need = (tool === "line" || tool === "gate-line") ? 2 : 3;
  if (draft.length < need) return;
  const pts = draft.map(p => [p[0], p[1]]);
  if (tool === "line") S.lines.push({ name: uniqueName("line", S.lines), points: pts, extra: {} });
  else if (tool === "gate-line") S.gates.push({ name: uniqueName("gate", S.gates), line: pts, extra: {} });
  else if (tool === "gate-polygon") S.gates.push({ name: uniqueName("gate", S.gates), polygon: pts, extra: {} });
  else if (tool === "zone") S.zones.push({ name: uniqueName("zone", S.zones), polygon: pts, extra: {} });
  else if (tool === "roi") S.roi = pts;
  draft = [];
  changed(false);
}

function vertexLists() {   // every draggable vertex list, with a flag for calibration points
  const out = [];
  for (const l of S.lines) out.push([l.points, false]);
  for (const g of S.gates) out.push([g.line || g.polygon, false]);
  for (const z of S.zones) out.push([z.polygon, false]);
  if (S.roi) out.push([S.roi, false]);
  out.push([S.points.map(p => p.image), true]);
  return out;
}

canvas.addEventListener("mousedown", ev => {
  if (!S || tool !== "edit") return;
  const p = toImage(ev);
  for (const [list, isPoint] of vertexLists())
    for (let i = 0; i < list.length; i++)
      if (near(list[i], p, 8)) { drag = { list, i, isPoint }; return; }
});
canvas.addEventListener("mousemove", ev => {
  if (!S) return;
  mouse = toImage(ev);
  if (drag) { drag.list[drag.i][0] = mouse[0]; drag.list[drag.i][1] = mouse[1]; dirty = true; }
  draw();
});
window.addEventListener("mouseup", () => {
  if (drag) { const fit = drag.isPoint; drag = null; changed(fit); }
});
canvas.addEventListener("click", ev => {
  if (!S || tool === "edit") return;
  const p = toImage(ev);
  if (tool === "point") {
    S.points.push({ image: p, world: null });
    changed(true);
    const inputs = document.querySelectorAll("#list-points input.metre");
    if (inputs.length) inputs[inputs.length - 2].focus();
    return;
  }
  const two = tool === "line" || tool === "gate-line";
  if (!two && draft.length >= 3 && near(draft[0], p, 10)) { finishShape(); return; }
  if (draft.length && near(draft[draft.length - 1], p, 2)) return;   // a double click's 2nd click
  draft.push(p);
  if (two && draft.length === 2) finishShape(); else draw();
});
canvas.addEventListener("dblclick", () => { if (tool !== "edit" && tool !== "point") finishShape(); });
window.addEventListener("keydown", ev => {
  if (ev.target.tagName === "INPUT") return;
  if (ev.key === "Enter") finishShape();
  if (ev.key === "Escape") { draft = []; draw(); }
});
for (const b of document.querySelectorAll("#tools button"))
  b.addEventListener("click", () => setTool(b.dataset.tool));
document.getElementById("finish").addEventListener("click", finishShape);

// ----------------------------------------------------------------------------- drawing
function path(pts, close) {
  ctx.beginPath();
  pts.forEach((p, i) => i ? ctx.lineTo(p[0], p[1]) : ctx.moveTo(p[0], p[1]));
  if (close) ctx.closePath();
}
function label(text, p, colour) {
  const u = unit();
  ctx.font = `bold ${Math.round(13 * u)}px system-ui, sans-serif`;
  const w = ctx.measureText(text).width;
  // kept inside the frame
  const x = Math.min(Math.max(p[0] + 4 * u, 0), S.width - w - 6 * u);
  const y = Math.min(Math.max(p[1], 18 * u), S.height - 2 * u);
  ctx.fillStyle = "rgba(0,0,0,0.65)";
  ctx.fillRect(x, y - 16 * u, w + 6 * u, 18 * u);
  ctx.fillStyle = colour;
  ctx.fillText(text, x + 3 * u, y - 3 * u);
}
function polygon(pts, colour, fill, name) {
  ctx.lineWidth = 2 * unit();
  ctx.strokeStyle = colour; ctx.fillStyle = fill;
  path(pts, true); ctx.fill(); ctx.stroke();
  vertices(pts, colour);
  if (name) label(name, pts[0], colour);
}
function vertices(pts, colour) {
  ctx.fillStyle = colour;
  for (const p of pts) { ctx.beginPath(); ctx.arc(p[0], p[1], 3 * unit(), 0, 2 * Math.PI); ctx.fill(); }
}
function arrowLine(a, b, colour, name, withArrow) {
  const u = unit();
  ctx.lineWidth = 3 * u; ctx.strokeStyle = colour;
  path([a, b], false); ctx.stroke();
  vertices([a, b], colour);
  const dx = b[0] - a[0], dy = b[1] - a[1], len = Math.hypot(dx, dy) || 1;
  const m = [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2];
  if (withArrow) {
    // forward: c(p) = dx*(py-y1) - dy*(px-x1) increases along the normal (-dy, dx)
    const n = [-dy / len, dx / len], L = 28 * u, h = 9 * u;
    const tip = [m[0] + n[0] * L, m[1] + n[1] * L];
    ctx.lineWidth = 3 * u;
    path([m, tip], false); ctx.stroke();
    ctx.fillStyle = colour;
    ctx.beginPath();
    ctx.moveTo(tip[0] + n[0] * h, tip[1] + n[1] * h);
    ctx.lineTo(tip[0] - n[1] * h * 0.7, tip[1] + n[0] * h * 0.7);
    ctx.lineTo(tip[0] + n[1] * h * 0.7, tip[1] - n[0] * h * 0.7);
    ctx.closePath(); ctx.fill();
    label(name, a, colour);
    ctx.font = `bold ${Math.round(12 * u)}px system-ui, sans-serif`;
    ctx.fillStyle = colour;
    ctx.fillText("fwd", tip[0] + n[0] * 14 * u - 10 * u, tip[1] + n[1] * 14 * u + 4 * u);
  } else if (name) {
    label(name, m, colour);
  }
}
function draw() {
  if (!S) return;
  ctx.drawImage(img, 0, 0);
  if (S.roi) {     // dim what lies outside the region of interest
    ctx.save();
    ctx.fillStyle = "rgba(0,0,0,0.45)";
    ctx.beginPath(); ctx.rect(0, 0, S.width, S.height);
    S.roi.forEach((p, i) => i ? ctx.lineTo(p[0], p[1]) : ctx.moveTo(p[0], p[1]));
    ctx.closePath(); ctx.fill("evenodd"); ctx.restore();
    ctx.setLineDash([8 * unit(), 5 * unit()]);
    polygon(S.roi, COLOURS.roi, "rgba(0,0,0,0)", "ROI");
    ctx.setLineDash([]);
  }
  for (const z of S.zones) polygon(z.polygon, COLOURS.zone, "rgba(64,160,255,0.18)", z.name);
  for (const g of S.gates) {
    if (g.line) arrowLine(g.line[0], g.line[1], COLOURS.gate, "gate " + g.name, false);
    else polygon(g.polygon, COLOURS.gate, "rgba(255,64,255,0.15)", "gate " + g.name);
  }
  for (const l of S.lines) arrowLine(l.points[0], l.points[1], COLOURS.line, l.name, true);
  S.points.forEach((p, i) => {
    const u = unit(), [x, y] = p.image;
    ctx.strokeStyle = COLOURS.point; ctx.lineWidth = 2 * u;
    ctx.beginPath(); ctx.arc(x, y, 6 * u, 0, 2 * Math.PI); ctx.stroke();
    path([[x - 10 * u, y], [x + 10 * u, y]], false); ctx.stroke();
    path([[x, y - 10 * u], [x, y + 10 * u]], false); ctx.stroke();
    label("P" + (i + 1) + (p.world ? "" : "?"), [x + 2 * u, y - 2 * u], COLOURS.point);
  });
  if (draft.length) {
    ctx.setLineDash([6 * unit(), 4 * unit()]);
    ctx.strokeStyle = COLOURS.draft; ctx.lineWidth = 2 * unit();
    path(mouse ? draft.concat([mouse]) : draft, false); ctx.stroke();
    ctx.setLineDash([]);
    vertices(draft, COLOURS.draft);
  }
}

// ----------------------------------------------------------------------------- lists
function el(tag, attrs, text) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
  if (text !== undefined) e.textContent = text;
  return e;
}
function nameInput(obj, kind, i) {
  const inp = el("input", { class: "name", id: `name-${kind}-${i}`, value: obj.name });
  inp.addEventListener("input", () => { obj.name = inp.value; dirty = true; draw(); });
  return inp;
}
function delButton(list, i, kind, fit) {
  const b = el("button", { id: `del-${kind}-${i}`, title: "delete" }, "\u2715");
  b.addEventListener("click", () => { list.splice(i, 1); changed(fit); });
  return b;
}
function renderLists() {
  const lines = document.getElementById("list-lines"); lines.replaceChildren();
  S.lines.forEach((l, i) => {
    const row = el("div", { class: "item" });
    const rev = el("button", { id: `rev-line-${i}`, title: "swap the forward direction" }, "reverse");
    rev.addEventListener("click", () => { l.points.reverse(); changed(false); });
    row.append(el("span", { class: "tag" }, "L" + (i + 1)), nameInput(l, "line", i), rev,
               delButton(S.lines, i, "line", false));
    lines.append(row);
  });
  const gates = document.getElementById("list-gates"); gates.replaceChildren();
  S.gates.forEach((g, i) => {
    const row = el("div", { class: "item" });
    row.append(el("span", { class: "tag" }, g.line ? "line" : "poly"), nameInput(g, "gate", i),
               delButton(S.gates, i, "gate", false));
    gates.append(row);
  });
  const zones = document.getElementById("list-zones"); zones.replaceChildren();
  S.zones.forEach((z, i) => {
    const row = el("div", { class: "item" });
    row.append(el("span", { class: "tag" }, "Z" + (i + 1)), nameInput(z, "zone", i),
               delButton(S.zones, i, "zone", false));
    zones.append(row);
  });
  const roi = document.getElementById("list-roi"); roi.replaceChildren();
  if (S.roi) {
    const row = el("div", { class: "item" });
    const b = el("button", { id: "del-roi" }, "\u2715");
    b.addEventListener("click", () => { S.roi = null; changed(false); });
    row.append(el("span", {}, `${S.roi.length} vertices`), b);
    roi.append(row);
  } else roi.append(el("span", { class: "tag" }, "none (whole frame)"));
  const pts = document.getElementById("list-points"); pts.replaceChildren();
  S.points.forEach((p, i) => {
    const row = el("div", { class: "item" });
    const xs = el("input", { class: "metre", id: `X-${i}`, placeholder: "X m",
                             value: p.world ? p.world[0] : "" });
    const ys = el("input", { class: "metre", id: `Y-${i}`, placeholder: "Y m",
                             value: p.world ? p.world[1] : "" });
    const update = () => {
      const X = parseFloat(xs.value), Y = parseFloat(ys.value);
      p.world = (xs.value.trim() !== "" && ys.value.trim() !== "" && isFinite(X) && isFinite(Y))
        ? [X, Y] : null;
      dirty = true; draw(); scheduleFit();
    };
    xs.addEventListener("input", update); ys.addEventListener("input", update);
    row.append(el("span", { class: "tag" }, "P" + (i + 1)),
               el("span", { class: "tag", style: "width:90px" },
                  `(${p.image[0].toFixed(0)}, ${p.image[1].toFixed(0)})`),
               xs, ys, delButton(S.points, i, "point", true));
    pts.append(row);
  });
}

// ----------------------------------------------------------------------------- server
async function post(url, body) {
  const r = await fetch(url, { method: "POST", headers: { "Content-Type": "application/json" },
                               body: JSON.stringify(body) });
  return r.json();
}
let fitTimer = null, fitSeq = 0;
function scheduleFit() { clearTimeout(fitTimer); fitTimer = setTimeout(runFit, 150); }
function showFit(f) {
  const box = document.getElementById("fit");
  box.dataset.points = f ? f.points : 0;
  if (!f || !S.points.length) { box.className = ""; box.textContent = ""; box.dataset.state = "none"; return; }
  if (f.ok) {
    const parts = Object.entries(f.errors).map(([k, v]) =>
      typeof v === "number" ? `${k} ${v.toFixed(3)}`
        : `${k} ${Object.entries(v).map(([a, b]) => `${a} ${Number(b).toFixed(3)}`).join(", ")}`);
    box.className = "ok"; box.dataset.state = "ok";
    box.textContent = `Calibration of ${f.points} points: ` + parts.join("; ");
  } else {
    box.className = "bad"; box.dataset.state = "refused";
    box.textContent = `Calibration refused (${f.points} points): ${f.error}`;
  }
}
async function runFit() {
  const seq = ++fitSeq;
  const f = await post("/api/fit", { points: S.points });
  if (seq === fitSeq) showFit(f);
}
function status(text, ok) {
  const s = document.getElementById("status");
  s.textContent = text; s.className = ok ? "ok" : "bad";
}
document.getElementById("save").addEventListener("click", async () => {
  const named = [...S.lines, ...S.gates, ...S.zones].filter(x => !x.name.trim());
  if (named.length) { status("Every line, gate and zone needs a name.", false); return; }
  const r = await post("/api/save", S);
  if (r.ok) {
    dirty = false;
    let text = "Saved " + r.written.join(", ");
    const open = S.points.filter(p => !p.world).length;
    if (open) text += `\n${open} calibration point(s) without metres were not saved.`;
    if (r.fit && !r.fit.ok) text += "\nThe calibration is refused: " + r.fit.error;
    status(text, !(r.fit && !r.fit.ok));
    document.getElementById("status").dataset.saved = "yes";
  } else status("Not saved: " + r.error, false);
});
document.getElementById("done").addEventListener("click", async () => {
  await post("/api/done", {});
  status((dirty ? "Unsaved changes were dropped. " : "") + "The server has stopped; close this page.", !dirty);
  document.body.dataset.done = "yes";
});

function fitView() {   // the frame as large as the view allows, its aspect kept
  if (!S) return;
  const v = document.getElementById("view");
  const k = Math.min((v.clientWidth - 16) / S.width, (v.clientHeight - 16) / S.height);
  canvas.style.width = Math.floor(S.width * k) + "px";
  canvas.style.height = Math.floor(S.height * k) + "px";
}
window.addEventListener("resize", fitView);

async function start() {
  S = await (await fetch("/api/drawing")).json();
  img.onload = () => {
    canvas.width = S.width; canvas.height = S.height;
    fitView(); renderLists(); setTool("line");
    if (S.points.length) runFit();
    document.body.dataset.ready = "yes";
  };
  img.src = "/frame.jpg";
}
start();
</script>
</body>
</html>
"""
