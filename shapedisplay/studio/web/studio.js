// The studio page (an ES module). It draws the top view the server renders, reads values with
// the C runtime (WebAssembly through sd_wasm.js, a second instance on this thread), plays the
// table with the C runtime in an AudioWorklet, edits the scene, charts and records strokes.
// No renderer is written here.
import {SdRuntime} from "/static/sd_wasm.js?token={{TOKEN}}";
import {initDesign} from "/static/design.js?token={{TOKEN}}";
import {initReactions} from "/static/reactions.js?token={{TOKEN}}";

const token = document.body.dataset.token;
const withToken = (p) => p + (p.includes("?") ? "&" : "?") + "token=" + encodeURIComponent(token);
const $ = (id) => document.getElementById(id);
const now = () => performance.timeOrigin + performance.now();     // epoch ms

const UNITS = {normal_force: "N", breakaway_force: "N", kinetic_force: "N", friction_scale: "", burst_gain: "",
               grad_x: "", grad_y: "", lateral_x: "N", lateral_y: "N", skin_stretch: "m"};

const studio = window.studio = {
  state: null, module: null, hover: null, layout: null, payload: null, tableGeneration: null,
  ctx: null, node: null, lastStroke: null, lastPointer: [], swaps: [], pending: null, dirty: false,
  errorLine: null, readoutValues: {}, hoverPos: null,
  playingModel: null,          // the pad model the worklet plays (null: no audio yet, or it refused the model)
  shownGeneration: null,       // the table generation of the last state shown whole (view, editor text, error)
  version: null,               // the version of the scene file this page knows (edits name it: design.js)
  textBase: null,              // {version, text}: what the editor's text was loaded from
  playing: null,               // what the worklet plays: {checksum, generation, which: "A" | "B"}
  lockedRange: {},             // channel -> [lo, hi] of a locked colour scale
};

// ------------------------------------------------------------------ server
async function fetchOk(path, init) {
  const r = await fetch(withToken(path), init);
  if (!r.ok) throw new Error(`${path}: ${r.status} ${await r.text()}`);
  return r;
}

async function loadModule() {
  if (!studio.module) {
    const bytes = await (await fetchOk("/api/runtime.wasm")).arrayBuffer();
    studio.module = await WebAssembly.compile(bytes);
    studio.hover = SdRuntime.fromModule(studio.module);
  }
  return studio.module;
}

async function fetchRuntime(which) {
  return parseRuntime(await (await fetchOk("/api/runtime" + (which ? `?table=${which}` : ""))).arrayBuffer());
}

// A runtime message (GET /api/runtime, or pushed over the WebSocket before a new table's state):
// u32 length, the layout as JSON, the table image.
function parseRuntime(buf) {
  const n = new DataView(buf).getUint32(0, true);
  const layout = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, 4, n)));
  for (const m of Object.values(layout.models)) if (m.pad) m.pad = padBlock(m.pad);
  return {layout, payload: buf.slice(4 + n)};
}

// A model's pad parameters as the layout sends them (base64 of little-endian float64) -> Float64Array.
function padBlock(b64) {
  const bytes = atob(b64), d = new DataView(new ArrayBuffer(bytes.length));
  for (let i = 0; i < bytes.length; i++) d.setUint8(i, bytes.charCodeAt(i));
  const out = new Float64Array(bytes.length / 8);
  for (let i = 0; i < out.length; i++) out[i] = d.getFloat64(8 * i, true);
  return out;
}

// Bind the table image to the read-out instance (the same lookup the renderer uses).
function bindHover(layout, payload) {
  studio.hover.loadTable(new Uint8Array(payload));
}

// Every stored channel at (x, y) metres, by the C runtime's bilinear lookup.
studio.readout = function (x, y) {
  const all = studio.hover.sample(x, y), out = {};
  for (const c of studio.layout.channels) out[c.name] = all[c.name];
  return out;
};

// ------------------------------------------------------------------ geometry
// Picture pixel (u, v) in [0, 1] from the top-left -> table position (m); y up, pixel centres
// on the samples.
function toTable(u, v) {
  const g = studio.layout.grid;
  const x = g.x0 + (u * g.cols - 0.5) * g.dx;
  const y = g.rows === 1 ? g.y0 : g.y0 + ((1 - v) * g.rows - 0.5) * g.dy;
  return [x, y];
}
function toPicture(x, y) {           // -> (u, v)
  const g = studio.layout.grid;
  const u = ((x - g.x0) / g.dx + 0.5) / g.cols;
  const v = g.rows === 1 ? 0.5 : 1 - ((y - g.y0) / g.dy + 0.5) / g.rows;
  return [u, v];
}
function eventPos(e) {
  const r = $("map").getBoundingClientRect();
  const u = (e.clientX - r.left - 1) / (r.width - 2), v = (e.clientY - r.top - 1) / (r.height - 2);
  return toTable(Math.min(Math.max(u, 0), 1), Math.min(Math.max(v, 0), 1));
}
// Screen pixel of a table position, relative to the overlay (for tests and drawing).
studio.screenOf = function (x, y) {
  const r = $("map").getBoundingClientRect();
  const [u, v] = toPicture(x, y);
  return [r.left + 1 + u * (r.width - 2), r.top + 1 + v * (r.height - 2)];
};

function mapSize(g) {
  const rows = g.rows === 1 ? 24 : g.rows;
  const maxW = 460, maxH = Math.max(window.innerHeight - 170, 300);
  const widthMm = g.cols * g.dx, heightMm = g.rows === 1 ? widthMm / 10 : g.rows * g.dy;
  const s = Math.min(maxW / widthMm, maxH / heightMm);
  return [Math.round(widthMm * s), Math.round(heightMm * s), rows];
}

function drawOverlay() {
  const cv = $("overlay"), img = $("map");
  const w = img.clientWidth - 2, h = img.clientHeight - 2;
  cv.width = w; cv.height = h;
  const c = cv.getContext("2d");
  c.clearRect(0, 0, w, h);
  if (studio.design) studio.design.drawGrid(c, w, h);
  c.font = "11px system-ui";
  for (const wd of (studio.state.widgets || [])) {
    const [x0, y0, x1, y1] = wd.bbox_m;
    const [ua, va] = toPicture(x0, y1), [ub, vb] = toPicture(x1, y0);
    c.strokeStyle = "rgba(255,255,255,0.85)";
    c.lineWidth = 1;
    c.strokeRect(ua * w, va * h, (ub - ua) * w, (vb - va) * h);
    c.fillStyle = "#fff";
    c.fillText(wd.id, ua * w + 2, va * h + 11);
  }
  const s = studio.lastStroke;
  if (s && s.ticks > 1) {
    c.strokeStyle = "#ff4d6d";
    c.lineWidth = 2;
    c.beginPath();
    const step = Math.max(1, Math.floor(s.ticks / 2000));
    for (let i = 0; i < s.ticks; i += step) {
      const [u, v] = toPicture(s.x[i], s.y[i]);
      if (i === 0) c.moveTo(u * w, v * h); else c.lineTo(u * w, v * h);
    }
    c.stroke();
  }
  if (studio.drawReactions) studio.drawReactions(c, w, h, toPicture);    // reactions.js: thumbs, toggles
  if (studio.design) studio.design.draw();
}

// ------------------------------------------------------------------ state + table swap
// `force`: load the scene text into the editor even if it holds unsaved typing (a resolved conflict).
async function showState(st, force) {
  if (studio.state && st.generation < studio.state.generation) return;       // an older message, late
  studio.state = st;
  $("report").textContent = st.report || "";
  showError(st.error);
  if (st.table_generation !== null && st.table_generation !== studio.tableGeneration) {
    await swapTable(st);
  }
  if ((force || !studio.dirty) && st.kind === "scene") {
    const r = await fetchOk("/api/scene");
    const text = await r.text();
    if (force || !studio.dirty) {
      studio.dirty = false;
      studio.textBase = {version: r.headers.get("X-Scene-Version"), text};
      if (text !== $("text").value) { $("text").value = text; gutter(); }
    }
  }
  markErrorLine();
  exportNote(st.error);
  if (st.error) {
    $("status").textContent = (st.error.line ? `error at line ${st.error.line}` : "error") +
      (studio.tableGeneration !== null ? `: table ${studio.tableGeneration} (the last good one) keeps playing` : "");
  }
  if (studio.design) studio.design.onState(st);
  studio.shownGeneration = studio.tableGeneration;
}
studio.applyState = (st, force) => (studio.pending = (studio.pending || Promise.resolve()).then(() => showState(st, force)));

async function swapTable(st) {
  const t0 = now();
  const gen = st.table_generation;
  studio.tableGeneration = gen;
  const swap = {generation: gen, t_message: t0, t_view: null, t_playing: null, t_changed: st.last_change};
  studio.swaps.push(swap);
  const first = !studio.layout;
  if (!first) fillChannels(st);
  const viewed = first ? null : showMap(st);             // the picture loads while the table is fetched
  await loadModule();
  const pushed = studio.pushedRuntime;         // sent over the WebSocket just before this state
  const {layout, payload} = pushed && pushed.layout.generation === gen ? pushed : await fetchRuntime();
  studio.layout = layout; studio.payload = payload;
  bindHover(layout, payload);
  fillModels(layout);
  const abA = studio.design && studio.design.abPlaying === "A";       // A/B: A keeps playing until switched
  const early = pushed && pushed.layout.generation === gen && pushed.posted;      // posted when it came
  const playing = studio.node && !abA ? (early || postTable(studio.node, layout, payload)) : Promise.resolve(null);
  if (first) fillChannels(st);
  await Promise.all([(viewed || showMap(st)).then(() => { swap.t_view = now(); drawOverlay(); rehover(); }),
                     playing.then(() => { swap.t_playing = studio.node ? (early && pushed.t_playing) || now() : null; })]);
  if (!st.error) $("status").textContent = `table ${gen} · compiled in ${(st.compile_seconds * 1e3).toFixed(0)} ms`;
}

// The model selector: the models the layout offers (one a device cannot play is shown disabled, with
// the reason); the choice is kept across tables, the server's model the first time.
function fillModels(layout) {
  const sel = $("model");
  const keep = sel.value || layout.model;
  sel.innerHTML = "";
  for (const [name, m] of Object.entries(layout.models)) {
    const o = document.createElement("option");
    o.value = name; o.textContent = name;
    if (m.error) { o.disabled = true; o.title = m.error; }
    sel.appendChild(o);
  }
  sel.value = keep in layout.models ? keep : layout.model;
}

// Play the selected model: the worklet reconfigures the C runtime on the same table (a restart).
async function chooseModel() {
  const model = $("model").value;
  if (!studio.node) return;
  const r = await postAndWait(studio.node, {type: "model", model},
                              (d) => d.type === "model-ready" && d.model === model);
  showPlaying(r);
}

function showPlaying(r) {
  studio.playingModel = r.rc === 0 ? r.model : null;
  if (r.rc !== 0) $("status").textContent = `cannot play: ${r.error}`;
  else $("status").textContent = `playing model ${r.model}`;
}

function fillChannels(st) {
  const sel = $("channel");
  const keep = sel.value || "normal_force";
  sel.innerHTML = "";
  for (const c of st.channels) {
    const o = document.createElement("option");
    o.value = c; o.textContent = c === "normal_force" ? "N (normal_force)" : c;
    sel.appendChild(o);
  }
  sel.value = st.channels.includes(keep) ? keep : st.channels[0];
  const tb = $("readout").tBodies[0];
  tb.innerHTML = "";
  for (const c of st.channels) {
    const tr = document.createElement("tr");
    tr.innerHTML = `<td>${c}</td><td class="v" data-channel="${c}">–</td>`;
    tb.appendChild(tr);
  }
}

function showMap(st) {
  st = st && st.grid ? st : studio.state;
  const ch = $("channel").value;
  const [w, h] = mapSize(st.grid);
  const img = $("map");
  img.style.width = w + "px"; img.style.height = h + "px";
  const locked = $("lock-scale").checked;
  if (locked && !studio.lockedRange[ch]) studio.lockedRange[ch] = st.ranges[ch];
  const [lo, hi] = locked ? studio.lockedRange[ch] : st.ranges[ch];
  const unit = UNITS[ch] || "";
  $("scale-lo").textContent = `${lo.toPrecision(3)} ${unit}`;
  $("scale-hi").textContent = `${hi.toPrecision(3)} ${unit}`;
  return new Promise((resolve) => {
    img.onload = () => resolve();
    img.onerror = () => resolve();
    img.src = withToken(`/api/map.png?channel=${encodeURIComponent(ch)}&g=${studio.tableGeneration}` +
                        (locked ? `&range=${lo}:${hi}` : ""));
  });
}

// Which table the export links give: the current one, or the last good one while the scene has an error.
function exportNote(err) {
  $("export-note").textContent = studio.tableGeneration === null ? "" : `exports table ${studio.tableGeneration}` +
    (err ? " — the last good one: the scene has an error, see above" : "");
  bitmapNote();
}

// The friction bitmap's quantity: what "auto" picks for this table, and a word when the choice gives a flat image.
function bitmapNote() {
  const note = $("bitmap-note"), sel = document.querySelector('#exports select[name="friction-png-quantity"]');
  const fp = studio.state && studio.state.friction_png;
  if (!note || !sel || !fp) return;
  const q = sel.value === "auto" ? fp.auto : sel.value;
  note.textContent = (sel.value === "auto" ? `friction-png auto: ${fp.auto} (${fp.rule})` : `friction-png: ${q}`) +
    (fp.flat.includes(q) ? ` — ${q} is uniform on this table: the image is flat` : "");
  note.classList.toggle("warn", fp.flat.includes(q));
}

function showError(err) {
  const box = $("error");
  studio.errorLine = err ? err.line : null;
  if (!err) { box.hidden = true; return; }
  box.hidden = false;
  $("error-where").textContent = err.line ? `line ${err.line}` : "";
  $("error-where").dataset.line = err.line || "";
  $("error-text").textContent = err.message + (studio.tableGeneration !== null ? " (the last good table keeps playing)" : "");
}

// ------------------------------------------------------------------ editor
function gutter() {
  const n = $("text").value.split("\n").length;
  let s = "";
  for (let i = 1; i <= n; i++) s += `<span data-line="${i}">${i}</span>\n`;
  $("gutter").innerHTML = s;
  markErrorLine();
}
function markErrorLine() {
  for (const el of $("gutter").querySelectorAll(".error-line")) el.classList.remove("error-line");
  if (studio.errorLine) {
    const el = $("gutter").querySelector(`[data-line="${studio.errorLine}"]`);
    if (el) {
      el.classList.add("error-line");
      const ta = $("text"), top = (studio.errorLine - 1) * 16;
      if (top < ta.scrollTop || top > ta.scrollTop + ta.clientHeight - 32) ta.scrollTop = Math.max(0, top - 64);
    }
  }
  $("gutter").scrollTop = $("text").scrollTop;
}
// Save the editor's text over the version it was loaded from: a file changed on disk meanwhile is a
// conflict (nothing written); text that is not TOML is refused at its line (the file stays as it was).
async function save() {
  const text = $("text").value;
  const base = studio.textBase ? studio.textBase.version : studio.version;
  const r = await fetch(withToken("/api/scene"), {method: "PUT", body: text, headers: {"X-Scene-Base": base || ""}});
  let data = {};
  try { data = await r.json(); } catch (err) { data = {error: String(r.status)}; }
  if (r.status === 200) {
    studio.dirty = false;
    studio.textBase = {version: data.version, text};
    if (!(data.state && data.state.error)) $("status").textContent = data.changed ? "saved" : "saved (no change)";
    if (data.state) await studio.applyState(data.state);          // (an error in it: the status says so)
  } else if (r.status === 409) {
    studio.design.showConflict(data, {text});
  } else {
    $("status").textContent = "not saved: " + (data.error || r.status);
    if (data.line) { studio.errorLine = data.line; markErrorLine(); }
  }
}

// ------------------------------------------------------------------ audio (the C runtime in a worklet)
function postAndWait(node, msg, isReply) {
  return new Promise((resolve) => {
    const done = (e) => {
      if (isReply(e.data)) {
        node.port.removeEventListener("message", done);
        resolve(e.data);
      }
    };
    node.port.addEventListener("message", done);
    node.port.postMessage(msg);
  });
}

async function postTable(node, layout, payload) {
  const r = await postAndWait(node, {type: "table", layout, payload: payload.slice(0), model: $("model").value},
                              (d) => d.type === "table-ready" && d.generation === layout.generation);
  studio.playing = {checksum: r.checksum, generation: r.generation, which: layout.which || "B"};
  showPlaying(r);
  if (studio.design) studio.design.showAB();
  return r;
}

async function makeNode(ctx, extra) {
  await ctx.audioWorklet.addModule(withToken("/static/worklet.js"));
  const node = new AudioWorkletNode(ctx, "sd-renderer", {numberOfInputs: 0, outputChannelCount: [ctx.destination.channelCount >= 2 ? 2 : 1],
                                                       processorOptions: Object.assign({delay: 0.02}, extra || {})});
  node.port.start();
  const ready = new Promise((resolve) => {
    const h = (e) => { if (e.data.type === "module-ready") { node.port.removeEventListener("message", h); resolve(); } };
    node.port.addEventListener("message", h);
  });
  node.port.postMessage({type: "module", module: studio.module});
  await ready;
  await postTable(node, studio.layout, studio.payload);
  node.connect(ctx.destination);
  return node;
}

// Feel on / off: the first press starts the audio output, later ones suspend and resume it.
async function toggleFeel() {
  if (!studio.ctx) return startFeel();
  if (studio.ctx.state === "running") await studio.ctx.suspend(); else await studio.ctx.resume();
  const on = studio.ctx.state === "running";
  $("feel").textContent = on ? "Feel on" : "Feel off";
  $("feel").setAttribute("aria-pressed", on ? "true" : "false");
}

async function startFeel() {
  if (studio.ctx) { await studio.ctx.resume(); return; }
  await loadModule();
  const rate = studio.layout.audio_rate;
  studio.ctx = new AudioContext({sampleRate: rate, latencyHint: "interactive"});
  studio.node = await makeNode(studio.ctx);
  studio.node.port.addEventListener("message", onWorklet);
  studio.node.port.postMessage({type: "mode", mode: $("mode").value});
  await studio.ctx.resume();
  $("feel").textContent = "Feel on";
  $("feel").setAttribute("aria-pressed", "true");
  studio.latency = {base: studio.ctx.baseLatency, output: studio.ctx.outputLatency || 0};
  $("status").textContent = `audio ${rate} Hz · output latency ${(1e3 * (studio.latency.base + studio.latency.output)).toFixed(1)} ms`;
}

function onWorklet(e) {
  const m = e.data;
  if (m.type === "meter") {
    $("lamp").classList.toggle("slip", m.touching && m.state === 1);
    $("meter-n").textContent = m.touching ? m.n.toFixed(2) : "–";
    $("meter-f").textContent = m.touching ? m.f.toFixed(3) : "–";
    $("meter-ev").textContent = m.events;
    if (studio.onReactionMeter) studio.onReactionMeter(m);       // reactions.js
  } else if (m.type === "stroke") {
    if (m.ticks > 0) showStroke(m);
  }
}

// Audio-context time of a pointer event (timeStamp on the performance clock): the render clock
// (currentTime, what the worklet is computing now), not the output clock, so that the worklet,
// rendering `delay` behind currentTime, finds every tick between two pointer events.
function ctxTime(ts) {
  return studio.ctx.currentTime - (performance.now() - ts) / 1000;
}

// Pointer -> worklet. Direct mode: positions. Stick mode: drag displacement -> force.
const STICK_N_PER_MM = 0.05;       // pointing-stick force per mm of drag on the screen
let down = null, pressed = false;
// The worklet renders the cursor this far behind the pointer so that every tick lies between
// two pointer events: 1.5 pointer intervals (measured on the moves), 20 ms at least, 80 ms at most.
let gapMs = 16, lastMove = null;
function inputDelay() { return Math.min(Math.max(1.5 * gapMs, 20), 80) / 1000; }
function pointer(kind, e) {
  const [x, y] = eventPos(e);
  if (kind === "down") pressed = true;
  if (pressed) studio.lastPointer.push({kind, t: e.timeStamp, x, y});
  if (kind === "up") pressed = false;
  if (!studio.node || !studio.ctx) return;
  const t = ctxTime(e.timeStamp);
  if ($("mode").value === "stick") {
    if (kind === "down") down = {x, y};
    const fx = kind === "up" ? 0 : (x - down.x) * 1e3 * STICK_N_PER_MM, fy = kind === "up" ? 0 : (y - down.y) * 1e3 * STICK_N_PER_MM;
    studio.lastCursor = {type: "cursor", kind, t, x: fx, y: fy, px: down.x, py: down.y, delay: inputDelay(),
                         press: studio.press || 0};
  } else {
    studio.lastCursor = {type: "cursor", kind, t, x, y, delay: inputDelay(), press: studio.press || 0};
  }
  studio.node.port.postMessage(studio.lastCursor);
  if (kind === "up") down = null;
}

function hover(e) {
  if (!studio.layout) return;
  showReadout(...eventPos(e));
}
// After a table swap the read-out shows the new table at the same point.
function rehover() { if (studio.hoverPos) showReadout(...studio.hoverPos); }
function showReadout(x, y) {
  const vals = studio.readout(x, y);
  studio.readoutValues = vals; studio.hoverPos = [x, y];
  const over = (studio.state.widgets || []).filter((w) => x >= w.bbox_m[0] && x <= w.bbox_m[2] &&
                                                         y >= w.bbox_m[1] && y <= w.bbox_m[3]).pop();
  const m = studio.state.mapping || {};
  const height = m.n_gain > 0 && vals.normal_force !== undefined ? (vals.normal_force - m.n_base) / m.n_gain : null;
  const yFile = studio.design ? studio.design.fileY(y) : y;         // in the scene's frame ([canvas] origin)
  $("hover-pos").textContent = `x ${(x * 1e3).toFixed(2)} mm, y ${(yFile * 1e3).toFixed(2)} mm` +
    (over ? ` · ${over.id} (${over.type})` : " · flat ground") +
    (height !== null ? ` · height ${(Math.abs(height) < 5e-6 ? 0 : height * 1e3).toFixed(2)} mm` : "");
  $("hover-pos").dataset.over = over ? over.id : "";          // (data-widget is the top view's boxes only)
  $("hover-pos").dataset.x = x; $("hover-pos").dataset.y = y;
  for (const td of $("readout").querySelectorAll("td.v")) {
    const c = td.dataset.channel, v = vals[c];
    td.textContent = `${v.toPrecision(4)} ${UNITS[c] || ""}`;
    td.dataset.value = v;
  }
}

// ------------------------------------------------------------------ strokes: chart, record, replay
function showStroke(s) {
  studio.lastStroke = s;
  drawChart(s);
  drawOverlay();
  $("dl-csv").disabled = false; $("dl-wav").disabled = false; $("dl-ahap").disabled = false;
  const dur = s.ticks / s.tickRate;
  $("stroke-info").textContent = `${s.model}: ${s.ticks} ticks (${dur.toFixed(3)} s) at ${s.tickRate} Hz, ` +
    `${s.event_time.length} stick-slip events, ${s.audio.length} audio samples` +
    (s.clipped ? `, ${s.clipped} clipped` : "") + (s.lost ? `, ${s.lost} ticks beyond the recording limit` : "");
}

function drawChart(s) {
  const cv = $("chart"), c = cv.getContext("2d");
  const W = cv.width, H = cv.height, pad = 34, h1 = (H - 30) * 0.62, h2 = (H - 30) - h1;
  c.clearRect(0, 0, W, H);
  c.font = "11px system-ui";
  const n = s.ticks, t0 = s.t[0], t1 = s.t[n - 1] || 1e-9;
  const X = (t) => pad + (W - pad - 8) * (t - t0) / Math.max(t1 - t0, 1e-9);
  let fmax = 0;
  for (let i = 0; i < n; i++) fmax = Math.max(fmax, s.normal_force[i], s.friction_force[i]);
  fmax = fmax > 0 ? fmax * 1.1 : 1;
  const Y1 = (v) => 8 + h1 * (1 - v / fmax);
  c.fillStyle = "rgba(242,140,40,0.15)";         // slip shading
  for (let i = 0; i < n; i++) if (s.state[i] === 1) c.fillRect(X(s.t[i]), 8, Math.max(1, X(s.t[Math.min(i + 1, n - 1)]) - X(s.t[i])), h1);
  const line = (arr, colour, Y) => {
    c.strokeStyle = colour; c.lineWidth = 1.2; c.beginPath();
    const step = Math.max(1, Math.floor(n / (2 * W)));
    for (let i = 0; i < n; i += step) { const px = X(s.t[i]), py = Y(arr[i]); if (i === 0) c.moveTo(px, py); else c.lineTo(px, py); }
    c.stroke();
  };
  line(s.normal_force, "#3b528b", Y1);
  line(s.friction_force, "#e63946", Y1);
  c.fillStyle = "#333";
  c.fillText(`${fmax.toFixed(2)} N`, 2, 14);
  c.fillText("0", 20, 8 + h1);
  c.fillStyle = "#3b528b"; c.fillText("N", W - 90, 16);
  c.fillStyle = "#e63946"; c.fillText("friction", W - 70, 16);
  // bursts: the drive per tick, and a tick mark per stick-slip event
  const y2 = 8 + h1 + 14, mid = y2 + h2 / 2;
  const Y2 = (v) => mid - v * h2 / 2;
  line(s.drive, "#21918c", Y2);
  c.strokeStyle = "#f28c28";
  for (const te of s.event_time) { const px = X(te); c.beginPath(); c.moveTo(px, y2 + h2 - 6); c.lineTo(px, y2 + h2); c.stroke(); }
  c.fillStyle = "#21918c"; c.fillText("burst drive", W - 90, y2 + 10);
  c.fillStyle = "#333"; c.fillText(`${(t1 - t0).toFixed(3)} s`, W - 50, H - 2); c.fillText("0", pad, H - 2);
  // the widgets crossed: a band per stretch of ticks inside a widget's box, its id on it
  studio.chartSpans = widgetSpans(s, studio.state.widgets || []);
  const bandY = H - 26;
  studio.chartSpans.forEach((sp, k) => {
    const xa = X(sp.t0), xb = Math.max(X(sp.t1), xa + 2);
    c.fillStyle = k % 2 ? "rgba(209,149,91,0.85)" : "rgba(91,143,209,0.85)";
    c.fillRect(xa, bandY, xb - xa, 9);
    c.fillStyle = "#222";
    if (xb - xa > c.measureText(sp.id).width + 4) c.fillText(sp.id, xa + 2, bandY - 2);
  });
}

// Stretches of the stroke inside each widget's box, by tick: [{id, t0, t1}] in time order
// (t0, t1 the first and last tick inside; the box edges count as inside).
function widgetSpans(s, widgets) {
  const out = [];
  for (const wd of widgets) {
    const [x0, y0, x1, y1] = wd.bbox_m;
    let start = -1;
    for (let i = 0; i <= s.ticks; i++) {
      const inside = i < s.ticks && s.x[i] >= x0 && s.x[i] <= x1 && s.y[i] >= y0 && s.y[i] <= y1;
      if (inside && start < 0) start = i;
      if (!inside && start >= 0) { out.push({id: wd.id, t0: s.t[start], t1: s.t[i - 1]}); start = -1; }
    }
  }
  return out.sort((a, b) => a.t0 - b.t0);
}

// The recorded cursor trace: one row per tick, as `shapedisplay play --trace` reads it.
studio.traceCSV = function (s) {
  s = s || studio.lastStroke;
  const rows = [`# shapedisplay studio stroke: ${s.ticks} ticks at ${s.tickRate} Hz, table ${s.generation}, model ${s.model}`,
                `# replay: shapedisplay play TABLE --model ${s.model} --cursor-csv stroke.csv --rate ${s.tickRate}Hz -o stroke.wav`,
                "t,x_m,y_m"];
  for (let i = 0; i < s.ticks; i++) rows.push(`${s.t[i]},${s.x[i]},${s.y[i]}`);
  return rows.join("\n") + "\n";
};

function wavBytes(samples, rate) {        // 32-bit float mono WAV
  const n = samples.length, buf = new ArrayBuffer(44 + 4 * n), d = new DataView(buf);
  const str = (o, s) => { for (let i = 0; i < s.length; i++) d.setUint8(o + i, s.charCodeAt(i)); };
  str(0, "RIFF"); d.setUint32(4, 36 + 4 * n, true); str(8, "WAVE"); str(12, "fmt ");
  d.setUint32(16, 16, true); d.setUint16(20, 3, true); d.setUint16(22, 1, true); d.setUint32(24, rate, true);
  d.setUint32(28, rate * 4, true); d.setUint16(32, 4, true); d.setUint16(34, 32, true);
  str(36, "data"); d.setUint32(40, 4 * n, true);
  new Float32Array(buf, 44).set(samples);
  return buf;
}
studio.wav = () => wavBytes(studio.lastStroke.audio, studio.layout.audio_rate);

function download(name, data, type) {
  const a = document.createElement("a");
  a.href = URL.createObjectURL(new Blob([data], {type}));
  a.download = name;
  document.body.appendChild(a); a.click(); a.remove();
  setTimeout(() => URL.revokeObjectURL(a.href), 1000);
}

// Render a stroke given per tick (x, y arrays, metres) through an OfflineAudioContext: the
// same worklet and WebAssembly runtime as the live output, faster than real time.
studio.renderOffline = async function (xs, ys) {
  await loadModule();
  const rate = studio.layout.audio_rate, tickRate = studio.layout.tick_rate;
  const length = Math.ceil(xs.length * rate / tickRate) + 1024;
  const ctx = new OfflineAudioContext({numberOfChannels: 1, length, sampleRate: rate});
  await ctx.audioWorklet.addModule(withToken("/static/worklet.js"));
  const node = new AudioWorkletNode(ctx, "sd-renderer", {
    numberOfInputs: 0, outputChannelCount: [1],
    processorOptions: {module: studio.module, layout: studio.layout, payload: studio.payload.slice(0),
                       model: $("model").value,
                       script: {x: Float64Array.from(xs), y: Float64Array.from(ys)}}});
  node.connect(ctx.destination);
  let got;
  const stroke = new Promise((resolve) => { got = resolve; });
  node.port.onmessage = (e) => { if (e.data.type === "stroke") got(e.data); };
  const t0 = performance.now();
  const rendered = await ctx.startRendering();
  const wall = performance.now() - t0;
  const s = await Promise.race([stroke, new Promise((_, fail) => setTimeout(
    () => fail(new Error("the offline render ended without a stroke")), 5000))]);
  s.wall_ms = wall; s.quanta = Math.ceil(length / 128); s.rendered = rendered.getChannelData(0).length;
  return s;
};

// Per-tick positions of the recorded pointer stroke (linear between pointer events), for replay.
studio.pointerTicks = function () {
  const p = studio.lastPointer, rate = studio.layout.tick_rate;
  const i0 = p.map((e) => e.kind).lastIndexOf("down");
  const pts = p.slice(i0);
  const t0 = pts[0].t, t1 = pts[pts.length - 1].t;
  const n = Math.floor((t1 - t0) / 1000 * rate) + 1;
  const xs = new Float64Array(n), ys = new Float64Array(n);
  let j = 0;
  for (let k = 0; k < n; k++) {
    const t = t0 + 1000 * k / rate;
    while (j < pts.length - 2 && pts[j + 1].t <= t) j++;
    const a = pts[j], b = pts[Math.min(j + 1, pts.length - 1)];
    const u = b.t > a.t ? Math.min(Math.max((t - a.t) / (b.t - a.t), 0), 1) : 0;
    xs[k] = a.x + (b.x - a.x) * u; ys[k] = a.y + (b.y - a.y) * u;
  }
  return {x: Array.from(xs), y: Array.from(ys)};
};

// The last stroke as AHAP: its events and drive, made by the exporter `shapedisplay play --ahap` uses.
async function downloadAhap() {
  const s = studio.lastStroke;
  if (!s) return;
  const body = {event_time: Array.from(s.event_time), event_amplitude: Array.from(s.event_amplitude),
                audio: Array.from(s.audio), t0: s.ticks ? s.t[0] : 0};
  const r = await fetch(withToken("/api/export-ahap"), {method: "POST", body: JSON.stringify(body)});
  if (!r.ok) { $("status").textContent = "AHAP export failed: " + (await r.text()); return; }
  download("stroke.ahap", await r.arrayBuffer(), "application/json");
  $("status").textContent = `AHAP of the last stroke (${r.headers.get("X-Export-Table")})`;
}

async function snapshot() {
  const s = studio.lastStroke;
  const body = {channel: $("channel").value};
  if (s) body.stroke = {t: Array.from(s.t), x: Array.from(s.x), y: Array.from(s.y),
                        normal_force: Array.from(s.normal_force), friction_force: Array.from(s.friction_force),
                        state: Array.from(s.state), event_time: Array.from(s.event_time),
                        event_amplitude: Array.from(s.event_amplitude)};
  $("status").textContent = "rendering the 3D snapshot…";
  const r = await fetch(withToken("/api/snapshot"), {method: "POST", body: JSON.stringify(body)});
  if (!r.ok) { $("status").textContent = "snapshot failed: " + (await r.text()); return; }
  const img = $("snapshot-img");
  img.src = URL.createObjectURL(await r.blob());
  img.hidden = false;
  $("status").textContent = "3D snapshot ready";
}

// ------------------------------------------------------------------ wiring
function connect() {
  const proto = location.protocol === "https:" ? "wss:" : "ws:";
  const ws = new WebSocket(withToken(`${proto}//${location.host}/ws`));
  ws.binaryType = "arraybuffer";
  ws.onmessage = (e) => {
    if (e.data instanceof ArrayBuffer) {        // a new table's runtime, just before its state: play it now
      const rt = studio.pushedRuntime = parseRuntime(e.data);
      if (studio.node && !(studio.design && studio.design.abPlaying === "A")) {
        rt.posted = postTable(studio.node, rt.layout, rt.payload).then(() => { rt.t_playing = now(); });
      }
      return;
    }
    const m = JSON.parse(e.data);
    if (m.type === "state") studio.pending = (studio.pending || Promise.resolve()).then(() => showState(m.state));
  };
  ws.onclose = () => { $("status").textContent = "disconnected from the studio server"; setTimeout(connect, 1000); };
}

// The press changed while the pointer rests (Space, reactions.js): the last cursor point again, pressing so.
function resendPress() {
  if (!pressed || !studio.node || !studio.lastCursor) return;
  studio.lastCursor = {...studio.lastCursor, kind: "move", t: ctxTime(performance.now()), press: studio.press};
  studio.node.port.postMessage(studio.lastCursor);
}

function init() {
  const wrap = $("map-wrap");
  studio.redraw = drawOverlay;
  initReactions(studio, $, resendPress);
  wrap.addEventListener("pointerdown", (e) => { wrap.setPointerCapture(e.pointerId); studio.lastPointer = []; pointer("down", e); });
  wrap.addEventListener("pointermove", (e) => {
    if (lastMove !== null && e.timeStamp > lastMove) gapMs += 0.1 * (Math.min(e.timeStamp - lastMove, 200) - gapMs);
    lastMove = e.timeStamp;
    hover(e);
    if (pressed) pointer("move", e);
  });
  wrap.addEventListener("pointerup", (e) => pointer("up", e));
  $("channel").addEventListener("change", () => showMap().then(drawOverlay));
  $("lock-scale").addEventListener("change", () => { studio.lockedRange = {}; if (studio.layout) showMap().then(drawOverlay); });
  $("model").addEventListener("change", chooseModel);
  $("mode").addEventListener("change", () => studio.node && studio.node.port.postMessage({type: "mode", mode: $("mode").value}));
  $("feel").addEventListener("click", toggleFeel);
  $("save").addEventListener("click", save);
  $("text").addEventListener("input", () => { studio.dirty = true; gutter(); });
  $("text").addEventListener("scroll", () => { $("gutter").scrollTop = $("text").scrollTop; });
  document.addEventListener("keydown", (e) => { if ((e.ctrlKey || e.metaKey) && e.key === "s") { e.preventDefault(); save(); } });
  $("dl-csv").addEventListener("click", () => download("stroke.csv", studio.traceCSV(), "text/csv"));
  $("dl-wav").addEventListener("click", () => download("stroke.wav", studio.wav(), "audio/wav"));
  $("snapshot").addEventListener("click", snapshot);
  window.addEventListener("resize", () => studio.layout && showMap().then(drawOverlay));
  $("dl-ahap").addEventListener("click", downloadAhap);
  fetchOk("/api/state").then((r) => r.json()).then((st) => {
    const ex = $("exports");
    for (const f of st.export_formats || []) {
      const a = document.createElement("a");
      a.href = withToken(`/api/export/${f}`); a.textContent = f; a.className = "export";
      a.dataset.format = f;
      ex.appendChild(a);
      const opts = (st.export_options || {})[f];
      if (!opts) continue;
      const sels = [];
      for (const [k, choices] of Object.entries(opts)) {           // friction-png: quantity, bits
        const sel = document.createElement("select");
        sel.name = `${f}-${k}`; sel.title = `${f} ${k}`; sel.dataset.option = k;
        for (const c of choices) { const o = document.createElement("option"); o.value = c; o.textContent = c; sel.appendChild(o); }
        sels.push(sel);
        ex.appendChild(sel);
      }
      const link = () => { a.href = withToken(`/api/export/${f}?` + sels.map((s) => `${s.dataset.option}=${s.value}`).join("&"));
                           bitmapNote(); };
      for (const s of sels) s.addEventListener("change", link);
      link();
    }
    if (st.kind !== "scene") $("text").disabled = true;
  });
  connect();
  initDesign({fetchOk, withToken, toPicture, applyState: studio.applyState, startFeel, toggleFeel, postTable,
              fetchRuntime, drawOverlay,
              refresh: async () => studio.applyState(await (await fetchOk("/api/state")).json())});
}
init();
