// Reactive widgets in the studio (docs/reactive.md): the press, the events and the widgets' states.
//
// Hold Space while the pointer is down to press (PRESS_N newtons along z, above the default 2 N threshold
// of a button or toggle): a button clicks, a toggle flips, a slider's thumb is grabbed and follows the
// pointer, a movable widget is dragged. The AudioWorklet (worklet.js) plays the press in the C runtime and
// posts the events and states with its meters; this module keeps the event list (studio.reactions), the
// states by widget id (studio.widgetStates), shows them beside the meters and draws the thumbs and the
// toggles' states on the top view.

export const PRESS_N = 3.0;
// as sd_wasm.js: SD_EV_* numbered from 1, and the fields of a reactive widget's state
const EVENT_KINDS = ["press", "release", "click", "toggle", "value", "grab", "drop"];
const STATE_FIELDS = ["pressed", "state", "grabbed", "dx", "dy", "grab_x", "grab_y", "thumb", "value", "reported",
                      "region", "clock"];
const KEEP = 200;                    // events kept in studio.reactions

export function initReactions(studio, $, resend) {
  studio.press = 0;
  studio.reactions = [];
  studio.widgetStates = {};
  const panel = document.createElement("span");
  panel.id = "reactions";
  panel.className = "meter";
  panel.title = "reactive widgets: hold Space while the pointer is down to press (docs/reactive.md)";
  const status = $("status");
  status.parentNode.insertBefore(panel, status);

  const typing = (e) => e.target && (e.target.closest("input, textarea, select, [contenteditable]"));
  const setPress = (p, e) => {
    if (typing(e) || studio.press === p) return;
    e.preventDefault();
    studio.press = p;
    resend();                        // a press while the pointer rests: the worklet hears it now
    show();
  };
  document.addEventListener("keydown", (e) => { if (e.code === "Space") setPress(PRESS_N, e); });
  document.addEventListener("keyup", (e) => { if (e.code === "Space") setPress(0, e); });

  function show() {
    const states = Object.entries(studio.widgetStates).map(([id, st]) => {
      const r = st.reaction;
      if (r.kind === "toggle") return `${id} ${st.state ? "on" : "off"}`;
      if (r.kind === "slider") return `${id} ${st.value.toFixed(2)}`;
      return null;
    }).filter(Boolean);
    const last = studio.reactions.slice(-3).map((e) => `${e.kind} ${e.widget}`);
    panel.textContent = (studio.press ? "pressing · " : "") + [...states, ...last].join(" · ");
  }

  // The worklet's meter message: new events and every reactive widget's state.
  studio.onReactionMeter = function (m) {
    const layout = studio.layout;
    if (!layout) return;
    let changed = false;
    for (const [k, w, t, value] of m.reactions || []) {
      studio.reactions.push({kind: EVENT_KINDS[k - 1], widget: (layout.widget_ids || [])[w] ?? String(w), t, value});
      changed = true;
    }
    if (studio.reactions.length > KEEP) studio.reactions.splice(0, studio.reactions.length - KEEP);
    if (m.widgets && layout.reactions) {
      const n = STATE_FIELDS.length, next = {};
      layout.reactions.forEach((r, i) => {
        if ((i + 1) * n > m.widgets.length) return;
        const st = {reaction: r};
        STATE_FIELDS.forEach((f, j) => { st[f] = m.widgets[i * n + j]; });
        next[r.id] = st;
      });
      const key = (s) => JSON.stringify(Object.values(s).map((v) => [v.state, v.thumb, v.dx, v.dy, v.pressed]));
      if (key(next) !== key(studio.widgetStates)) changed = true;
      studio.widgetStates = next;
    }
    if (changed) {
      show();
      if (studio.redraw) studio.redraw();
    }
  };

  // On the top view: each slider's thumb where it is, each toggle's state, each moved widget's box.
  studio.drawReactions = function (c, w, h, toPicture) {
    for (const [id, st] of Object.entries(studio.widgetStates)) {
      const r = st.reaction;
      if (st.pressed) {                // pressed: the widget's box lit while the press holds
        const wd = (studio.state.widgets || []).find((x) => x.id === id);
        if (wd) {
          const [x0, y0, x1, y1] = wd.bbox_m;
          const [ua, va] = toPicture(x0, y1), [ub, vb] = toPicture(x1, y0);
          c.fillStyle = "rgba(255, 209, 102, 0.25)";
          c.fillRect(ua * w, va * h, (ub - ua) * w, (vb - va) * h);
        }
      }
      if (r.kind === "slider" && r.thumb_m !== undefined) {
        const along = r.thumb_m + (r.axis ? st.dy : st.dx);
        const [u, v] = r.axis ? toPicture(r.cross_m, along) : toPicture(along, r.cross_m);
        const [u1] = toPicture((r.axis ? r.cross_m : along) + r.thumb_r_m, 0);
        c.beginPath();
        c.arc(u * w, v * h, Math.max(3, Math.abs(u1 - u) * w), 0, 2 * Math.PI);
        c.strokeStyle = st.grabbed ? "#ffd166" : "#7bdff2";
        c.lineWidth = 2;
        c.stroke();
      } else if (r.kind === "toggle") {
        const wd = (studio.state.widgets || []).find((x) => x.id === id);
        if (!wd) continue;
        const [ua, va] = toPicture(wd.bbox_m[0], wd.bbox_m[1]);
        c.fillStyle = st.state ? "#06d6a0" : "#adb5bd";
        c.fillText(st.state ? "on" : "off", ua * w + 2, va * h - 3);
      } else if (r.kind === "object" && (st.dx || st.dy)) {
        const wd = (studio.state.widgets || []).find((x) => x.id === id);
        if (!wd) continue;
        const [x0, y0, x1, y1] = wd.bbox_m;
        const [ua, va] = toPicture(x0 + st.dx, y1 + st.dy), [ub, vb] = toPicture(x1 + st.dx, y0 + st.dy);
        c.setLineDash([4, 3]);
        c.strokeStyle = "#ffd166";
        c.strokeRect(ua * w, va * h, (ub - ua) * w, (vb - va) * h);
        c.setLineDash([]);
      }
    }
  };
  show();
}
