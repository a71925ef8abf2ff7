#include "viz/view_page.hpp"

namespace bgkmap::viz {

namespace {

// The page before the data. The script reads the three constants after it; it reports what it
// draws in <body data-cells-held data-cells-drawn data-map-cells data-map-occupied data-clip
// data-view data-map-screen data-legend-box data-ready data-load-ms> and any script error in
// data-error (the browser test reads them). "#clip=Z" in the address starts the height clip at Z m.
const char* const kHead = R"PAGE(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>bgkmap view</title>
<style>
html,body{margin:0;height:100%;background:#202428;color:#e8e8e8;font:13px sans-serif;overflow:hidden}
canvas{display:block;width:100%;height:100%}
#panel{position:absolute;top:8px;left:8px;background:rgba(20,22,26,.85);padding:8px 10px;border-radius:4px;max-width:340px}
#panel label{display:block;margin:4px 0}
#stats{color:#aab}
#ramp{height:12px;width:100%;border:1px solid #889;box-sizing:border-box;
background:linear-gradient(to right,rgb(48,18,128),rgb(26,140,217) 25%,rgb(77,217,102) 50%,rgb(250,217,38) 75%,rgb(230,51,26))}
#rampLabels{display:flex;justify-content:space-between;color:#aab}
.swatch{display:inline-block;width:10px;height:10px;margin:0 3px 0 8px;vertical-align:middle}
</style></head>
<body>
<script>window.addEventListener("error", e => { document.body.dataset.error = String(e.message || e); });</script>
<canvas id="view"></canvas>
<div id="panel">
<div><b id="name"></b></div>
<label>Colour <select id="colour"><option value="0">by height</option><option value="1">by probability</option></select></label>
<label>Probability &ge; <input id="threshold" type="range" min="0.5" max="1" step="0.01"> <span id="thresholdText"></span></label>
<label><input id="uncertain" type="checkbox"> show uncertain cells (variance above the map's threshold)</label>
<label>Clip above z <input id="clip" type="range" step="any"> <span id="clipText"></span></label>
<div id="legend"><div id="rampName"></div><div id="ramp"></div><div id="rampLabels"><span id="rampLo"></span><span id="rampHi"></span></div>
<div><span class="swatch" style="background:#bfbfcc;margin-left:0"></span>uncertain
<span class="swatch" style="background:#e63333"></span>x <span class="swatch" style="background:#33d94d"></span>y
<span class="swatch" style="background:#4d80ff"></span>z axes at (0, 0, 0)</div>
<div id="gridText"></div></div>
<div id="stats"></div>
<div style="color:#889">drag: orbit &middot; shift+drag or right-drag: pan &middot; wheel: zoom</div>
</div>
<script>
)PAGE";

const char* const kScript = R"PAGE(
"use strict";
const started = performance.now();
function decode(b64) {
  const s = atob(b64), out = new Uint8Array(s.length);
  for (let i = 0; i < s.length; ++i) out[i] = s.charCodeAt(i);
  return out;
}
const positions = new Uint16Array(decode(POSITIONS).buffer);
const info = decode(INFO);
const n = META.cells;
const canvas = document.getElementById("view");
const gl = canvas.getContext("webgl2", {preserveDrawingBuffer: true, antialias: true});
if (!gl) throw new Error("WebGL 2 is not available in this browser");

const vertexShader = `#version 300 es
in vec3 corner; in vec3 normal; in vec3 cell; in vec3 meta; in float visible;
uniform mat4 mvp; uniform float res; uniform int colourMode; uniform vec2 zRange; uniform float minP;
out vec3 colour;
vec3 ramp(float t) {
  t = clamp(t, 0.0, 1.0);
  vec3 a = vec3(0.19, 0.07, 0.50), b = vec3(0.10, 0.55, 0.85), c = vec3(0.30, 0.85, 0.40), d = vec3(0.98, 0.85, 0.15), e = vec3(0.90, 0.20, 0.10);
  if (t < 0.25) return mix(a, b, t * 4.0);
  if (t < 0.5) return mix(b, c, t * 4.0 - 1.0);
  if (t < 0.75) return mix(c, d, t * 4.0 - 2.0);
  return mix(d, e, t * 4.0 - 3.0);
}
void main() {
  if (visible < 0.5) { gl_Position = vec4(2.0, 2.0, 2.0, 1.0); colour = vec3(0.0); return; }
  float size = exp2(meta.x);
  vec3 world = (cell + corner) * size * res;
  gl_Position = mvp * vec4(world, 1.0);
  float p = meta.y / 255.0;
  float centreZ = (cell.z + 0.5) * size * res;
  vec3 base = colourMode == 0 ? ramp((centreZ - zRange.x) / max(zRange.y - zRange.x, 1e-6))
                              : ramp((p - minP) / (1.0 - minP));
  if (mod(meta.z, 2.0) > 0.5) base = mix(base, vec3(0.75, 0.75, 0.8), 0.6);  // uncertain
  float light = 0.45 + 0.55 * max(dot(normal, normalize(vec3(0.4, 0.3, 0.85))), 0.0);
  colour = base * light;
}`;
const fragmentShader = `#version 300 es
precision mediump float;
in vec3 colour; out vec4 fragColour;
void main() { fragColour = vec4(colour, 1.0); }`;

function compile(type, source) {
  const s = gl.createShader(type);
  gl.shaderSource(s, source);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error("shader: " + gl.getShaderInfoLog(s));
  return s;
}
const program = gl.createProgram();
gl.attachShader(program, compile(gl.VERTEX_SHADER, vertexShader));
gl.attachShader(program, compile(gl.FRAGMENT_SHADER, fragmentShader));
gl.linkProgram(program);
if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error("link: " + gl.getProgramInfoLog(program));
gl.useProgram(program);

// A unit cube: 6 faces x 2 triangles, corner and face normal per vertex.
const cube = [];
const faces = [[0, 1], [0, -1], [1, 1], [1, -1], [2, 1], [2, -1]];
for (const [axis, sign] of faces) {
  const u = (axis + 1) % 3, v = (axis + 2) % 3;
  const quad = [[0, 0], [1, 0], [1, 1], [0, 0], [1, 1], [0, 1]];
  for (const [a, b] of (sign > 0 ? quad : quad.map(([a, b]) => [b, a]))) {
    const c = [0, 0, 0], nrm = [0, 0, 0];
    c[axis] = sign > 0 ? 1 : 0; c[u] = a; c[v] = b; nrm[axis] = sign;
    cube.push(...c, ...nrm);
  }
}
function buffer(data) {
  const b = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, b);
  gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
  return b;
}
function attribute(name, size, type, stride, offset, divisor) {
  const at = gl.getAttribLocation(program, name);
  gl.enableVertexAttribArray(at);
  gl.vertexAttribPointer(at, size, type, false, stride, offset);
  gl.vertexAttribDivisor(at, divisor);
}
const vao = gl.createVertexArray();
gl.bindVertexArray(vao);
buffer(new Float32Array(cube));
attribute("corner", 3, gl.FLOAT, 24, 0, 0);
attribute("normal", 3, gl.FLOAT, 24, 12, 0);
buffer(positions);
attribute("cell", 3, gl.UNSIGNED_SHORT, 6, 0, 1);
buffer(info);
attribute("meta", 3, gl.UNSIGNED_BYTE, 3, 0, 1);
const visible = new Uint8Array(n);
const visibleBuffer = buffer(visible);
attribute("visible", 1, gl.UNSIGNED_BYTE, 1, 0, 1);

// Box centre heights for the colour ramp and the clip, in the page's frame (offsets from the
// map's lowest corner); world = page + corner.
const corner = META.origin.map(c => c * META.resolution);
const centreZ = new Float32Array(n);
let zMin = Infinity, zMax = -Infinity;
for (let i = 0; i < n; ++i) {
  const z = (positions[3 * i + 2] + 0.5) * Math.pow(2, info[3 * i]) * META.resolution;
  centreZ[i] = z;
  zMin = Math.min(zMin, z); zMax = Math.max(zMax, z);
}
if (n === 0) { zMin = 0; zMax = 1; }
// A planar map (one layer, e.g. --2d) has no heights to colour by and reads best from above.
const flat = zMax - zMin < 2 * META.resolution * Math.pow(2, META.level);

const ui = {colour: document.getElementById("colour"), threshold: document.getElementById("threshold"),
            uncertain: document.getElementById("uncertain"), stats: document.getElementById("stats"),
            clip: document.getElementById("clip")};
document.getElementById("name").textContent = META.source;
// The slider reaches down to the lowest probability whose every cell is in the page.
ui.threshold.min = (Math.ceil(META.min_probability * 100 - 1e-6) / 100).toFixed(2);
ui.threshold.value = META.occupied_threshold.toFixed(2);
if (flat) ui.colour.value = "1";
ui.uncertain.disabled = !META.has_variance;
const startThreshold = ui.threshold.value;
// The clip in world metres: boxes whose centre is above it are hidden (a ceiling over a corridor).
ui.clip.min = (zMin + corner[2]).toFixed(3);
ui.clip.max = (zMax + corner[2]).toFixed(3);
ui.clip.value = ui.clip.max;
ui.clip.disabled = flat;
const clipAt = /[#&]clip=(-?[0-9.]+(?:e-?[0-9]+)?)/.exec(location.hash);
if (clipAt) ui.clip.value = clipAt[1];
function clipZ() { return parseFloat(ui.clip.value) - corner[2]; }

// Which boxes are drawn: at the slider's starting value the map's own classification (flag 2),
// elsewhere probability >= the slider; uncertain boxes only with the toggle.
let drawn = 0;
function select() {
  const atStart = ui.threshold.value === startThreshold;
  const t = Math.round(parseFloat(ui.threshold.value) * 255);
  const showUncertain = ui.uncertain.checked;
  const clipped = parseFloat(ui.clip.value) < parseFloat(ui.clip.max);
  const clip = clipped ? clipZ() : Infinity;
  drawn = 0;
  for (let i = 0; i < n; ++i) {
    const p = info[3 * i + 1], flags = info[3 * i + 2], uncertain = (flags & 1) !== 0;
    let v = atStart ? (flags & 2) !== 0 || (showUncertain && uncertain && p >= t) : p >= t && (!uncertain || showUncertain);
    visible[i] = v && centreZ[i] <= clip ? 1 : 0;
    drawn += visible[i];
  }
  gl.bindBuffer(gl.ARRAY_BUFFER, visibleBuffer);
  gl.bufferSubData(gl.ARRAY_BUFFER, 0, visible);
  document.getElementById("thresholdText").textContent = ui.threshold.value + (atStart ? " (start: the map's occupied cells)" : "");
  document.body.dataset.cellsDrawn = drawn;
  document.body.dataset.clip = clipped ? ui.clip.value : "none";
  document.getElementById("clipText").textContent = clipped ? parseFloat(ui.clip.value).toFixed(2) + " m" : "(none)";
  document.title = "bgkmap view: " + drawn + " of " + n + " cells";
  const lod = META.level > 0 ? `; occupied cells merged ${Math.pow(2, META.level)}x per side to stay under ${META.max_cells} boxes`
            : n < META.map_cells ? `; cells under ${ui.threshold.min} left out to stay under ${META.max_cells}` : "";
  ui.stats.textContent = `${drawn} of ${n} boxes drawn${lod}; cell ${META.resolution} m`;
}

// Orbit camera around the map's centre, z up. A planar map starts from straight above with x to
// the right and y up, as on a floor plan, at a distance that shows all of it.
const ext = META.extent.map(e => e * META.resolution);
const halfFov = 0.4;
function fittingDistance() {
  const aspect = Math.max(canvas.clientWidth, 1) / Math.max(canvas.clientHeight, 1);
  return 1.25 * Math.max(ext[1], ext[0] / aspect, 1e-3) / (2 * Math.tan(halfFov));
}
const camera = flat ? {target: [ext[0] / 2, ext[1] / 2, (zMin + zMax) / 2], distance: fittingDistance(), yaw: -Math.PI / 2, pitch: 1.55}
                    : {target: [ext[0] / 2, ext[1] / 2, (zMin + zMax) / 2], distance: 1.6 * Math.max(ext[0], ext[1], ext[2], 1e-3),
                       yaw: -0.7, pitch: 0.75};
document.body.dataset.view = flat ? "top" : "orbit";
function multiply(a, b) {
  const o = new Float32Array(16);
  for (let c = 0; c < 4; ++c) for (let r = 0; r < 4; ++r) {
    let s = 0;
    for (let k = 0; k < 4; ++k) s += a[k * 4 + r] * b[c * 4 + k];
    o[c * 4 + r] = s;
  }
  return o;
}
function viewProjection() {
  const aspect = canvas.width / canvas.height, f = 1 / Math.tan(halfFov);
  const near = camera.distance * 0.01, far = camera.distance * 10;
  const proj = [f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) / (near - far), -1, 0, 0, 2 * far * near / (near - far), 0];
  const cp = Math.cos(camera.pitch), eye = [camera.target[0] + camera.distance * cp * Math.cos(camera.yaw),
               camera.target[1] + camera.distance * cp * Math.sin(camera.yaw), camera.target[2] + camera.distance * Math.sin(camera.pitch)];
  const fwd = camera.target.map((t, i) => t - eye[i]), fl = Math.hypot(...fwd), F = fwd.map(v => v / fl);
  const side = [F[1] * 1 - F[2] * 0, F[2] * 0 - F[0] * 1, 0], sl = Math.hypot(...side) || 1, S = side.map(v => v / sl);
  const U = [S[1] * F[2] - S[2] * F[1], S[2] * F[0] - S[0] * F[2], S[0] * F[1] - S[1] * F[0]];
  const view = [S[0], U[0], -F[0], 0, S[1], U[1], -F[1], 0, S[2], U[2], -F[2], 0,
                -(S[0] * eye[0] + S[1] * eye[1] + S[2] * eye[2]), -(U[0] * eye[0] + U[1] * eye[1] + U[2] * eye[2]),
                F[0] * eye[0] + F[1] * eye[1] + F[2] * eye[2], 1];
  return {mvp: multiply(proj, view), S, U};
}
function draw() {
  const w = canvas.clientWidth * devicePixelRatio, h = canvas.clientHeight * devicePixelRatio;
  if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
  gl.viewport(0, 0, canvas.width, canvas.height);
  gl.clearColor(0.125, 0.141, 0.157, 1);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  gl.enable(gl.DEPTH_TEST);
  gl.enable(gl.CULL_FACE);
  gl.uniformMatrix4fv(gl.getUniformLocation(program, "mvp"), false, viewProjection().mvp);
  gl.uniform1f(gl.getUniformLocation(program, "res"), META.resolution);
  gl.uniform1i(gl.getUniformLocation(program, "colourMode"), parseInt(ui.colour.value));
  gl.uniform2f(gl.getUniformLocation(program, "zRange"), zMin, zMax);
  gl.uniform1f(gl.getUniformLocation(program, "minP"), META.min_probability);
  gl.bindVertexArray(vao);
  if (n > 0) gl.drawArraysInstanced(gl.TRIANGLES, 0, 36, n);
  gl.useProgram(lineProgram);
  gl.uniformMatrix4fv(gl.getUniformLocation(lineProgram, "mvp"), false, viewProjection().mvp);
  gl.bindVertexArray(lineVao);
  gl.depthFunc(gl.LEQUAL);  // the axes after the grid lines they lie on
  gl.drawArrays(gl.LINES, 0, lines.length / 6);
  gl.depthFunc(gl.LESS);
  gl.useProgram(program);
  document.body.dataset.mapScreen = screenBox();
  document.body.dataset.viewport = canvas.clientWidth + "x" + canvas.clientHeight;
}
// Where the map's extent lies on the screen (CSS pixels): the browser test checks it is in view.
function screenBox() {
  const {mvp} = viewProjection();
  let box = [Infinity, Infinity, -Infinity, -Infinity];
  for (const cx of [0, ext[0]]) for (const cy of [0, ext[1]]) for (const cz of [zMin, zMax]) {
    const v = [0, 1, 2, 3].map(r => mvp[r] * cx + mvp[4 + r] * cy + mvp[8 + r] * cz + mvp[12 + r]);
    const sx = (v[0] / v[3] + 1) / 2 * canvas.clientWidth, sy = (1 - v[1] / v[3]) / 2 * canvas.clientHeight;
    box = [Math.min(box[0], sx), Math.min(box[1], sy), Math.max(box[2], sx), Math.max(box[3], sy)];
  }
  return box.map(Math.round).join(",");
}
// Grid lines on the map's floor at a round spacing in world metres, and the world's axes.
const lineVertex = `#version 300 es
in vec3 position; in vec3 lineColour; uniform mat4 mvp; out vec3 colour;
void main() { gl_Position = mvp * vec4(position, 1.0); colour = lineColour; }`;
const lineProgram = gl.createProgram();
gl.attachShader(lineProgram, compile(gl.VERTEX_SHADER, lineVertex));
gl.attachShader(lineProgram, compile(gl.FRAGMENT_SHADER, fragmentShader));
gl.linkProgram(lineProgram);
if (!gl.getProgramParameter(lineProgram, gl.LINK_STATUS)) throw new Error("link: " + gl.getProgramInfoLog(lineProgram));
function niceStep(span) {
  const raw = span / 10, m = Math.pow(10, Math.floor(Math.log10(raw))), r = raw / m;
  return m * (r < 1.5 ? 1 : r < 3.5 ? 2 : r < 7.5 ? 5 : 10);
}
const gridStep = niceStep(Math.max(ext[0], ext[1], 10 * META.resolution));
const lines = [];
{
  const ground = Math.max(zMin - 0.5 * META.resolution * Math.pow(2, META.level), 0), grey = [0.36, 0.38, 0.42];
  const x0 = Math.floor(corner[0] / gridStep) * gridStep, x1 = Math.ceil((corner[0] + ext[0]) / gridStep) * gridStep;
  const y0 = Math.floor(corner[1] / gridStep) * gridStep, y1 = Math.ceil((corner[1] + ext[1]) / gridStep) * gridStep;
  for (let x = x0; x <= x1 + 1e-9; x += gridStep) lines.push(x - corner[0], y0 - corner[1], ground, ...grey, x - corner[0], y1 - corner[1], ground, ...grey);
  for (let y = y0; y <= y1 + 1e-9; y += gridStep) lines.push(x0 - corner[0], y - corner[1], ground, ...grey, x1 - corner[0], y - corner[1], ground, ...grey);
  const o = [-corner[0], -corner[1], -corner[2]], len = 2 * gridStep;
  const axes = [[1, 0, 0, 0.9, 0.2, 0.2], [0, 1, 0, 0.2, 0.85, 0.3], [0, 0, 1, 0.3, 0.5, 1.0]];
  for (const [dx, dy, dz, r, g, b] of axes) lines.push(...o, r, g, b, o[0] + dx * len, o[1] + dy * len, o[2] + dz * len, r, g, b);
}
const lineVao = gl.createVertexArray();
gl.bindVertexArray(lineVao);
buffer(new Float32Array(lines));
for (const [name, offset] of [["position", 0], ["lineColour", 12]]) {
  const at = gl.getAttribLocation(lineProgram, name);
  gl.enableVertexAttribArray(at);
  gl.vertexAttribPointer(at, 3, gl.FLOAT, false, 24, offset);
}
gl.bindVertexArray(null);
document.getElementById("gridText").textContent = `grid: ${gridStep} m squares on the map's floor`;

// The colour ramp's meaning for the current colouring.
function legend() {
  const byHeight = ui.colour.value === "0";
  document.getElementById("rampName").textContent = byHeight ? "height of the box centre (m)" : "occupancy probability";
  document.getElementById("rampLo").textContent = byHeight ? (zMin + corner[2]).toFixed(2) : META.min_probability.toFixed(2);
  document.getElementById("rampHi").textContent = byHeight ? (zMax + corner[2]).toFixed(2) : "1.00";
}

let pending = false;
function redraw() { if (!pending) { pending = true; requestAnimationFrame(() => { pending = false; draw(); }); } }

let drag = null, moved = false;
canvas.addEventListener("contextmenu", e => e.preventDefault());
canvas.addEventListener("pointerdown", e => { moved = true; drag = {x: e.clientX, y: e.clientY, pan: e.shiftKey || e.button === 2}; canvas.setPointerCapture(e.pointerId); });
canvas.addEventListener("pointerup", () => { drag = null; });
canvas.addEventListener("pointermove", e => {
  if (!drag) return;
  const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
  drag.x = e.clientX; drag.y = e.clientY;
  if (drag.pan) {
    const {S, U} = viewProjection(), k = camera.distance / canvas.clientHeight;
    for (let i = 0; i < 3; ++i) camera.target[i] -= (S[i] * dx - U[i] * dy) * k;
  } else {
    camera.yaw -= dx * 0.008;
    camera.pitch = Math.max(-1.55, Math.min(1.55, camera.pitch + dy * 0.008));
  }
  redraw();
});
canvas.addEventListener("wheel", e => { e.preventDefault(); moved = true; camera.distance *= Math.exp(e.deltaY * 0.001); redraw(); }, {passive: false});
// Until the view is moved, a planar map keeps fitting the window.
window.addEventListener("resize", () => { if (flat && !moved) camera.distance = fittingDistance(); redraw(); });
ui.colour.addEventListener("change", () => { legend(); redraw(); });
ui.clip.addEventListener("input", () => { select(); redraw(); });
ui.threshold.addEventListener("input", () => { select(); redraw(); });
ui.uncertain.addEventListener("change", () => { select(); redraw(); });

select();
legend();
draw();
gl.finish();
const rampBox = document.getElementById("ramp").getBoundingClientRect();
document.body.dataset.legendBox = [rampBox.left, rampBox.top, rampBox.right, rampBox.bottom].map(Math.round).join(",");
document.body.dataset.cellsHeld = n;
document.body.dataset.mapCells = META.map_cells;
document.body.dataset.mapOccupied = META.map_occupied;
document.body.dataset.loadMs = Math.round(performance.now() - started);
document.body.dataset.ready = "1";
</script>
</body></html>
)PAGE";

}  // namespace

std::string view_page(const std::string& meta_json, const std::string& positions_base64,
                      const std::string& info_base64) {
  std::string page = kHead;
  page.reserve(page.size() + positions_base64.size() + info_base64.size() + meta_json.size() + 16384);
  // JSON cannot close the script element: "</" is escaped.
  std::string meta = meta_json;
  for (size_t at = meta.find("</"); at != std::string::npos; at = meta.find("</", at + 2)) meta.replace(at, 2, "<\\/");
  page += "const META = " + meta + ";\nconst POSITIONS = \"" + positions_base64 + "\";\nconst INFO = \"" + info_base64 +
          "\";\n";
  page += kScript;
  return page;
}

}  // namespace bgkmap::viz
