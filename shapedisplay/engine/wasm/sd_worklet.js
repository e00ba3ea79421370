// sd_worklet.js -- AudioWorkletProcessor "shapedisplay-renderer": the C runtime (sd_runtime.wasm)
// renders the burst drive in the browser's audio thread.
//
// Main thread:
//   const module = await WebAssembly.compileStreaming(fetch("sd_runtime.wasm"));
//   await ctx.audioWorklet.addModule("sd_worklet.js");          // sd_wasm.js beside it
//   const node = new AudioWorkletNode(ctx, "shapedisplay-renderer",
//       {numberOfInputs: 0, outputChannelCount: [1],
//        processorOptions: {module, model: "jump", policy: "retrigger", tickRate: 10000}});
//   node.connect(ctx.destination);
//   node.port.postMessage({type: "table", image: arrayBuffer});  // binary table image; again to swap
//   node.port.postMessage({type: "cursor", x, y});               // metres, whenever the pointer moves
//   node.port.onmessage = (e) => { e.data.type: "values" | "loaded" | "error" };
//
// The audio rate is the AudioContext's sampleRate. Each render quantum runs as many renderer
// ticks as its samples need, with the cursor moving linearly from the previous quantum's
// position to the latest one received; about every 1/60 s it posts
//   {type: "values", t, x, y, normal_force, friction_force, state, lateral_x, lateral_y,
//    skin_stretch, events, drive, clipped, events_total}
// (the last tick's channel values). Messages: "table" {image}, "cursor" {x, y},
// "configure" {model, policy, tickRate}, "reset" {}.
import {SdRuntime, OUT_NAMES} from "./sd_wasm.js";

class ShapeDisplayRenderer extends AudioWorkletProcessor {
  constructor(options) {
    super();
    const o = options.processorOptions || {};
    this.rt = SdRuntime.fromModule(o.module);
    this.settings = {model: o.model || "jump", policy: o.policy || "retrigger", tickRate: o.tickRate,
                     audioRate: sampleRate};
    this.ready = false;
    this.x = 0; this.y = 0; this.px = 0; this.py = 0;
    this.fifo = new Float32Array(4096);    // samples rendered but not yet played
    this.head = 0; this.count = 0;
    this.sinceValues = 0;
    this.port.onmessage = (e) => this.onMessage(e.data);
  }

  onMessage(m) {
    try {
      if (m.type === "table") {
        const first = !this.ready;
        this.rt.loadTable(new Uint8Array(m.image));
        if (first) this.rt.configure(this.settings);
        this.ready = true;
        this.port.postMessage({type: "loaded", bytes: m.image.byteLength});
      } else if (m.type === "cursor") {
        this.x = m.x; this.y = m.y;
      } else if (m.type === "configure") {
        Object.assign(this.settings, m, {audioRate: sampleRate});
        if (this.ready) this.rt.configure(this.settings);
      } else if (m.type === "reset") {
        this.rt.reset(0);
        this.count = 0;
      }
    } catch (err) {
      this.port.postMessage({type: "error", message: String(err.message || err)});
    }
  }

  push(samples) {
    for (let i = 0; i < samples.length && this.count < this.fifo.length; i++) {
      this.fifo[(this.head + this.count) % this.fifo.length] = samples[i];
      this.count++;
    }
  }

  process(inputs, outputs) {
    const out = outputs[0][0];
    if (!this.ready) { out.fill(0); return true; }
    // ticks until this quantum's samples are rendered (bounded: the FIFO holds 4096 samples)
    let k = 0;
    const need = out.length;
    const ticks = Math.ceil((need - this.count) * this.settings.tickRate / sampleRate) + 1;
    while (this.count < need && k < 4 * ticks) {
      const u = (k + 1) / ticks;
      const x = this.px + (this.x - this.px) * Math.min(u, 1);
      const y = this.py + (this.y - this.py) * Math.min(u, 1);
      this.rt.step(x, y);
      this.push(this.rt.audio());
      k++;
    }
    this.px = this.x; this.py = this.y;
    for (let i = 0; i < need; i++) {
      if (this.count > 0) {
        out[i] = this.fifo[this.head];
        this.head = (this.head + 1) % this.fifo.length;
        this.count--;
      } else {
        out[i] = 0;
      }
    }
    for (let c = 1; c < outputs[0].length; c++) outputs[0][c].set(out);
    this.sinceValues += need;
    if (this.sinceValues >= sampleRate / 60) {
      this.sinceValues = 0;
      const o = this.rt.outputs();
      const msg = {type: "values"};
      for (const n of OUT_NAMES) msg[n] = o[n];
      const c = this.rt.counters();
      msg.clipped = c.clipped; msg.events_total = c.events;
      this.port.postMessage(msg);
    }
    return true;
  }
}

registerProcessor("shapedisplay-renderer", ShapeDisplayRenderer);
