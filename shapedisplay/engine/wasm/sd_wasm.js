// sd_wasm.js -- JavaScript wrapper of sd_runtime.wasm (the shapedisplay C runtime in WebAssembly).
//
// Works wherever WebAssembly does (an AudioWorklet, a page, node): no DOM, no fetch.
//
//   const rt = await SdRuntime.create(moduleOrBytes);   // WebAssembly.Module, or the .wasm bytes
//   rt.loadTable(imageBytes);          // binary table image (export --format bin); throws on a bad image
//   rt.configure({model: "jump", policy: "retrigger", tickRate: 10000, audioRate: 48000});
//   rt.configure({model: "karnopp", pad});   // pad: the model's parameters, PAD_FIELDS order (the image
//                                      // carries only mass, stiffness, damping, burst gain and stick limit;
//                                      // karnopp and stribeck need a block: shapedisplay.studio.wasm.table_payload)
//   const drive = rt.step(x, y);       // one tick, cursor in metres
//   rt.step(x, y, press);              // ... pressing with `press` N (docs/reactive.md: buttons, toggles, ...)
//   rt.reactions();                    // [{kind: "toggle", widget: 1, t, value}, ...]: events since the last call
//   rt.widgetStates();                 // [{pressed, state, grabbed, dx, dy, thumb, value, ...}, ...] per widget
//   rt.audio();                        // Float64Array view: the last tick's audio samples
//   rt.outputs();                      // {t, x, y, vx, vy, normal_force, ...} of the last tick
//   rt.tickEvents();                   // {t, a}: the last tick's stick-to-slip events (Float64Array views)
//   rt.sample(x, y);                   // {normal_force, ...}: every stored channel at (x, y), same lookup
//   const n = rt.run(xy, out);         // many ticks: xy = Float64Array [x0, y0, x1, y1, ...];
//                                      // audio written to `out` (Float32Array or Float64Array of at
//                                      // least ticks x audioCap() samples); returns the count written
// A table can be swapped while playing (loadTable again): the model, policy and rates stay.
// Real-time rule: loadTable/configure may grow memory; step/run never allocate.

// model ids and burst policies as in sd_layout.h (SD_MODEL_*, SD_RETRIGGER..): tests/test_layouts.py checks
export const MODELS = {exact: 0, jump: 1, karnopp: 2, stribeck: 3};
export const POLICIES = {retrigger: 0, add: 1, max: 2};
export const OUT_NAMES = ["t", "x", "y", "vx", "vy", "normal_force", "friction_force", "state", "lateral_x",
                          "lateral_y", "skin_stretch", "events", "drive", "audio_samples", "pad_speed", "mu_s",
                          "mu_k", "burst_gain", "press", "reactions"];
// reaction events (SD_EV_*, numbered from 1) and the fields of a reactive widget's state (REACT_STATE)
export const EVENT_KINDS = ["press", "release", "click", "toggle", "value", "grab", "drop"];
export const REACT_STATE_FIELDS = ["pressed", "state", "grabbed", "dx", "dy", "grab_x", "grab_y", "thumb", "value",
                                   "reported", "region", "clock"];
// table channels in the runtime's slot order (SD_SLOT_*)
export const SLOTS = ["normal_force", "friction_scale", "burst_gain", "grad_x", "grad_y", "lateral_x", "lateral_y",
                      "skin_stretch", "breakaway_force", "kinetic_force"];
// settings stored in the table image (sd_wasm_set / sd_wasm_param index)
export const PARAMS = ["pad_mass_kg", "pad_stiffness_n_per_m", "pad_damping_ns_per_m", "burst_gain",
                       "max_stick_period_s", "mu_s", "mu_k", "slope_friction_gain", "skin_stretch_target_m",
                       "tick_rate_hz", "audio_rate_hz", "burst_carrier_hz", "burst_rise_s", "burst_decay_s"];
// fields of sd_pad_params_t in order (PAD_PARAMS in shapedisplay/render/layouts.py): configure's `pad`
export const PAD_FIELDS = ["mass", "stiffness", "damping", "burst_gain", "max_stick_period", "substep",
                           "karnopp_spring", "karnopp_v_threshold", "stribeck_a", "stribeck_b", "stribeck_p",
                           "stribeck_d", "stribeck_variant", "stribeck_tol", "contactor_amplitude",
                           "contactor_omega", "tanh_eps"];
const ERRORS = {
  "-1": "bad argument or no table loaded", "-2": "table unusable (no normal_force channel?)",
  "-3": "setting out of range", "-10": "image size wrong (truncated?)", "-11": "not a table image",
  "-12": "unsupported image version", "-13": "image CRC mismatch (corrupt)", "-14": "image layout out of bounds",
  "-15": "image misaligned", "-16": "non-finite value in image", "-17": "big-endian host",
  "-18": "channel values overflow (offset + scale x code)",
};

export class SdError extends Error {
  // why: what went wrong, when it says more than the code's meaning
  constructor(what, code, why) {
    super(`${what}: ${why || ERRORS[String(code)] || "error"} (code ${code})`);
    this.code = code;
  }
}

export class SdRuntime {
  static async create(moduleOrBytes) {
    const module = moduleOrBytes instanceof WebAssembly.Module
      ? moduleOrBytes : await WebAssembly.compile(moduleOrBytes);
    return new SdRuntime(new WebAssembly.Instance(module, {}));
  }

  // Synchronous form for an AudioWorkletProcessor constructor (module compiled on the main thread).
  static fromModule(module) {
    return new SdRuntime(new WebAssembly.Instance(module, {}));
  }

  constructor(instance) {
    this.x = instance.exports;
    if (this.x._initialize) this.x._initialize();
    this._hasTable = false;
  }

  _f64(ptr, n) { return new Float64Array(this.x.memory.buffer, ptr, n); }

  loadTable(bytes) {
    const data = bytes instanceof Uint8Array ? bytes : new Uint8Array(bytes);
    // staged apart from the active table: a bad image leaves the playing table intact
    const ptr = this.x.sd_wasm_stage(data.length);
    if (!ptr) throw new SdError("table image", -1);
    new Uint8Array(this.x.memory.buffer, ptr, data.length).set(data);
    const rc = this.x.sd_wasm_load(ptr, data.length);
    if (rc < -3) throw new SdError("table image", rc);
    this._hasTable = true;
    if (rc !== 0) throw new SdError("renderer settings", rc);
  }

  // pad: the model's pad parameters (PAD_FIELDS.length numbers, PAD_FIELDS order), or none: the
  // present ones (the image's, or the block last given for this model)
  configure({model = "jump", policy = "retrigger", tickRate, audioRate, pad} = {}) {
    if (!Object.hasOwn(MODELS, model)) {
      throw new SdError("configure", -3, `model must be one of ${Object.keys(MODELS).join(", ")} (got ${model})`);
    }
    if (!Object.hasOwn(POLICIES, policy)) throw new SdError(`policy ${policy}`, -3);
    if (pad !== undefined && pad !== null && pad.length !== PAD_FIELDS.length) {
      throw new SdError("configure", -1, `pad must hold ${PAD_FIELDS.length} numbers, PAD_FIELDS order (got ${pad.length})`);
    }
    const tr = tickRate ?? this.param("tick_rate_hz");
    const ar = audioRate ?? this.param("audio_rate_hz");
    if (pad !== undefined && pad !== null) {
      const ptr = this.x.sd_wasm_pad_block(pad.length);
      if (!ptr) throw new SdError("pad block", -1);
      this._f64(ptr, pad.length).set(pad);
    }
    const rc = this.x.sd_wasm_configure(MODELS[model], POLICIES[policy], tr, ar);
    if (rc === -1 && this._hasTable && (pad === undefined || pad === null)) {
      throw new SdError("configure", -1, `model ${model} needs its pad parameters (pad, PAD_FIELDS order): ` +
                        "the table image carries only those of exact and jump");
    }
    if (rc === -3 && pad !== undefined && pad !== null) {
      throw new SdError("configure", rc, `model ${model}: the rates or a pad parameter out of range ` +
                        "(a NaN, a fractional stribeck_variant)");
    }
    if (rc !== 0) throw new SdError(`configure ${model}`, rc);
  }

  audioCap() { return this.x.sd_wasm_audio_cap(); }   // most audio samples one tick writes

  param(name) { return this.x.sd_wasm_param(PARAMS.indexOf(name)); }

  set(name, value) {
    const rc = this.x.sd_wasm_set(PARAMS.indexOf(name), value);
    if (rc !== 0) throw new SdError(`setting ${name}`, rc);
  }

  reset(t0 = 0) { this.x.sd_wasm_reset(t0); }

  // a new run that keeps the reactive widgets' states (a flipped toggle stays flipped, a dragged thumb stays)
  restart(t0 = 0) { this.x.sd_wasm_restart(t0); }

  step(x, y, press) { return press ? this.x.sd_wasm_step_press(x, y, press) : this.x.sd_wasm_step(x, y); }

  // reaction events since the last call, oldest first: {kind, widget (index in the table's widgets), t, value}
  reactions() {
    const out = [];
    for (let p = this.x.sd_wasm_react_pop(); p; p = this.x.sd_wasm_react_pop()) {
      const v = this._f64(p, 4);
      out.push({kind: EVENT_KINDS[v[0] - 1], widget: v[1], t: v[2], value: v[3]});
    }
    return out;
  }

  // every reactive widget's state (REACT_STATE_FIELDS), in the table's reaction order
  widgetStates() {
    const n = this.x.sd_wasm_react_n(), k = this.x.sd_wasm_react_state_size();
    const v = this._f64(this.x.sd_wasm_react_states(), n * k);
    const out = [];
    for (let i = 0; i < n; i++) {
      const o = {};
      REACT_STATE_FIELDS.forEach((f, j) => { o[f] = v[i * k + j]; });
      out.push(o);
    }
    return out;
  }

  audio() { return this._f64(this.x.sd_wasm_audio(), this.x.sd_wasm_audio_count()); }

  outputs() {
    const v = this._f64(this.x.sd_wasm_outputs(), OUT_NAMES.length);
    const o = {};
    OUT_NAMES.forEach((n, i) => { o[n] = v[i]; });
    return o;
  }

  tickEvents() {
    const n = this.x.sd_wasm_tick_events();
    return {t: this._f64(this.x.sd_wasm_event_times(), n), a: this._f64(this.x.sd_wasm_event_amplitudes(), n)};
  }

  sample(x, y) {
    const v = this._f64(this.x.sd_wasm_sample(x, y), SLOTS.length);
    const o = {};
    SLOTS.forEach((n, i) => { o[n] = v[i]; });
    return o;
  }

  counters() {
    return {clipped: this.x.sd_wasm_counter(0), events: this.x.sd_wasm_counter(1),
            eventsDropped: this.x.sd_wasm_counter(2)};
  }

  run(xy, out) {
    const n = xy.length >> 1;
    const perTick = this.x.sd_wasm_audio_cap();
    const cap = n * perTick;
    if (out.length < cap) throw new SdError(`run: output needs ${cap} samples for ${n} ticks`, -1);
    const xyPtr = this.x.sd_wasm_scratch(8 * (xy.length + cap));
    if (!xyPtr) throw new SdError("run buffers", -1);
    const audioPtr = xyPtr + 8 * xy.length;
    this._f64(xyPtr, xy.length).set(xy);
    const written = this.x.sd_wasm_run(xyPtr, n, 0, audioPtr, cap);
    if (written < 0) throw new SdError("run", -1);
    out.set(this._f64(audioPtr, written));
    return written;
  }
}
