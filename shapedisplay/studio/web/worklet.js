// AudioWorklet of the studio: the C runtime (WebAssembly) plays the table in the audio thread.
//
// Every rendering step is the C renderer's (sd_runtime.wasm through its wrapper sd_wasm.js);
// this file only moves the cursor to the tick times, queues the renderer's audio samples for
// the output, and records the stroke. Real-time rules: no allocation per tick or per render quantum (all
// buffers are made when a table is bound); a message is posted ~30 times a second (meters)
// and once at the end of a stroke (the recording).
//
// Cursor input (messages {type: "cursor", kind: "down" | "move" | "up", t, x, y}):
//   direct mode: (x, y) is the cursor position in metres at audio-context time t;
//   stick mode:  (x, y) is the pointing-stick force in newtons; v = alpha f moves the cursor.
// The cursor is rendered `delay` seconds (sent with "down", from the pointer's event rate)
// behind the input so that every tick falls between two input points (linear interpolation);
// a stroke runs from "down" to "up".
// Scripted strokes ({type: "script", x: Float64Array, y: Float64Array}) give one position per
// tick: the offline test and benchmark path (OfflineAudioContext).
// A cursor point may carry `press` (N along z, docs/reactive.md): the table's reactive widgets react; their
// events (ReactionEvent: [kind, widget, t, value]) and states go to the page with the meters. A stroke
// starts a new run that keeps the widgets where they are (a flipped toggle stays flipped).
// The pad model ({type: "model", model}, or `model` with a table) is one the layout offers:
// layout.models[model].pad holds its parameters (decoded to a Float64Array by the page), handed
// to the C runtime with the configuration; switching restarts the renderer on the same table.

import {SdRuntime, OUT_NAMES} from "/static/sd_wasm.js?token={{TOKEN}}";

const MAX_TICKS = 300000;          // one stroke recorded: 30 s at 10 kHz
const MAX_EVENTS = 200000;
const RING = 16384;                // audio samples queued for the output

class StudioRenderer extends AudioWorkletProcessor {
  constructor(options) {
    super();
    const o = (options && options.processorOptions) || {};
    this.delay = o.delay !== undefined ? o.delay : 0.02;
    this.mode = "direct";
    this.rt = null;
    this.ready = false;
    this.points = [];
    this.touching = false;
    this.script = null;
    this.ring = new Float32Array(RING);
    this.ringRead = 0;
    this.ringCount = 0;
    this.rec = null;
    this.lastMeter = 0;
    this.model = o.model || null;     // the pad model played (null: the layout's)
    this.layout = null;
    this.reactions = [];               // reaction events not yet posted: [kind, widget, t, value]
    this.press = 0;
    this.port.onmessage = (e) => this.onMessage(e.data);
    // Offline renders hand everything over at construction: nothing waits on a message.
    if (o.module) {
      this.rt = SdRuntime.fromModule(o.module);
      if (o.layout) this.bind(o.layout, o.payload);
      if (o.script) this.script = {x: o.script.x, y: o.script.y, i: 0};
    }
  }

  onMessage(m) {
    if (m.type === "module") {
      this.rt = SdRuntime.fromModule(m.module);
      this.port.postMessage({type: "module-ready"});
    } else if (m.type === "table") {
      if (m.model) this.model = m.model;
      this.bind(m.layout, m.payload);
    } else if (m.type === "model") {
      this.model = m.model;
      if (this.layout) this.useModel("model changed");
      this.port.postMessage({type: "model-ready", model: m.model, rc: this.rc, error: this.error});
    } else if (m.type === "cursor") {
      this.points.push(m);
    } else if (m.type === "mode") {
      this.mode = m.mode;
      this.stickScale = m.stickScale || 0;
    } else if (m.type === "script") {
      this.script = {x: m.x, y: m.y, i: 0};
    }
  }

  // Configure the renderer for this.model on the bound table (a restart); rc 0 or the error.
  useModel(reason) {
    const layout = this.layout, name = this.model || layout.model, entry = layout.models[name];
    this.rc = 0; this.error = null;
    if (this.touching) this.endStroke(reason);
    try {
      if (!entry) throw new Error(`model ${name}: the page offers ${Object.keys(layout.models).join(", ")}`);
      if (entry.error) throw new Error(`model ${name}: ${entry.error}`);
      this.rt.configure({model: name, policy: layout.policy, tickRate: layout.tick_rate,
                         audioRate: layout.audio_rate, pad: entry.pad});
    } catch (err) {
      this.rc = err.code || -1; this.error = String(err.message || err);
    }
    this.ready = this.rc === 0;
    this.playing = this.ready ? name : null;
  }

  // Load a table image (shapedisplay.studio.wasm.table_payload) and (re)start the renderer on it.
  bind(layout, payload) {
    // a stroke under way goes on over the new table (an edit or an A/B switch while stroking)
    const was = this.touching && this.w ? {tau: this.tStart + this.k / this.tickRate, x: this.cx, y: this.cy} : null;
    this.layout = layout;
    try {
      this.rt.loadTable(new Uint8Array(payload));
      this.useModel("table swapped");
    } catch (err) {
      this.rc = err.code || -1; this.error = String(err.message || err); this.ready = false;
    }
    const rc = this.rc;
    const w = this.rt.x;
    this.w = w;
    const g = layout.grid;
    this.tickRate = layout.tick_rate;
    this.alpha = layout.cursor_gain;
    this.extent = [g.x0, g.y0, g.x0 + (g.cols - 1) * g.dx, g.y0 + (g.rows - 1) * g.dy];
    const o = OUT_NAMES;
    this.iT = o.indexOf("t"); this.iN = o.indexOf("normal_force"); this.iF = o.indexOf("friction_force");
    this.iState = o.indexOf("state"); this.iNev = o.indexOf("events"); this.iDrive = o.indexOf("drive");
    this.iNaudio = o.indexOf("audio_samples");
    // views made once per table (loading may grow the memory); a tick reads through them
    this.mem = new Float64Array(w.memory.buffer);
    this.out = new Float64Array(w.memory.buffer, w.sd_wasm_outputs(), OUT_NAMES.length);
    this.audioAt = w.sd_wasm_audio() >> 3;
    if (!this.rec) {
      this.rec = {
        t: new Float64Array(MAX_TICKS), x: new Float64Array(MAX_TICKS), y: new Float64Array(MAX_TICKS),
        n: new Float64Array(MAX_TICKS), f: new Float64Array(MAX_TICKS), state: new Float64Array(MAX_TICKS),
        drive: new Float64Array(MAX_TICKS), evT: new Float64Array(MAX_EVENTS), evA: new Float64Array(MAX_EVENTS),
        audio: new Float32Array(MAX_TICKS * 8), ticks: 0, events: 0, samples: 0, lost: 0,
      };
    }
    this.generation = layout.generation;
    if (was && this.ready) this.startStroke(was.tau, was.x, was.y);
    this.port.postMessage({type: "table-ready", generation: layout.generation, rc: rc, error: this.error,
                           model: this.playing, checksum: layout.checksum, which: layout.which || "B"});
  }

  startStroke(tInput, x, y) {
    this.w.sd_wasm_restart(0.0);     // the reactive widgets stay where the last stroke left them
    this.press = 0;
    this.touching = true;
    this.k = 0;
    this.tStart = tInput;            // input time of tick 0
    this.cx = x; this.cy = y;        // stick mode: cursor position
    const r = this.rec;
    r.ticks = 0; r.events = 0; r.samples = 0; r.lost = 0;
  }

  endStroke(reason) {
    this.touching = false;
    const r = this.rec;
    const n = r.ticks, ne = r.events, ns = r.samples;
    this.port.postMessage({
      type: "stroke", reason: reason, generation: this.generation, model: this.playing, ticks: n, lost: r.lost,
      tickRate: this.tickRate, clipped: this.w.sd_wasm_counter(0),
      t: r.t.slice(0, n), x: r.x.slice(0, n), y: r.y.slice(0, n), normal_force: r.n.slice(0, n),
      friction_force: r.f.slice(0, n), state: r.state.slice(0, n), drive: r.drive.slice(0, n),
      event_time: r.evT.slice(0, ne), event_amplitude: r.evA.slice(0, ne), audio: r.audio.slice(0, ns),
    });
  }

  // Cursor input at input time tau: linear between the queued points around it.
  cursorAt(tau) {
    const p = this.points;
    while (p.length > 1 && p[1].t <= tau) p.shift();
    const a = p[0];
    this.press = a.press || 0;       // the press holds from one point to the next
    if (p.length === 1 || tau <= a.t) return [a.x, a.y];
    const b = p[1];
    const u = (tau - a.t) / (b.t - a.t);
    return [a.x + (b.x - a.x) * u, a.y + (b.y - a.y) * u];
  }

  tick(x, y) {
    const w = this.w, r = this.rec, out = this.out, mem = this.mem;
    w.sd_wasm_step_press(x, y, this.press);
    for (let p = w.sd_wasm_react_pop(); p; p = w.sd_wasm_react_pop()) {
      const q = p >> 3;
      if (this.reactions.length < 256) this.reactions.push([mem[q], mem[q + 1], mem[q + 2], mem[q + 3]]);
    }
    const na = out[this.iNaudio];
    for (let i = 0; i < na; i++) {
      const s = mem[this.audioAt + i];
      this.ring[(this.ringRead + this.ringCount) % RING] = s;
      this.ringCount++;
      if (r.samples < r.audio.length) r.audio[r.samples++] = s;
    }
    if (r.ticks < MAX_TICKS) {
      const j = r.ticks++;
      r.t[j] = out[this.iT]; r.x[j] = x; r.y[j] = y; r.n[j] = out[this.iN]; r.f[j] = out[this.iF];
      r.state[j] = out[this.iState]; r.drive[j] = out[this.iDrive];
      const nev = w.sd_wasm_tick_events();
      if (nev > 0) {
        const pt = w.sd_wasm_event_times() >> 3, pa = w.sd_wasm_event_amplitudes() >> 3;
        for (let e = 0; e < nev; e++) {
          if (r.events < MAX_EVENTS) { r.evT[r.events] = mem[pt + e]; r.evA[r.events] = mem[pa + e]; r.events++; }
        }
      }
    } else {
      r.lost++;
    }
    this.k++;
  }

  // Run ticks until the queue holds `need` samples or the stroke ends.
  fill(need) {
    while (this.ringCount < need) {
      if (this.script) {
        const s = this.script;
        if (!this.touching) this.startStroke(0, s.x[0], s.y[0]);
        if (s.i >= s.x.length) { this.script = null; this.endStroke("script done"); return; }
        this.tick(s.x[s.i], s.y[s.i]);
        s.i++;
        continue;
      }
      if (!this.touching) return;
      const tau = this.tStart + this.k / this.tickRate;
      let ended = false;
      for (let i = 0; i < this.points.length; i++) {
        const p = this.points[i];
        if (p.t > tau) break;
        if (p.kind === "up") { ended = true; break; }
      }
      if (ended) {
        this.points = this.points.filter((p) => p.t > tau);
        this.endStroke("up");
        return;
      }
      let x, y;
      if (this.mode === "stick") {
        const f = this.cursorAt(tau);
        if (this.k > 0) {
          this.cx = Math.min(Math.max(this.cx + this.alpha * f[0] / this.tickRate, this.extent[0]), this.extent[2]);
          this.cy = Math.min(Math.max(this.cy + this.alpha * f[1] / this.tickRate, this.extent[1]), this.extent[3]);
        }
        x = this.cx; y = this.cy;
      } else {
        const c = this.cursorAt(tau);
        x = c[0]; y = c[1];
      }
      this.tick(x, y);
    }
  }

  process(inputs, outputs) {
    const outs = outputs[0];
    const n = outs[0].length;
    if (this.ready) {
      if (!this.touching && !this.script && this.points.length) {
        // a "down" that is due starts a stroke (its start position: the down point itself)
        while (this.points.length && this.points[0].kind !== "down") this.points.shift();
        const delay = this.points.length && this.points[0].delay !== undefined ? this.points[0].delay : this.delay;
        if (this.points.length && this.points[0].t <= currentTime - delay) {
          const d = this.points[0];
          this.startStroke(d.t, this.mode === "stick" ? d.px : d.x, this.mode === "stick" ? d.py : d.y);
        }
      }
      this.fill(n);
    }
    const ch0 = outs[0];
    const take = Math.min(n, this.ringCount);
    for (let i = 0; i < take; i++) ch0[i] = this.ring[(this.ringRead + i) % RING];
    for (let i = take; i < n; i++) ch0[i] = 0;
    this.ringRead = (this.ringRead + take) % RING;
    this.ringCount -= take;
    for (let c = 1; c < outs.length; c++) outs[c].set(ch0);
    if (this.ready && currentTime - this.lastMeter > 0.033) {
      this.lastMeter = currentTime;
      const out = this.out;
      const w = this.w, nw = w.sd_wasm_react_n(), k = w.sd_wasm_react_state_size();
      this.port.postMessage({type: "meter", touching: this.touching, state: out[this.iState],
                             n: out[this.iN], f: out[this.iF], events: this.rec ? this.rec.events : 0,
                             x: this.rec && this.rec.ticks ? this.rec.x[this.rec.ticks - 1] : 0,
                             y: this.rec && this.rec.ticks ? this.rec.y[this.rec.ticks - 1] : 0,
                             press: this.press, reactions: this.reactions.splice(0),
                             widgets: nw ? new Float64Array(w.memory.buffer, w.sd_wasm_react_states(), nw * k).slice() : null});
    }
    return true;
  }
}

registerProcessor("sd-renderer", StudioRenderer);
