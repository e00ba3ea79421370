// The studio's design tool (an ES module the page imports): select, move, resize and nudge widgets
// on the top view, the inspector, the palette, undo / redo with the history, conflicts, A/B.
//
// Nothing is kept here that the file does not hold: every change is sent to the server as
// operations on the scene file (POST /api/edit, naming the version of the file this page
// edited), which rewrites only the values that change, recompiles and answers with the new
// state. A change made on a stale version comes back 409 with the disk's text: the conflict
// panel shows both and the designer chooses (keep mine, take the disk's, merge).

const $ = (id) => document.getElementById(id);
let studio = null;         // the page's state (window.studio), set by initDesign
let api = null;            // helpers of studio.js: fetchOk, withToken, toPicture, applyState, ...
const SNAP_PX = 4;         // snapping to other widgets' edges and centres: within this many screen pixels

const design = {
  schema: null, selected: null, drag: null, conflict: null, busy: null,
  abPlaying: "B",          // which table the worklet plays: B (the current one) or A (the pinned one)
  lastEdit: null,          // {t_sent, t_answer, generation} of the last canvas or inspector edit
  guides: [],
};

// ------------------------------------------------------------------ server calls
async function post(path, body) {
  const r = await fetch(api.withToken(path), {method: "POST", headers: {"Content-Type": "application/json"},
                                              body: JSON.stringify(body)});
  let data = {};
  try { data = await r.json(); } catch (err) { data = {error: `${r.status}`}; }
  return {status: r.status, data};
}

// Send operations on the file; the answer's state is shown (the new table swapped in).
design.edit = async function (ops, label) {
  const t0 = performance.now();
  const {status, data} = await post("/api/edit", {base: studio.version, ops, label});
  design.lastEdit = {t_sent: performance.timeOrigin + t0, status, generation: data.state ? data.state.table_generation : null};
  return answered(status, data, {ops, label});
};

async function answered(status, data, what) {
  if (status === 409) { showConflict(data, what); return data; }
  if (status !== 200) {
    $("status").textContent = "not written: " + (data.error || status);
    design.lastError = data.error || String(status);
    return data;
  }
  design.lastError = null;
  if (data.select !== undefined) design.selected = data.select;
  if (data.state) await api.applyState(data.state);
  return data;
}

async function step(kind) {
  const {status, data} = await post(`/api/${kind}`, {base: studio.version});
  if (status === 409) {              // the file changed on disk since: show it; nothing was written
    $("status").textContent = `${kind}: the file changed on disk since this page read it; the page shows it now ` +
      `(${kind} again to step over that change)`;
    await api.refresh();
    return data;
  }
  return answered(status, data, null);
}
design.undo = () => step("undo");
design.redo = () => step("redo");
design.revert = () => step("revert");

// ------------------------------------------------------------------ geometry
function grid() { return studio.layout && studio.state ? studio.state.grid : null; }     // null until a table is shown
function scale() {                    // screen pixels per metre (x, y)
  const g = grid(), img = $("map");
  return [img.clientWidth / (g.cols * g.dx), img.clientHeight / (g.rows * g.dy)];
}
function widgetsNow() { return (studio.state && studio.state.widgets) || []; }
function boxOf(id) {
  const w = widgetsNow().find((w) => w.id === id);
  return w ? w.bbox_m.slice() : null;
}
// Screen rectangle (relative to the layer) of a box in metres [x0, y0, x1, y1].
function rectOf(b) {
  const img = $("map"), W = img.clientWidth, H = img.clientHeight;      // the picture inside its 1 px border
  const [ua, va] = api.toPicture(b[0], b[3]), [ub, vb] = api.toPicture(b[2], b[1]);
  if (grid().rows === 1) return {left: ua * W, top: 0, width: Math.max((ub - ua) * W, 1), height: H};   // a strip
  return {left: ua * W, top: va * H, width: Math.max((ub - ua) * W, 1), height: Math.max((vb - va) * H, 1)};
}

// ------------------------------------------------------------------ the widget layer
function layer() {
  const img = $("map"), el = $("widgets");
  el.style.width = img.clientWidth + "px";
  el.style.height = img.clientHeight + "px";
  return el;
}

design.draw = function () {
  if (!grid()) return;
  const el = layer();
  const keep = new Set();
  for (const w of widgetsNow()) {
    keep.add(w.id);
    let d = el.querySelector(`[data-widget="${CSS.escape(w.id)}"]`);
    if (!d) {
      d = document.createElement("div");
      d.className = "wbox";
      d.dataset.widget = w.id;
      d.addEventListener("pointerdown", (e) => startDrag(e, w.id, null));
      el.appendChild(d);
    }
    d.title = `${w.id} (${w.type})`;
    const b = design.drag && design.drag.id === w.id ? design.drag.box : w.bbox_m;
    place(d, b);
    d.classList.toggle("selected", design.selected === w.id);
    handles(d, design.selected === w.id);
  }
  for (const d of [...el.querySelectorAll(".wbox")]) if (!keep.has(d.dataset.widget)) d.remove();
  if (design.selected && !keep.has(design.selected)) design.selected = null;
  drawGuides();
};

function place(d, b) {
  const r = rectOf(b);
  Object.assign(d.style, {left: r.left + "px", top: r.top + "px", width: r.width + "px", height: r.height + "px"});
}

const HANDLES = ["nw", "n", "ne", "e", "se", "s", "sw", "w"];
function handles(d, on) {
  const have = d.querySelectorAll(".handle");
  if (!on) { for (const h of have) h.remove(); return; }
  if (have.length) return;
  for (const name of HANDLES) {
    const h = document.createElement("div");
    h.className = `handle h-${name}`;
    h.dataset.handle = name;
    h.addEventListener("pointerdown", (e) => startDrag(e, d.dataset.widget, name));
    d.appendChild(h);
  }
}

function drawGuides() {
  const el = $("widgets");
  for (const g of [...el.querySelectorAll(".guide")]) g.remove();
  const img = $("map"), W = img.clientWidth, H = img.clientHeight;
  for (const g of design.guides) {
    const d = document.createElement("div");
    d.className = "guide";
    if (g.axis === "x") {
      const [u] = api.toPicture(g.at, 0);
      Object.assign(d.style, {left: u * W + "px", top: "0px", width: "1px", height: H + "px"});
    } else {
      const [, v] = api.toPicture(0, g.at);
      Object.assign(d.style, {left: "0px", top: v * H + "px", width: W + "px", height: "1px"});
    }
    el.appendChild(d);
  }
}

// ------------------------------------------------------------------ select, move, resize
function editing() { return $("tool").value === "edit"; }

design.select = function (id) {
  design.selected = id;
  design.draw();
  inspect();
};

// Which edges a handle moves: [x0, y0, x1, y1] (y up: the top of the screen is y1).
const EDGES = {n: [0, 0, 0, 1], s: [0, 1, 0, 0], e: [0, 0, 1, 0], w: [1, 0, 0, 0],
               ne: [0, 0, 1, 1], nw: [1, 0, 0, 1], se: [0, 1, 1, 0], sw: [1, 1, 0, 0]};

function startDrag(e, id, handle) {
  if (!editing() || e.button !== 0 || studio.state.kind !== "scene") return;     // an SVG or image: feel only
  e.stopPropagation();
  e.preventDefault();
  if (design.selected !== id) design.select(id);
  const box0 = boxOf(id);
  if (!box0) return;
  e.currentTarget.setPointerCapture(e.pointerId);
  design.drag = {id, handle, sx: e.clientX, sy: e.clientY, box0, box: box0.slice(), d: [0, 0, 0, 0],
                 mask: handle ? EDGES[handle] : [1, 1, 1, 1], target: e.currentTarget};
  const move = (ev) => { ev.stopPropagation(); dragTo(ev); };
  const up = (ev) => {
    ev.stopPropagation();
    design.drag.target.removeEventListener("pointermove", move);
    design.drag.target.removeEventListener("pointerup", up);
    design.drag.target.removeEventListener("pointercancel", up);
    endDrag(ev);
  };
  design.drag.target.addEventListener("pointermove", move);
  design.drag.target.addEventListener("pointerup", up);
  design.drag.target.addEventListener("pointercancel", up);
}

// Snap a set of candidate positions (metres, on one axis) to other widgets' edges and centres
// and the canvas's edges and centre: the shift to apply (0 if nothing is near) and the guide.
function snapAxis(cands, axis, exclude, tol) {
  const g = grid();
  const lines = [];
  const ext = axis === "x" ? [g.x0, g.x0 + (g.cols - 1) * g.dx] : [g.y0, g.y0 + (g.rows - 1) * g.dy];
  lines.push(ext[0], ext[1], (ext[0] + ext[1]) / 2);
  for (const w of widgetsNow()) {
    if (w.id === exclude) continue;
    const [a, b] = axis === "x" ? [w.bbox_m[0], w.bbox_m[2]] : [w.bbox_m[1], w.bbox_m[3]];
    lines.push(a, b, (a + b) / 2);
  }
  let best = null;
  for (const c of cands) for (const l of lines) {
    const d = l - c;
    if (Math.abs(d) <= tol && (best === null || Math.abs(d) < Math.abs(best.d))) best = {d, at: l};
  }
  return best;
}

function dragTo(e) {
  const dr = design.drag, g = grid();
  const [sx, sy] = scale();
  const res = g.dx;
  const q = (v) => Math.round(v / res) * res;
  let dx = q((e.clientX - dr.sx) / sx), dy = q(-(e.clientY - dr.sy) / sy);
  design.guides = [];
  const m = dr.mask, b = dr.box0;
  if (!e.altKey) {                      // Alt: the grid only
    const xs = [], ys = [];
    if (m[0]) xs.push(b[0] + dx);
    if (m[2]) xs.push(b[2] + dx);
    if (m[0] && m[2]) xs.push((b[0] + b[2]) / 2 + dx);
    if (m[1]) ys.push(b[1] + dy);
    if (m[3]) ys.push(b[3] + dy);
    if (m[1] && m[3]) ys.push((b[1] + b[3]) / 2 + dy);
    const sxn = snapAxis(xs, "x", dr.id, SNAP_PX / sx), syn = snapAxis(ys, "y", dr.id, SNAP_PX / sy);
    if (sxn) { dx = q(dx + sxn.d); design.guides.push({axis: "x", at: sxn.at}); }
    if (syn) { dy = q(dy + syn.d); design.guides.push({axis: "y", at: syn.at}); }
  }
  dr.d = [m[0] * dx, m[1] * dy, m[2] * dx, m[3] * dy];
  dr.box = [b[0] + dr.d[0], b[1] + dr.d[1], b[2] + dr.d[2], b[3] + dr.d[3]];
  if (dr.box[2] - dr.box[0] < res) dr.box[m[0] ? 0 : 2] = m[0] ? dr.box[2] - res : dr.box[0] + res;
  if (g.rows > 1 && dr.box[3] - dr.box[1] < res) dr.box[m[1] ? 1 : 3] = m[1] ? dr.box[3] - res : dr.box[1] + res;
  const d = $("widgets").querySelector(`[data-widget="${CSS.escape(dr.id)}"]`);
  if (d) place(d, dr.box);
  drawGuides();
  $("status").textContent = `${dr.id}: ${dr.handle ? "resize" : "move"} ` +
    `${(dr.d[0] * 1e3).toFixed(1)}, ${(dr.d[1] * 1e3).toFixed(1)} mm` + (e.altKey ? "" : " (Alt: grid only)");
}

async function endDrag() {
  const dr = design.drag;
  design.guides = [];
  drawGuides();
  if (!dr) return;
  const d = dr.d.map((v) => Math.round(v * 1e7) / 1e4);            // mm
  if (d.every((v) => v === 0)) { design.drag = null; design.draw(); return; }
  design.released = performance.timeOrigin + performance.now();
  design.drag = null;                  // the box stays where it was dropped until the new state draws it
  await design.edit([{op: "box", widget: dr.id, d}], `${dr.handle ? "resize" : "move"} ${dr.id}`);
  design.draw();
}

async function nudge(dx, dy) {
  const id = design.selected, g = grid();
  if (!id || !g) return;
  const d = [dx * g.dx * 1e3, dy * g.dx * 1e3, dx * g.dx * 1e3, dy * g.dx * 1e3].map((v) => Math.round(v * 1e4) / 1e4);
  await design.edit([{op: "box", widget: id, d}], `nudge ${id}`);
}

// ------------------------------------------------------------------ inspector
function valuesOf(id) {
  return ((studio.state && studio.state.values) || []).find((v) => v.id === id);
}

function shown(v) {
  if (v === undefined || v === null) return "";
  return typeof v === "string" ? v : JSON.stringify(v);
}

function effective(id, key) {          // the compiled value (SI) of a key, for the placeholder
  const p = ((studio.state && studio.state.widget_params) || {})[id] || {};
  const v = p[key];
  if (typeof v !== "number") return typeof v === "string" ? v : "";
  const lengths = ["height", "depth", "ramp", "corner_radius", "width", "track_width", "track_depth", "track_ramp",
                   "thumb_size", "detent_height", "detent_width", "knob_size"];
  return lengths.includes(key) ? `${+(Math.abs(v) * 1e3).toPrecision(4)} mm` : `${+v.toPrecision(4)}`;
}

// The value typed into a field, as the file should hold it: a bare number gets the key's unit.
function parseField(spec, text) {
  const t = text.trim();
  if (t === "") return null;
  if (spec.kind === "num") return /^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$/.test(t) ? Number(t) : t;
  if (spec.kind === "bool") return t === "true" ? true : t === "false" ? false : t;
  if (spec.kind === "detents") return /^\d+$/.test(t) ? Number(t) : t;
  if (spec.kind === "array" || spec.key === "distinct_from" || t.startsWith("[")) {
    try { return JSON.parse(t); } catch (err) { return t; }
  }
  if (spec.unit && /^[-+]?[\d.]+([x,:][-+]?[\d.]+)?$/.test(t)) return `${t} ${spec.unit}`;
  return t;
}

function inspect() {
  const box = $("inspector-fields");
  const id = design.selected;
  box.innerHTML = "";
  $("inspector-title").textContent = id ? id : "no widget selected (click one on the top view)";
  $("duplicate").disabled = $("delete").disabled = !id;
  if (!id || !design.schema) return;
  const vals = valuesOf(id);
  if (!vals || !vals.type || !design.schema.types[vals.type]) return;
  $("inspector-title").textContent = `${id} · ${vals.type}`;
  const spec = design.schema.types[vals.type];
  for (const k of spec.keys) {
    if (k.key === "id") continue;
    const row = document.createElement("label");
    row.className = "field" + (k.strength ? " strength" : "");
    const name = document.createElement("span");
    name.className = "key";
    name.textContent = k.key;
    name.title = k.strength ? `strength: give one of ${spec.strength.join(", ")} (writing one removes the others)` : k.hint;
    row.appendChild(name);
    const own = vals.values[k.key], inh = vals.inherited[k.key];
    let input;
    if (k.choices) {
      input = document.createElement("select");
      const o0 = document.createElement("option");
      o0.value = "";
      o0.textContent = inh !== undefined ? `(defaults: ${shown(inh)})` : `(built-in${effective(id, k.key) ? ": " + effective(id, k.key) : ""})`;
      input.appendChild(o0);
      for (const c of k.choices) {
        const o = document.createElement("option");
        o.value = c; o.textContent = c;
        input.appendChild(o);
      }
      input.value = own !== undefined ? String(own) : "";
    } else {
      input = document.createElement("input");
      input.value = shown(own);
      const eff = effective(id, k.key);
      input.placeholder = inh !== undefined ? `${shown(inh)} (defaults)` : eff ? `${eff} (compiled)` : (k.hint || "");
    }
    input.name = k.key;
    input.dataset.kind = k.kind;
    row.appendChild(input);
    const unit = document.createElement("span");
    unit.className = "unit";
    unit.textContent = k.unit;
    const hint = k.key === "position" && topLeft() ? "x,y of the top-left corner (y down)" : k.hint;
    if (hint) row.title = hint;
    row.appendChild(unit);
    const msg = document.createElement("small");
    msg.className = "msg";
    row.appendChild(msg);
    let timer = null;
    input.addEventListener("input", () => {
      clearTimeout(timer);
      timer = setTimeout(() => checkField(id, k, input, msg), 200);
    });
    input.addEventListener("change", () => setField(id, k, input, msg));
    input.addEventListener("keydown", (e) => { if (e.key === "Enter") { e.preventDefault(); input.blur(); } });
    box.appendChild(row);
  }
}

async function checkField(id, spec, input, msg) {
  const value = parseField(spec, input.value);
  const {data} = await post("/api/check", {ops: [{op: "set", widget: id, key: spec.key, value}]});
  msg.textContent = data.error ? data.error.replace(/^scene '[^']*': /, "") : "";
  input.classList.toggle("invalid", !!data.error);
}

async function setField(id, spec, input, msg) {
  const value = parseField(spec, input.value);
  const own = (valuesOf(id) || {values: {}}).values[spec.key];
  if (JSON.stringify(own === undefined ? null : own) === JSON.stringify(value)) return;
  design.released = performance.timeOrigin + performance.now();
  const r = await design.edit([{op: "set", widget: id, key: spec.key, value}],
                              `${id}.${spec.key} = ${value === null ? "(removed)" : shown(value)}`);
  if (r && r.error) {
    msg.textContent = r.error.replace(/^scene '[^']*': /, "");
    input.classList.add("invalid");
  }
}

// ------------------------------------------------------------------ palette
function palette() {
  const el = $("palette");
  el.innerHTML = "";
  for (const t of design.schema.palette) {
    const b = document.createElement("button");
    b.dataset.add = t;
    b.textContent = "+ " + t;
    b.title = `add a ${t} in the middle of the canvas`;
    b.addEventListener("click", () => design.edit([{op: "add", type: t}], `add a ${t}`).then(() => design.select(design.selected)));
    el.appendChild(b);
  }
}

// ------------------------------------------------------------------ history
function history() {
  const h = studio.state && studio.state.history;
  $("undo").disabled = !(h && h.can_undo);
  $("redo").disabled = !(h && h.can_redo);
  const ol = $("history");
  ol.innerHTML = "";
  if (!h) return;
  const first = document.createElement("li");
  first.textContent = "the file as the history began";
  first.className = h.position === 0 ? "current" : "";
  first.dataset.position = 0;
  ol.appendChild(first);
  h.steps.forEach((s, k) => {
    const li = document.createElement("li");
    li.textContent = s.label;
    li.dataset.position = k + 1;
    li.className = (k + 1 === h.position ? "current" : "") + (k + 1 > h.position ? " undone" : "");
    ol.appendChild(li);
  });
  for (const li of ol.children) li.addEventListener("click", () => jump(+li.dataset.position));
  const cur = ol.querySelector(".current");
  if (cur) cur.scrollIntoView({block: "nearest"});
}

async function jump(position) {           // undo or redo until the history stands at `position`
  for (let guard = 0; guard < 400; guard++) {
    const h = studio.state.history;
    if (h.position === position) return;
    const before = h.position;
    await (h.position > position ? design.undo() : design.redo());
    if (studio.state.history.position === before) return;          // refused: stop
  }
}

// ------------------------------------------------------------------ conflicts
function linesDiffer(a, b) {               // the line numbers of `a` whose text `b` does not have at the same line
  const la = a.split("\n"), lb = b.split("\n");
  return la.map((l, i) => l !== lb[i]);
}

function fill(pre, text, marks) {
  pre.innerHTML = "";
  text.split("\n").forEach((l, i) => {
    const s = document.createElement("span");
    s.textContent = l + "\n";
    if (marks[i]) s.className = "changed";
    pre.appendChild(s);
  });
}

function showConflict(data, what) {
  design.conflict = {base: data.base, mine: data.mine, disk: data.disk, disk_version: data.disk_version, what};
  $("conflict").hidden = false;
  $("conflict-text").textContent = data.conflict;
  const mine = data.mine === null || data.mine === undefined ? "(this page's change cannot be shown on its old version)" : data.mine;
  fill($("conflict-mine"), mine, linesDiffer(mine, data.disk));
  fill($("conflict-disk"), data.disk, linesDiffer(data.disk, mine));
  $("keep-mine").disabled = $("merge").disabled = typeof data.mine !== "string";
  $("conflict-result").textContent = "";
  $("status").textContent = "conflict: the file changed on disk; nothing was written — choose below";
}

async function resolve(choice) {
  const c = design.conflict;
  if (!c) return;
  const {status, data} = await post("/api/resolve", {choice, base: c.base, mine: c.mine, disk_version: c.disk_version});
  if (status === 409) { showConflict(data, c.what); return; }
  if (status !== 200) { $("conflict-result").textContent = data.error || String(status); return; }
  design.conflict = null;
  $("conflict").hidden = true;
  studio.dirty = false;
  if (data.conflicts && data.conflicts.length) {
    $("status").textContent = `merged; ${data.conflicts.length} place(s) changed on both sides kept the disk's: ` +
      data.conflicts.map((k) => `line ${k.line}`).join(", ");
  } else {
    $("status").textContent = choice === "disk" ? "took the disk's version" : choice === "mine" ? "kept this page's version" : "merged";
  }
  if (data.state) await api.applyState(data.state, true);
}

// ------------------------------------------------------------------ A/B
async function abSwitch() {
  if (!studio.node) await api.startFeel();
  else if (studio.ctx && studio.ctx.state !== "running") await api.toggleFeel();
  const to = design.abPlaying === "B" ? "A" : "B";
  let layout, payload;
  if (to === "A") {
    const r = await api.fetchRuntime("a");
    layout = r.layout; payload = r.payload;
  } else {
    layout = studio.layout; payload = studio.payload;
  }
  design.abPlaying = to;
  $("ab-box").open = true;
  await api.postTable(studio.node, layout, payload);
  showAB();
}
design.abSwitch = abSwitch;

async function pin() {
  const {status, data} = await post("/api/pin", {});
  if (status === 200) {
    if (design.abPlaying === "A") design.abPlaying = "B";
    if (studio.node) await api.postTable(studio.node, studio.layout, studio.payload);
    await api.applyState(data.state);
  }
}

function showAB() {
  const ab = studio.state && studio.state.ab;
  const b = $("ab");
  b.textContent = `A/B: playing ${design.abPlaying}`;
  b.setAttribute("aria-pressed", design.abPlaying === "A" ? "true" : "false");
  b.dataset.playing = design.abPlaying;
  if (studio.playing) b.dataset.checksum = studio.playing.checksum || "";
  const ul = $("ab-diff");
  ul.innerHTML = "";
  if (!ab) return;
  $("ab-label").textContent = `A = ${ab.a_label} (table ${ab.a_generation}), B = the current table` +
    (ab.a_checksum === ab.b_checksum ? ": identical" : "");
  for (const c of ab.changes) {
    const li = document.createElement("li");
    li.textContent = c.line;
    ul.appendChild(li);
  }
}
design.showAB = showAB;

// ------------------------------------------------------------------ keys
function typing(e) {
  const t = e.target;
  return t && (t.tagName === "INPUT" || t.tagName === "TEXTAREA" || t.tagName === "SELECT" || t.isContentEditable);
}

function keys(e) {
  const mod = e.ctrlKey || e.metaKey;
  if (mod && (e.key === "z" || e.key === "Z" || e.key === "y")) {
    if (e.target === $("text") && studio.dirty) return;        // the editor's own undo, until it is saved
    if (typing(e) && e.target !== $("text")) return;
    e.preventDefault();
    if (e.key === "y" || e.shiftKey) design.redo(); else design.undo();
    return;
  }
  if (typing(e)) return;
  if (mod && e.key === "d") { e.preventDefault(); if (design.selected) duplicate(); return; }
  if (mod) return;
  const step = e.shiftKey ? 10 : 1;
  const arrows = {ArrowLeft: [-step, 0], ArrowRight: [step, 0], ArrowUp: [0, step], ArrowDown: [0, -step]};
  if (arrows[e.key] && design.selected) { e.preventDefault(); nudge(...arrows[e.key]); return; }
  if ((e.key === "Delete" || e.key === "Backspace") && design.selected) { e.preventDefault(); remove(); return; }
  if (e.key === "Escape") { design.select(null); return; }
  if (e.key === "a" || e.key === "A") { abSwitch(); return; }
  if (e.key === "v") { $("tool").value = "edit"; tool(); return; }
  if (e.key === "f") { $("tool").value = "feel"; tool(); return; }
}

function duplicate() {
  return design.edit([{op: "duplicate", widget: design.selected}], `duplicate ${design.selected}`).then(() => inspect());
}
function remove() {
  const id = design.selected;
  return design.edit([{op: "delete", widget: id}], `delete ${id}`).then(() => { design.selected = null; design.draw(); inspect(); });
}

function tool() {
  $("widgets").classList.toggle("feel", !editing());
  $("map-wrap").classList.toggle("editing", editing());
}

// ------------------------------------------------------------------ rulers and grid
design.rulers = function () {
  const g = grid();
  if (!g) return;
  const img = $("map"), W = img.clientWidth, H = img.clientHeight;
  const [sx] = scale();
  const pxmm = sx / 1000;
  const major = pxmm * 10 >= 30 ? 10 : 20;
  const minor = pxmm >= 4 ? 1 : 5;
  const rx = $("ruler-x"), ry = $("ruler-y");
  rx.width = W + 2; rx.height = 18; ry.width = 30; ry.height = H + 2;
  rx.style.width = rx.width + "px"; ry.style.height = ry.height + "px";
  const cx = rx.getContext("2d"), cy = ry.getContext("2d");
  cx.clearRect(0, 0, rx.width, rx.height); cy.clearRect(0, 0, ry.width, ry.height);
  cx.font = cy.font = "10px system-ui"; cx.fillStyle = cy.fillStyle = "#555"; cx.strokeStyle = cy.strokeStyle = "#888";
  const x1 = g.x0 + (g.cols - 1) * g.dx, y1 = g.y0 + (g.rows - 1) * g.dy;
  for (let mmv = Math.ceil(g.x0 * 1e3 / minor) * minor; mmv <= x1 * 1e3 + 1e-9; mmv += minor) {
    const [u] = api.toPicture(mmv / 1e3, g.y0);
    const px = 1 + u * W, big = mmv % major === 0;
    cx.beginPath(); cx.moveTo(px, 18); cx.lineTo(px, big ? 6 : 13); cx.stroke();
    if (big) cx.fillText(String(mmv), px + 2, 9);
  }
  const down = topLeft();                 // [canvas] origin = "top-left": the file's y runs down from the top
  if (g.rows > 1) {
    for (let mmv = Math.ceil(g.y0 * 1e3 / minor) * minor; mmv <= y1 * 1e3 + 1e-9; mmv += minor) {
      const [, v] = api.toPicture(g.x0, (down ? y1 * 1e3 - mmv : mmv) / 1e3);
      const py = 1 + v * H, big = mmv % major === 0;
      cy.beginPath(); cy.moveTo(30, py); cy.lineTo(big ? 18 : 25, py); cy.stroke();
      if (big) cy.fillText(String(mmv), 1, down ? py + 10 : py - 2);
    }
  }
  cy.fillText(down ? "y↓" : "y↑", 1, down ? ry.height - 3 : 10);
  $("ruler-y").title = down ? "y in the scene's frame: down from the top edge ([canvas] origin = \"top-left\")"
                            : "y in the scene's frame: up from the bottom edge";
};

function topLeft() { return !!(studio.state && studio.state.origin === "top-left"); }
design.fileY = (y) => {                  // a table y (m, up) as the scene file writes it
  const g = grid();
  return topLeft() && g ? g.y0 + (g.rows - 1) * g.dy - y : y;
};

// The mm grid drawn on the overlay (called by the page's overlay drawing).
design.drawGrid = function (c, w, h) {
  if (!$("show-grid").checked || !grid()) return;
  const g = grid();
  const [sx] = scale();
  const stepMm = sx / 1000 >= 8 ? 1 : 5;
  c.save();
  c.strokeStyle = "rgba(255,255,255,0.18)";
  c.lineWidth = 1;
  const x1 = g.x0 + (g.cols - 1) * g.dx, y1 = g.y0 + (g.rows - 1) * g.dy;
  for (let m = Math.ceil(g.x0 * 1e3 / stepMm) * stepMm; m <= x1 * 1e3 + 1e-9; m += stepMm) {
    const [u] = api.toPicture(m / 1e3, g.y0);
    c.beginPath(); c.moveTo(u * w + 0.5, 0); c.lineTo(u * w + 0.5, h); c.stroke();
  }
  if (g.rows > 1) for (let m = Math.ceil(g.y0 * 1e3 / stepMm) * stepMm; m <= y1 * 1e3 + 1e-9; m += stepMm) {
    const [, v] = api.toPicture(g.x0, m / 1e3);
    c.beginPath(); c.moveTo(0, v * h + 0.5); c.lineTo(w, v * h + 0.5); c.stroke();
  }
  c.restore();
};

// ------------------------------------------------------------------ state from the server
design.onState = function (st) {
  if (st.scene_version) studio.version = st.scene_version;
  design.draw();
  if (!design.drag) inspect();
  history();
  showAB();
  design.rulers();
};

export async function initDesign(helpers) {
  api = helpers;
  studio = window.studio;
  studio.design = design;
  design.showConflict = showConflict;
  const r = await api.fetchOk("/api/schema");
  design.schema = await r.json();
  palette();
  document.addEventListener("keydown", keys);
  $("undo").addEventListener("click", () => design.undo());
  $("redo").addEventListener("click", () => design.redo());
  $("revert").addEventListener("click", () => design.revert());
  $("duplicate").addEventListener("click", duplicate);
  $("delete").addEventListener("click", remove);
  $("ab").addEventListener("click", abSwitch);
  $("pin").addEventListener("click", pin);
  $("tool").addEventListener("change", tool);
  $("show-grid").addEventListener("change", () => api.drawOverlay());
  $("keep-mine").addEventListener("click", () => resolve("mine"));
  $("take-disk").addEventListener("click", () => resolve("disk"));
  $("merge").addEventListener("click", () => resolve("merge"));
  // a click on flat ground (not on a widget) in the edit tool clears the selection
  $("map-wrap").addEventListener("pointerdown", (e) => { if (editing() && !e.target.closest(".wbox")) design.select(null); });
  tool();
  if (studio.state) design.onState(studio.state);
}
