"""Compile a scene into a friction-envelope table, storing only what it needs.

How a scene becomes a table
---------------------------
1. **Groups and blocks.** Each widget occupies its snapped box (canvas
   samples). The stored region of a widget is its box grown by the *reach*
   of the gradient method (1 sample for central differences), so the slopes
   at the widget's rim are stored too. Widgets whose stored regions overlap
   are merged into one group; groups whose bounding rectangles overlap are
   merged again, until the rectangles are disjoint. One group = one block.
2. **Heights.** Inside a group, widgets combine by their ``overlap`` rule
   (``max`` by default; ``min``, ``add``, ``over`` = later widget wins); a
   sample covered by no widget is flat (height 0). Heights are then clamped
   to what the device can render (``normal_force_range`` through
   ``N = n_base + n_gain h``), with a warning per widget stating the excess.
3. **Channels.** Slopes are computed on the group rectangle grown by one more
   reach (so they equal the slopes of the whole canvas at every stored
   sample), walls are detected and limited as for any height field, and
   :func:`shapedisplay.author.forces.force_channels` gives the channels the device
   and mapping need. Data layers add ``friction_scale``/``burst_gain``
   (background 1) when the device uses them.
4. **Quantization** is chosen per channel from perceptual resolution over the
   values of every block (:func:`shapedisplay.author.compile.quantization_for`); the
   background is snapped to a code so that flat ground reads the same inside
   and outside blocks. Blocks whose coded contents are identical (identical
   widgets, since boxes are snapped to the grid) are stored once.
5. **Toggles**: the group holding a toggle is compiled once per state. The
   block shows the initial ``state``; the other state is stored as an extra
   patch, and ``table.meta["scene"]["toggles"][id]`` records
   ``{"block": i, "states": {"off": p, "on": q}, "state": ...}``. The runtime
   selects a state by pointing block ``i`` at the state's patch (what
   :func:`select_state` does; a device host can do the same with the header).

The result renders exactly like the dense table of the same canvas: every
canvas sample outside the blocks is flat ground, whose channel values are
the background values.
"""
from __future__ import annotations

import copy
import hashlib
import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from shapedisplay.errors import InputError
from shapedisplay.author.heightfield import HeightField
from shapedisplay.author.scene.fields import SceneError
from shapedisplay.author.scene.spec import Scene, load_scene
from shapedisplay.author.scene.widgets import WIDGET_TYPES

#: Background of the data channels (a multiplier: 1 = unchanged).
DATA_BACKGROUND = 1.0


# --------------------------------------------------------------- geometry
def _box(w) -> tuple[int, int, int, int]:
    """Clipped box of a widget: (r0, c0, r1, c1) inclusive canvas indices."""
    return w.box


def _grow(box, k: int, rows: int, cols: int):
    r0, c0, r1, c1 = box
    return (max(r0 - k, 0), max(c0 - k, 0), min(r1 + k, rows - 1), min(c1 + k, cols - 1))


def _overlap(a, b) -> bool:
    return not (a[2] < b[0] or b[2] < a[0] or a[3] < b[1] or b[3] < a[1])


def _union(a, b):
    return (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))


#: Most pairs of widgets whose boxes (grown by the gradient's reach) may overlap: n widgets stacked
#: on one another make n^2 / 2 pairs, each checked for its overlap rule and warned about.
MAX_OVERLAP_PAIRS = 200_000


def overlapping_pairs(boxes, where: str = "scene") -> list[tuple[int, int]]:
    """Index pairs ``(i, j)``, ``i < j``, of the boxes ``(r0, c0, r1, c1)`` (inclusive) that overlap, sorted.

    A sweep along the axis whose starts spread more (rows, or columns for a
    strip): each box is compared only with the boxes still open where it
    starts, so n widgets laid out on a screen cost about n x (widgets across
    one band), not n^2 / 2 comparisons. More than :data:`MAX_OVERLAP_PAIRS`
    pairs is a :class:`SceneError` (``where`` names the scene).
    """
    n = len(boxes)
    if n < 2:
        return []
    ax = 0 if len({b[0] for b in boxes}) >= len({b[1] for b in boxes}) else 1
    order = sorted(range(n), key=lambda i: boxes[i][ax])
    active: list = []
    pairs = []
    for i in order:
        bi = boxes[i]
        active = [j for j in active if boxes[j][ax + 2] >= bi[ax]]
        for j in active:
            if _overlap(bi, boxes[j]):
                pairs.append((j, i) if j < i else (i, j))
        if len(pairs) > MAX_OVERLAP_PAIRS:
            raise SceneError(f"{where}: more than {MAX_OVERLAP_PAIRS} pairs of widgets overlap or touch "
                             f"(MAX_OVERLAP_PAIRS, docs/limits.md); stack fewer widgets on one another")
        active.append(i)
    pairs.sort()
    return pairs


def _pairs_by_group(scene: Scene, grps: list[dict]) -> list[list]:
    """Per group, the pairs ``(wa, wb)`` of its widgets whose boxes overlap, by index (widgets whose
    boxes overlap always share a group)."""
    rank = {i: k for k, g in enumerate(grps) for i in g["members"]}
    out: list = [[] for _ in grps]
    ws = scene.widgets
    for i, j in overlapping_pairs([_box(w) for w in ws], f"scene '{scene.path}'"):
        out[rank[i]].append((ws[i], ws[j]))
    return out


def gradient_reach(options, spacing: float) -> int:
    """Samples beyond a widget's box where its slopes are nonzero (and beyond that, which heights they read)."""
    m = getattr(options, "gradient_method", "central")
    kw = dict(getattr(options, "gradient_kw", {}) or {})
    if m == "gaussian":
        from shapedisplay.units import parse_quantity
        s = kw.get("sigma")
        sigma = 1.5 * spacing if s is None else (parse_quantity(s, "m", "sigma") if isinstance(s, str) else float(s))
        return int(math.ceil(4.0 * sigma / spacing)) + 1
    if m == "savgol":
        win = kw.get("window", 7)
        if isinstance(win, str):
            from shapedisplay.units import parse_quantity
            win = int(round(parse_quantity(win, "m", "window") / spacing))
        return int(win) // 2 + 1
    return 1


def groups(scene: Scene, reach: int = 1) -> list[dict]:
    """Partition the widgets into blocks.

    Returns
    -------
    list of dict
        ``{"members": [widget indices], "rect": (r0, c0, r1, c1)}`` with
        disjoint rectangles, ordered by first member.
    """
    rows, cols = scene.canvas.rows, scene.canvas.cols
    n = len(scene.widgets)
    parent = list(range(n))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    stored = [_grow(_box(w), reach, rows, cols) for w in scene.widgets]
    for i, j in overlapping_pairs(stored, f"scene '{scene.path}'"):
        parent[find(j)] = find(i)
    while True:
        rects: dict = {}
        for i in range(n):
            r = find(i)
            rects[r] = stored[i] if r not in rects else _union(rects[r], stored[i])
        keys = sorted(rects)
        merged = False
        for a, b in overlapping_pairs([rects[k] for k in keys], f"scene '{scene.path}'"):
            parent[find(keys[b])] = find(keys[a])
            merged = True
        if not merged:
            break
    out: dict = {}
    for i in range(n):
        out.setdefault(find(i), []).append(i)
    res = [{"members": sorted(m), "rect": rects[r]} for r, m in out.items()]
    return sorted(res, key=lambda g: g["members"][0])


def check_groups(scene: Scene, grps: list[dict]) -> None:
    """Overlap rules: widgets that truly overlap must share a rule; one toggle per block."""
    ws = scene.widgets
    for g, pairs in zip(grps, _pairs_by_group(scene, grps)):
        mem = [ws[i] for i in g["members"]]
        for wa, wb in pairs:
            da, db = WIDGET_TYPES[wa.type].data_layer, WIDGET_TYPES[wb.type].data_layer
            if da != db or (da and wa.params["channel"] != wb.params["channel"]):
                continue  # height and data (or two data channels) never combine
            if wa.overlap != wb.overlap:
                raise SceneError(
                    f"scene '{scene.path}': {wa.where} and {wb.where} overlap with conflicting rules "
                    f"(`widget[{wa.index}].overlap` = '{wa.overlap}', `widget[{wb.index}].overlap` = "
                    f"'{wb.overlap}'); give both the same `overlap` (max, min, add or over)")
        toggles = [w for w in mem if WIDGET_TYPES[w.type].states]
        if len(toggles) > 1:
            a, b = toggles[0], toggles[1]
            raise SceneError(
                f"scene '{scene.path}': {a.where} and {b.where} are toggles sharing one block (they overlap or lie "
                f"within {2 * 1 + 1} samples of each other); each toggle needs a block of its own so its state can "
                f"be switched: move them apart")


# --------------------------------------------------------------- compositing
def height_limits(scene: Scene) -> tuple[float, float]:
    """Heights (m) the device can render: N = n_base + n_gain h within normal_force_range."""
    m = scene.mapping
    lo, hi = scene.device.normal_force_range
    if m.n_gain <= 0:
        return -math.inf, math.inf
    return m.height_of_force(lo), m.height_of_force(hi)


def _widget_local(w, r0: int, c0: int, r1: int, c1: int, is_1d: bool):
    """Intersection of widget w's box with the region and its local coordinates."""
    br0, bc0, br1, bc1 = _box(w)
    a0, b0, a1, b1 = max(r0, br0), max(c0, bc0), min(r1, br1), min(c1, bc1)
    if a0 > a1 or b0 > b1:
        return None
    s = w.spacing
    u = ((np.arange(b0, b1 + 1) - w.col0) * s)[None, :]
    v = (np.zeros((1, 1)) if is_1d else ((np.arange(a0, a1 + 1) - w.row0) * s)[:, None])
    W, H = w.size
    return (a0 - r0, b0 - c0, a1 - a0 + 1, b1 - b0 + 1), u, v, W, H


def _combine(acc, cov, vals, rule: str, sl):
    a, c = acc[sl], cov[sl]
    if rule == "max":
        a[...] = np.where(c, np.maximum(a, vals), vals)
    elif rule == "min":
        a[...] = np.where(c, np.minimum(a, vals), vals)
    elif rule == "add":
        a[...] = np.where(c, a + vals, vals)
    else:  # over
        a[...] = vals
    c[...] = True


def composite(scene: Scene, region, states: dict | None = None, members=None):
    """Heights and data layers of the scene on a canvas region.

    Parameters
    ----------
    region : (r0, c0, r1, c1)
        Inclusive canvas sample indices.
    states : dict
        Toggle id -> state (default: each toggle's ``state``).
    members : iterable of int, optional
        Widget indices to draw (default: every widget).

    Returns
    -------
    heights : ndarray (rows, cols) float64, metres, unclamped
    data : dict channel -> ndarray (rows, cols) float64 (only channels some layer drives)
    """
    r0, c0, r1, c1 = region
    is_1d = scene.canvas.is_1d
    shape = (r1 - r0 + 1, c1 - c0 + 1)
    h = np.zeros(shape)
    cov = np.zeros(shape, dtype=bool)
    data, dcov = {}, {}
    states = states or {}
    idx = range(len(scene.widgets)) if members is None else sorted(members)
    for i in idx:
        w = scene.widgets[i]
        if w.params.get("part") and states.get(w.id) not in ("part", "rest"):
            continue                        # a moving part (reactions.py): a patch of its own, not the blocks'
        loc = _widget_local(w, r0, c0, r1, c1, is_1d)
        if loc is None:
            continue
        (lr, lc, nr, nc), u, v, W, H = loc
        sl = (slice(lr, lr + nr), slice(lc, lc + nc))
        wt = WIDGET_TYPES[w.type]
        if wt.data_layer:
            ch, vals = wt.data(w.params, u, v, W, H, is_1d)
            if ch not in data:
                data[ch] = np.full(shape, DATA_BACKGROUND)
                dcov[ch] = np.zeros(shape, dtype=bool)
            _combine(data[ch], dcov[ch], np.broadcast_to(vals, (nr, nc)), w.overlap, sl)
        else:
            vals = wt.heights(w.params, u, v, W, H, is_1d, states.get(w.id))
            _combine(h, cov, np.broadcast_to(vals, (nr, nc)), w.overlap, sl)
    return h, data


def data_channels(scene: Scene) -> list[str]:
    return sorted({w.params["channel"] for w in scene.widgets if WIDGET_TYPES[w.type].data_layer})


def scene_heightfield(scene, states: dict | None = None) -> HeightField:
    """The whole canvas as one height field (metres), clamped to the device's range.

    ``scene`` is a :class:`Scene` or a path. Used by the 3D preview and as the
    dense reference the compiled table must reproduce.
    """
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    c = scene.canvas
    rest = {w.id: "rest" for w in scene.widgets if w.params.get("part") or w.params.get("thumb_part")}
    h, _ = composite(scene, (0, 0, c.rows - 1, c.cols - 1), {**rest, **(states or {})})
    lo, hi = height_limits(scene)
    np.clip(h, lo, hi, out=h)
    return HeightField(h, c.spacing, c.spacing, 0.0, 0.0, f"scene {scene.name}",
                       {"scene": scene.path, "widgets": [w.id for w in scene.widgets]})


# --------------------------------------------------------------- checks
def _fmt(v: float, unit: str) -> str:
    return f"{v:.4g} {unit}"


def height_warnings(scene: Scene) -> list[str]:
    """Per-widget: heights beyond the device range (they will be clamped), stating by how much."""
    lo, hi = height_limits(scene)
    m = scene.mapping
    flo, fhi = scene.device.normal_force_range
    out = []
    for w in scene.widgets:
        wt = WIDGET_TYPES[w.type]
        if wt.data_layer:
            continue
        states = wt.states or (None,)
        hmin, hmax = math.inf, -math.inf
        for st in states:
            h, _ = composite(scene, _box(w), {w.id: st} if st else None, members=[w.index])
            hmin, hmax = min(hmin, float(h.min())), max(hmax, float(h.max()))
        if hmax > hi + 1e-12:
            n = m.n_base + m.n_gain * hmax
            out.append(f"{w.where}: height {hmax * 1e3:.4g} mm asks for {_fmt(n, 'N')}, above the device "
                       f"'{scene.device.name}' maximum {_fmt(fhi, 'N')} by {_fmt(n - fhi, 'N')} "
                       f"({(hmax - hi) * 1e3:.4g} mm); clamped to {hi * 1e3:.4g} mm")
        if hmin < lo - 1e-12:
            n = m.n_base + m.n_gain * hmin
            out.append(f"{w.where}: height {hmin * 1e3:.4g} mm asks for {_fmt(n, 'N')}, below the device "
                       f"'{scene.device.name}' minimum {_fmt(flo, 'N')} by {_fmt(flo - n, 'N')} "
                       f"({(lo - hmin) * 1e3:.4g} mm); clamped to {lo * 1e3:.4g} mm (raise mapping.n_base "
                       f"to render dents)")
    return out


def combined_height_warnings(scene: Scene, grps: list[dict], warned: list[str]) -> list[str]:
    """Groups whose combined heights (overlap rule ``add``) go beyond the device when no single
    widget of the group does (those are in ``warned`` already), stating by how much."""
    lo, hi = height_limits(scene)
    gain = scene.mapping.n_gain
    out = []
    for g in grps:
        ids = [scene.widgets[i].id for i in g["members"]]
        if len(ids) < 2 or any(f"'{i}'" in w for i in ids for w in warned):
            continue
        h, _ = composite(scene, g["rect"], members=g["members"])
        for v, lim, side in ((float(h.max()), hi, "above"), (float(h.min()), lo, "below")):
            if (v - lim) * (1 if side == "above" else -1) > 1e-12:
                out.append(f"widgets {', '.join(repr(i) for i in ids)}: combined height "
                           f"{v * 1e3:.4g} mm is {side} what the device renders by "
                           f"{abs(v - lim) * 1e3:.4g} mm ({abs(v - lim) * gain:.4g} N); "
                           f"clamped to {lim * 1e3:.4g} mm")
    return out


def overlap_warnings(scene: Scene, grps: list[dict]) -> list[str]:
    """Widgets whose shapes (not just boxes) overlap, when the file did not choose how they combine.

    Two height widgets overlap where both have a nonzero height on the same
    sample; they then combine by their ``overlap`` rule (``max`` unless
    written). The warning is left out when both widgets set ``overlap``.
    """
    out = []
    is_1d = scene.canvas.is_1d
    s = scene.canvas.spacing
    for pairs in _pairs_by_group(scene, grps):
        for wa, wb in pairs:
            if WIDGET_TYPES[wa.type].data_layer or WIDGET_TYPES[wb.type].data_layer:
                continue
            if wa.overlap_given and wb.overlap_given:
                continue
            ba, bb = _box(wa), _box(wb)
            region = (max(ba[0], bb[0]), max(ba[1], bb[1]), min(ba[2], bb[2]), min(ba[3], bb[3]))
            both = None
            for w in (wa, wb):
                (lr, lc, nr, nc), u, v, W, H = _widget_local(w, *region, is_1d)
                hv = np.broadcast_to(WIDGET_TYPES[w.type].heights(w.params, u, v, W, H, is_1d), (nr, nc))
                nz = np.abs(hv) > 1e-12
                both = nz if both is None else both & nz
            if both is None or not both.any():
                continue
            rr, cc = np.nonzero(both)
            x0, x1 = (region[1] + cc.min()) * s, (region[1] + cc.max()) * s
            y0, y1 = (region[0] + rr.min()) * s, (region[0] + rr.max()) * s
            where = f"x {x0 * 1e3:.4g}..{x1 * 1e3:.4g} mm" + ("" if is_1d else f", y {y0 * 1e3:.4g}..{y1 * 1e3:.4g} mm")
            out.append(f"{wa.where} and {wb.where} overlap on {int(both.sum())} samples ({where}); their heights "
                       f"combine by `overlap` = '{wa.overlap}' ({_RULE_WORDS[wa.overlap]}); set `overlap` on both "
                       f"(max, min, add or over) to choose the rule and silence this warning")
    return out


_RULE_WORDS = {"max": "the higher wins", "min": "the lower wins", "add": "heights add up", "over": "the later wins"}


def scene_warnings(scene: Scene, grps: list[dict]) -> list[str]:
    """Every warning of a scene: placement (clipping, snapping, detents, ramps), overlapping widgets
    without a chosen rule, and heights the device cannot render, alone or combined."""
    warned = list(scene.warnings) + overlap_warnings(scene, grps) + height_warnings(scene)
    return warned + combined_height_warnings(scene, grps, warned)


#: Most widget ids a report note lists (a block of n widgets would otherwise list n^2 ids).
REPORT_IDS = 12


def _some_ids(members: list, but) -> str:
    """The ids of ``members`` other than ``but``, quoted: the first REPORT_IDS, then how many more."""
    shown = [m for m in members[:REPORT_IDS + 1] if m is not but][:REPORT_IDS]
    more = len(members) - 1 - len(shown)
    return ", ".join(f"'{m.id}'" for m in shown) + (f" and {more} more" if more > 0 else "")


def check_scene(path, device=None, confine: bool = False) -> list[str]:
    """Validate a scene without compiling it.

    Raises :class:`SceneError` (an ``InputError``) on the first error; returns
    the warnings (clipping, snapping, detents too dense to feel apart, heights
    the device cannot render alone or combined, ramps shortened), the same
    as the compile report lists.
    """
    scene = path if isinstance(path, Scene) else load_scene(path, device=device, confine=confine)
    grps = groups(scene, 1)
    check_groups(scene, grps)
    return scene_warnings(scene, grps)


# --------------------------------------------------------------- compiling
def _scene_sha256(scene: Scene) -> str:
    d = hashlib.sha256()
    p = Path(scene.path)
    if p.is_file():
        d.update(p.read_bytes())
    for w in scene.widgets:
        f = w.params.get("file")
        if f and Path(f).is_file():
            d.update(Path(f).read_bytes())
    return d.hexdigest()


def scene_channels(scene: Scene, device, mapping) -> tuple[list, dict]:
    """Channels a scene's table keeps on ``device`` with ``mapping``.

    Returns ``(kept, left_out)``: channel names, and channel -> why it is not stored.
    """
    from shapedisplay.author.forces import FRICTION_OUTPUTS, needed_channels
    from shapedisplay.table.model import CHANNELS
    kept, left_out = needed_channels(device, mapping, scene.canvas.is_1d)
    driven = data_channels(scene)
    outs = set(device.outputs)
    for ch in ("friction_scale", "burst_gain"):
        if ch not in driven:
            left_out[ch] = "no data layer of the scene drives it"
            continue
        if ch == "friction_scale" and not outs & set(FRICTION_OUTPUTS):
            left_out[ch] = f"device '{device.name}' outputs {sorted(outs)} do not render friction"
        elif ch == "burst_gain" and "burst" not in outs:
            left_out[ch] = f"device '{device.name}' has no 'burst' output (outputs: {sorted(outs)})"
        else:
            kept.append(ch)
            left_out.pop(ch, None)
    return [n for n in CHANNELS if n in kept], left_out


def _merge_clamp(acc: dict, notes: dict, samples: int) -> None:
    """Add one block's clamping notes (forces._clamp format) to the scene totals."""
    for name, c in notes.items():
        a = acc.setdefault(name, dict(c, below=0, above=0, fraction=0.0, max_excess=0.0, samples=0))
        a["below"] += c["below"]
        a["above"] += c["above"]
        a["samples"] += samples
        a["fraction"] = (a["below"] + a["above"]) / max(a["samples"], 1)
        a["max_excess"] = max(a["max_excess"], c["max_excess"])
        a["raw_min"], a["raw_max"] = min(a["raw_min"], c["raw_min"]), max(a["raw_max"], c["raw_max"])


def _group_channels(scene, rect, reach, states, device, mapping, options, kept, lims, clamped=None, members=None):
    """Channels of one block (of ``members`` alone when given): dict name -> (rows, cols) float64; plus wall and
    clamp notes."""
    from shapedisplay.author.gradients import detect_walls, gradient, limit_walls
    from shapedisplay.author.forces import force_channels
    c = scene.canvas
    calc = _grow(rect, reach, c.rows, c.cols)
    h, data = composite(scene, calc, states, members)
    np.clip(h, lims[0], lims[1], out=h)
    s = c.spacing
    hf_calc = HeightField(h, s, s, calc[1] * s, calc[0] * s, f"scene {scene.name}")
    gx, gy = gradient(hf_calc, options.gradient_method, **options.gradient_kw)
    walls = detect_walls(hf_calc, gx, gy, options.max_slope)
    if walls.count and options.limit_walls:
        limit_walls(gx, gy, options.max_slope, out=(gx, gy))
    r0, c0 = rect[0] - calc[0], rect[1] - calc[1]
    sl = (slice(r0, r0 + rect[2] - rect[0] + 1), slice(c0, c0 + rect[3] - rect[1] + 1))
    hf = HeightField(h[sl], s, s, rect[1] * s, rect[0] * s, f"scene {scene.name}")
    chans = force_channels(hf, device, mapping, grad=(gx[sl], gy[sl]))
    if clamped is not None:
        _merge_clamp(clamped, chans.clamped, hf.rows * hf.cols)
    out = {}
    for name in kept:
        if name in chans:
            out[name] = np.asarray(chans[name], dtype=np.float64)
        elif name in data:
            out[name] = data[name][sl].copy()
        elif name in ("friction_scale", "burst_gain"):
            out[name] = np.full(hf.shape, DATA_BACKGROUND)
        else:
            raise InputError(f"scene '{scene.path}': channel '{name}' was not produced by the force mapping")
    wall_count = int(walls.mask[sl].sum()) if walls.count else 0
    regions = _wall_regions(scene, walls.mask[sl], rect) if wall_count else (0, [])
    return out, (wall_count, *regions), float(walls.steepest)


def _wall_regions(scene, mask: np.ndarray, rect) -> tuple[int, list]:
    """The number of wall regions of one block and the largest ones: samples, box in mm (sample centres)
    and the widgets whose box the region touches, largest region first."""
    from shapedisplay.author.gradients import WallReport, wall_regions
    s = scene.canvas.spacing
    n_regions, _, spans = wall_regions(mask, WallReport.MAX_BOXES)
    out = []
    for r0, r1, c0, c1 in spans:
        box = [(rect[1] + c0) * s, (rect[1] + c1) * s, (rect[0] + r0) * s, (rect[0] + r1) * s]
        n = int(mask[r0:r1 + 1, c0:c1 + 1].sum())           # the region's samples (boxes of one block rarely hold two)
        ids = [w.id for w in scene.widgets
               if w.bbox[0] - s <= box[1] and box[0] <= w.bbox[2] + s and w.bbox[1] - s <= box[3]
               and box[2] <= w.bbox[3] + s]
        out.append({"box_mm": [round(v * 1e3, 6) for v in box], "samples": n, "widgets": ids})
    return n_regions, out


def _background(scene, device, mapping, kept) -> dict:
    from shapedisplay.author.forces import force_channels
    s = scene.canvas.spacing
    flat = HeightField(np.zeros((1, 2) if scene.canvas.is_1d else (2, 2)), s, s)
    ch = force_channels(flat, device, mapping, grad=(np.zeros(flat.shape), np.zeros(flat.shape)))
    return {n: (float(ch[n][0, 0]) if n in ch else DATA_BACKGROUND) for n in kept}


def _append_patch(table, chans: dict) -> int:
    """Store an extra patch (a toggle state) without a block; identical patches are shared."""
    names = table.channels
    shape = np.atleast_2d(chans[names[0]]).shape
    coded = {n: table.quant[n].encode(np.atleast_2d(chans[n])).ravel() for n in names}
    off = table.patch_offsets()
    for p, sh in enumerate(table.patch_shapes):
        if tuple(sh) == tuple(shape) and all(
                np.array_equal(table.codes[n][off[p]:off[p + 1]], coded[n]) for n in names):
            return p
    table.patch_shapes.append(tuple(int(x) for x in shape))
    for n in names:
        table.codes[n] = np.concatenate([table.codes[n], coded[n]])
    table._dense_cache.clear()
    table._check_layout()
    return len(table.patch_shapes) - 1


def scene_force_channels(scene: Scene, options=None) -> dict:
    """Every channel the compiled table of ``scene`` stores, computed over the whole canvas.

    The same computation as :func:`compile_scene` (heights clamped to what
    the device renders, the gradient method and wall limit of ``options``,
    the device's force mapping, the data layers the device renders), without
    grouping, pruning or quantization: what a preview of the scene shows.

    Returns
    -------
    dict name -> ndarray of shape (rows, cols), float64, SI
    """
    from shapedisplay.author.compile import CompileOptions
    options = CompileOptions() if options is None else options
    mapping = scene.mapping
    kept, _ = scene_channels(scene, scene.device, mapping)
    c = scene.canvas
    chans, _, _ = _group_channels(scene, (0, 0, c.rows - 1, c.cols - 1), gradient_reach(options, c.spacing), None,
                                  scene.device, mapping, options, kept, height_limits(scene))
    return chans


def compile_scene(path, device=None, options=None, confine: bool = False):
    """Compile a scene file into a friction-envelope table.

    Parameters
    ----------
    path : str, Path or Scene
        The scene TOML (or an already loaded :class:`Scene`).
    device : DeviceProfile, str, Path or None
        Overrides the scene's device.
    options : compile.CompileOptions, optional
        Quantization, gradient method, wall limit, channels to keep.
    confine : bool
        Read only files inside the scene's folder (see :func:`load_scene`); the studio sets it.

    Returns
    -------
    compile.CompileResult
        ``table`` on the canvas grid (a 1-D table for a 1-D canvas) with one
        block per widget group, and ``report`` (also in ``table.meta["report"]``)
        listing each widget with its block, bytes and notes, the channels kept
        and left out, quantization, walls, clamping, the stored and dense sizes
        and the warnings.
    """
    from shapedisplay.author.compile import CompileOptions, CompileResult, perceptual_bound, quantization_for, table_meta
    from shapedisplay.table.model import CHANNELS, FrictionTable

    options = CompileOptions() if options is None else options
    if not isinstance(options, CompileOptions):
        raise InputError(f"`options` must be CompileOptions (got {type(options).__name__})")
    if isinstance(path, Scene):
        scene = path if device is None else load_scene(path.path, device=device, confine=confine)
    else:
        scene = load_scene(path, device=device, confine=confine)
    dev = scene.device
    mapping = scene.mapping
    canvas = scene.canvas
    reach = gradient_reach(options, canvas.spacing)
    grps = groups(scene, reach)
    check_groups(scene, grps)
    warnings = scene_warnings(scene, grps)
    kept, left_out = scene_channels(scene, dev, mapping)
    for k in options.keep:
        if k not in kept:
            if k in ("grad_x", "grad_y") or (k == "normal_force" and mapping.height):
                kept.append(k)
                left_out.pop(k, None)
            else:
                raise InputError(f"cannot keep channel '{k}' for scene '{scene.path}': {left_out.get(k, 'not produced')}")
    kept = [n for n in CHANNELS if n in kept]
    if not kept:
        raise InputError(f"scene '{scene.path}': nothing to store: device '{dev.name}' (outputs "
                         f"{list(dev.outputs)}) uses none of the channels the scene produces; left out: "
                         + "; ".join(f"{k}: {v}" for k, v in left_out.items()))
    lims = height_limits(scene)

    # -- every block (and every toggle state), as float channels
    blocks, walls_total, steepest, n_wall_regions, wall_regions_, clamped = [], 0, 0.0, 0, [], {}
    for g in grps:
        toggle = next((scene.widgets[i] for i in g["members"] if WIDGET_TYPES[scene.widgets[i].type].states), None)
        variants = {}
        if toggle is not None:
            for st in WIDGET_TYPES[toggle.type].states:
                variants[st], wc, sp = _group_channels(scene, g["rect"], reach, {toggle.id: st}, dev, mapping,
                                                       options, kept, lims,
                                                       clamped if st == toggle.params["state"] else None)
                if st == toggle.params["state"]:
                    walls_total += wc[0]
                    n_wall_regions += wc[1]
                    wall_regions_ += wc[2]
                steepest = max(steepest, sp)
            main = variants[toggle.params["state"]]
        else:
            main, wc, sp = _group_channels(scene, g["rect"], reach, None, dev, mapping, options, kept, lims,
                                           clamped)
            walls_total += wc[0]
            n_wall_regions += wc[1]
            wall_regions_ += wc[2]
            steepest = max(steepest, sp)
        blocks.append({"group": g, "main": main, "toggle": toggle, "variants": variants})

    # -- moving parts (docs/reactive.md): each compiled alone, stored as a patch the engine adds where it moved
    from shapedisplay.author.scene.reactions import part_rect, reaction_entries
    moving = {}
    for k, w in enumerate(scene.widgets):
        if w.params.get("part") or w.params.get("thumb_part"):
            rect = part_rect(w, reach, canvas.rows, canvas.cols)
            moving[w.id] = (rect, _group_channels(scene, rect, reach, {w.id: "thumb" if w.params.get("thumb_part")
                                                                       else "part"}, dev, mapping, options, kept,
                                                  lims, None, [k])[0])

    # -- quantization over every stored value and the background
    background = _background(scene, dev, mapping, kept)
    quant, qinfo = {}, {}
    for name in kept:
        parts = [b["main"][name].ravel() for b in blocks]
        parts += [v[name].ravel() for b in blocks for v in b["variants"].values()]
        parts += [ch[name].ravel() for _, ch in moving.values()]
        parts.append(np.array([background[name]]))
        values = np.concatenate(parts)
        n_min = None
        if "normal_force" in kept:
            nf = np.concatenate([b["main"]["normal_force"].ravel() for b in blocks] + [np.array([background["normal_force"]])])
            n_min = float(np.min(np.abs(nf[nf != 0]))) if np.any(nf != 0) else None
        q = quantization_for(name, values, dev, options, mapping, n_min)
        bound, rule = perceptual_bound(name, values, dev, options, mapping, n_min)
        quant[name] = q
        background[name] = float(q.decode(q.encode(np.array([background[name]])))[0])
        qinfo[name] = {"dtype": q.dtype, "scale": q.scale, "offset": q.offset, "max_error": float(q.max_error),
                       "bound": None if math.isinf(bound) else bound, "rule": rule,
                       "meets_bound": bool(q.max_error <= bound)}

    placed = [((b["group"]["rect"][0], b["group"]["rect"][1]), b["main"]) for b in blocks]
    table = FrictionTable.from_patches(canvas.grid, placed, quant, background, {})
    toggles = {}
    for bi, b in enumerate(blocks):
        if b["toggle"] is None:
            continue
        t = b["toggle"]
        st_patch = {}
        for st, chans in b["variants"].items():
            st_patch[st] = table.blocks[bi][2] if st == t.params["state"] else _append_patch(table, chans)
        toggles[t.id] = {"block": bi, "states": st_patch, "state": t.params["state"]}
    part_patches = {wid: (rect[0], rect[1], _append_patch(table, ch)) for wid, (rect, ch) in moving.items()}
    reactions = reaction_entries(scene, table, part_patches)

    # -- report
    bps = sum(np.dtype(quant[n].dtype).itemsize for n in kept)
    first_owner: dict = {}
    widgets_rep = []
    for bi, b in enumerate(blocks):
        r0, c0, r1, c1 = b["group"]["rect"]
        patch = table.blocks[bi][2]
        nbytes = (r1 - r0 + 1) * (c1 - c0 + 1) * bps
        members = [scene.widgets[i] for i in b["group"]["members"]]
        shared = first_owner.get(patch)
        if shared is None:
            first_owner[patch] = members[0].id
        for k, w in enumerate(members):
            note, wbytes = [], 0
            if shared is not None:
                note.append(f"identical to '{shared}': stored once")
            elif k == 0:
                wbytes = nbytes
            if len(members) > 1:
                note.append(("block shared with " if k == 0 else f"merged into the block of '{members[0].id}' with ")
                            + _some_ids(members, w))
            asked = scene.perception.get("contrast", {}).get(w.id)
            if asked:                        # what `contrast = "3 jnd"` chose (spec._contrast_force)
                note.append(f"contrast {asked['asked']} -> force {asked['force_n']:.4g} N "
                            f"({asked['cue'].replace('_', ' ')})")
            if b["toggle"] is w:
                extra = [p for st, p in toggles[w.id]["states"].items() if st != w.params["state"]]
                for p in sorted(set(extra)):
                    if p not in first_owner:   # a state identical to a stored patch costs nothing
                        first_owner[p] = w.id
                        wbytes += table.patch_shapes[p][0] * table.patch_shapes[p][1] * bps
                note.append("both states stored (" + ", ".join(f"{st}: patch {p}" for st, p in
                                                               toggles[w.id]["states"].items()) + ")")
            x0, y0, x1, y1 = w.bbox
            widgets_rep.append({
                "id": w.id, "type": w.type, "index": w.index, "bbox_mm": [x0 * 1e3, y0 * 1e3, x1 * 1e3, y1 * 1e3],
                "block": bi, "patch": patch, "block_shape": [r1 - r0 + 1, c1 - c0 + 1], "bytes": int(wbytes),
                "overlap": w.overlap, "clipped": w.clipped, "notes": note,
                "params": WIDGET_TYPES[w.type].describe(w.params),
            })
    widgets_rep.sort(key=lambda d: d["index"])
    stored_samples = sum(s[0] * s[1] for s in table.patch_shapes)
    from shapedisplay.author.gradients import WallReport
    wall_regions_ = sorted(wall_regions_, key=lambda r: -r["samples"])[:WallReport.MAX_BOXES]
    covered = sum((b[0] * 0) + table.patch_shapes[b[2]][0] * table.patch_shapes[b[2]][1] for b in table.blocks)
    total = canvas.rows * canvas.cols
    left = dict(left_out)
    left["empty_regions"] = (f"{total - covered} of {total} canvas samples ({(total - covered) / total * 100:.1f} %) "
                             f"are flat ground outside every block: not stored (background values)")
    dup = len(table.blocks) - len({b[2] for b in table.blocks})
    if dup:
        left["duplicates"] = f"{dup} block(s) identical to another: stored once"
    dense_kept = total * len(kept) * 4
    report = {
        "source": f"scene {scene.name} ({scene.path})",
        "scene": scene.name,
        "grid": canvas.grid.to_json(),
        "is_1d": canvas.is_1d,
        "device": dev.name,
        "mapping": mapping.spec,
        "direction": scene.direction,
        "kept": kept,
        "left_out": left,
        "quantization": qinfo,
        "walls": {"count": walls_total, "fraction": walls_total / max(total, 1),
                  "max_slope": None if math.isinf(options.max_slope) else options.max_slope,
                  "steepest": steepest, "regions": n_wall_regions,
                  "boxes_mm": [r["box_mm"] for r in wall_regions_],
                  "region_widgets": [r["widgets"] for r in wall_regions_],
                  "limited": (f"slope magnitude clipped to {options.max_slope:g}, direction kept"
                              if walls_total and options.limit_walls else
                              ("no walls" if not walls_total else "not limited (limit_walls=False)"))},
        "clamped": clamped,
        "layout": (f"{len(table.blocks)} block(s), one per widget or group of touching widgets, holding "
                   f"{len(table.patch_shapes)} stored patch(es) over {covered} of {total} canvas samples; "
                   f"flat ground elsewhere"),
        "widgets": widgets_rep,
        "toggles": toggles,
        "blocks": len(table.blocks),
        "patches": len(table.patch_shapes),
        "stored_samples": int(stored_samples),
        "stored_bytes": table.stored_bytes,
        "dense_bytes": table.dense_bytes,
        "dense_kept_bytes": int(dense_kept),
        "bytes_saved": table.dense_bytes - table.stored_bytes,
        "ratio": table.stored_bytes / table.dense_bytes,
        "dense_rule": "dense = rows*cols * every format channel * 4 bytes (float32)",
        "warnings": warnings,
        "contrast": dict(scene.perception.get("contrast", {})),
    }
    meta = table_meta(dev, mapping, options, report["source"], _scene_sha256(scene), report)
    meta["scene"] = {
        "name": scene.name, "file": str(scene.path), "direction": report["direction"],
        "canvas": {"width_m": canvas.width, "height_m": canvas.height, "spacing_m": canvas.spacing,
                   "is_1d": canvas.is_1d},
        "widgets": [{"id": w.id, "type": w.type, "bbox_m": list(w.bbox), "label": w.label} for w in scene.widgets],
        "toggles": toggles,
    }
    if reactions:                           # reactive widgets the engine plays (render/reactions.py)
        meta["scene"]["reactions"] = reactions
    table.meta = meta
    return CompileResult(table, report)


def select_state(table, toggle_id: str, state: str):
    """A copy of ``table`` with toggle ``toggle_id`` switched to ``state``.

    Only the block's patch index changes (both states are stored); a device
    host does the same from the header: ``blocks[i][2] = states[state]``.
    """
    from shapedisplay.errors import unknown_key
    toggles = table.meta.get("scene", {}).get("toggles", {})
    if toggle_id not in toggles:
        raise unknown_key("toggle", toggle_id, toggles or ["(the table has no toggles)"])
    t = toggles[toggle_id]
    if state not in t["states"]:
        raise unknown_key(f"state of toggle '{toggle_id}'", state, t["states"])
    bi = int(t["block"])
    blocks = list(table.blocks)
    r0, c0, _ = blocks[bi]
    blocks[bi] = (r0, c0, int(t["states"][state]))
    meta = copy.deepcopy(table.meta)
    meta["scene"]["toggles"][toggle_id]["state"] = state
    out = replace(table, blocks=blocks, meta=meta, codes=dict(table.codes), _dense_cache={})
    out._check_layout()
    return out


def format_widget_report(report: dict) -> str:
    """Lines listing each widget of a scene compile report with its block, bytes and notes."""
    lines = ["widgets:"]
    for w in report.get("widgets", []):
        notes = "; ".join(w["notes"])
        r, c = w["block_shape"]
        lines.append(f"  {w['id']:<14} {w['type']:<7} block {w['block']:>2} ({c}x{r}) {w['bytes']:>7} bytes"
                     + (f"  {notes}" if notes else ""))
    for msg in report.get("warnings", []):
        lines.append(f"warning: {msg}")
    return "\n".join(lines)
