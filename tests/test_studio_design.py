"""The studio as a design tool, in a real headless Chromium: the scene file on disk is the result.

One studio and one page serve the module; every test starts from the bundled
phone scene (its bytes written back and seen by the page) and checks the
file: a drag moves ``position`` by the dragged millimetres on the grid and
changes nothing else; a handle changes ``size``; the inspector writes one key;
the palette adds, duplicates and deletes; undo restores the exact bytes; a text
edit followed by undo never leaves invalid TOML; an external write during an
unsaved edit is a conflict and stays on disk until the designer chooses; the
A/B switch alternates the table the worklet plays.
"""
from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

import pytest

from studio_helpers import require_chromium

pytest.importorskip("tomlkit")
require_chromium()                                        # skips the module without them

if sys.version_info >= (3, 11):
    import tomllib
else:                                                     # pragma: no cover
    import tomli as tomllib

from shapedisplay.studio.edits import version_of  # noqa: E402

from studio_helpers import PHONE, studio_page  # noqa: E402

ORIGINAL = PHONE.read_bytes()
#: Where the docs' screenshot goes when this variable names a folder (scripts/docs_images.py).
SCREENSHOT_DIR = os.environ.get("SHAPEDISPLAY_SCREENSHOT_DIR")


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    folder = tmp_path_factory.mktemp("design")
    shutil.copy(PHONE, folder / "phone.toml")
    with studio_page(folder / "phone.toml", "window.studio && studio.shownGeneration !== null && studio.design "
                     "&& studio.design.schema", height=1000) as pg:
        pg.studio.folder, pg.studio.scene = folder, folder / "phone.toml"
        yield pg


@pytest.fixture
def fresh(page):
    """The page on the bundled phone scene: its bytes on disk, seen by the page, nothing selected."""
    scene = page.studio.scene
    page.evaluate("studio.dirty = false; document.getElementById('conflict').hidden = true")
    if scene.read_bytes() != ORIGINAL:
        scene.write_bytes(ORIGINAL)
    v = version_of(ORIGINAL)
    page.wait_for_function(f"studio.version === '{v}' && studio.textBase && studio.textBase.version === '{v}' "
                           f"&& studio.state.scene_version === '{v}'", timeout=20000)
    page.keyboard.press("Escape")
    page.evaluate("document.activeElement && document.activeElement.blur()")
    yield page
    assert not page.js_errors


def wait_version_change(page, before: str) -> str:
    page.wait_for_function(f"studio.version !== '{before}' && studio.state.scene_version === studio.version",
                           timeout=20000)
    return page.evaluate("studio.version")


def changed_lines(a: bytes, b: bytes) -> list:
    la, lb = a.decode().splitlines(), b.decode().splitlines()
    assert len(la) == len(lb), "lines were added or removed"
    return [(i + 1, x, y) for i, (x, y) in enumerate(zip(la, lb)) if x != y]


def widget(data: dict, wid: str) -> dict:
    return next(w for w in data["widget"] if w["id"] == wid)


def undo_to(page, expected: bytes):
    v = page.evaluate("studio.version")
    page.click("#undo")
    wait_version_change(page, v)
    assert page.studio.scene.read_bytes() == expected


def px_per_mm(page) -> float:
    return page.evaluate("document.getElementById('map').clientWidth / "
                         "(studio.state.grid.cols * studio.state.grid.dx)") / 1e3


# ------------------------------------------------------------------ canvas
def test_widget_elements_cover_their_boxes_and_a_drag_moves_position_only(fresh):
    page = fresh
    before = page.studio.scene.read_bytes()
    for w in page.evaluate("studio.state.widgets"):
        box = page.locator(f'[data-widget="{w["id"]}"]').bounding_box()
        x0, y0, x1, y1 = w["bbox_m"]
        (ax, ay), (bx, by) = page.evaluate(f"[studio.screenOf({x0}, {y1}), studio.screenOf({x1}, {y0})]")
        assert box["x"] == pytest.approx(ax, abs=0.6) and box["y"] == pytest.approx(ay, abs=0.6), w["id"]
        assert box["width"] == pytest.approx(bx - ax, abs=0.6) and box["height"] == pytest.approx(by - ay, abs=0.6)
    box = page.locator('[data-widget="app-1"]').bounding_box()
    cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    dx, dy = 37, 23                                       # pixels: right and down the screen
    page.mouse.move(cx, cy)
    page.mouse.down()
    page.mouse.move(cx + dx, cy + dy, steps=6)
    page.mouse.up()
    v = wait_version_change(page, version_of(before))
    after = page.studio.scene.read_bytes()
    s = px_per_mm(page)
    res = 0.5
    ex = 5 + round(dx / s / res) * res
    ey = 118 - round(dy / s / res) * res
    a, b = tomllib.loads(before.decode()), tomllib.loads(after.decode())
    assert widget(b, "app-1")["position"] == f"{ex:g},{ey:g} mm"
    widget(b, "app-1")["position"] = widget(a, "app-1")["position"]
    assert a == b                                         # nothing else changed ...
    assert [ln for ln, _, _ in changed_lines(before, after)] == [52]     # ... byte for byte
    assert page.evaluate("studio.design.selected") == "app-1"
    assert page.locator('[data-widget="app-1"] [data-handle]').count() == 8
    assert page.input_value("#inspector input[name=position]") == f"{ex:g},{ey:g} mm"
    assert v == page.evaluate("studio.state.scene_version")
    undo_to(page, before)


def test_a_drag_near_another_widget_snaps_to_its_edge_with_a_guide(fresh):
    page = fresh
    before = page.studio.scene.read_bytes()
    s = px_per_mm(page)
    box = page.locator('[data-widget="app-4"]').bounding_box()
    cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(cx, cy)
    page.mouse.down()
    page.mouse.move(cx + 25.6 * s, cy, steps=5)          # left edge 5 -> 30.6 mm: app-5's left edge is at 30
    assert page.locator("#widgets .guide").count() >= 1
    page.mouse.up()
    wait_version_change(page, version_of(before))
    assert widget(tomllib.loads(page.studio.scene.read_text()), "app-4")["position"] == "30,90 mm"
    undo_to(page, before)


def test_a_handle_resizes_and_arrow_keys_nudge(fresh):
    page = fresh
    before = page.studio.scene.read_bytes()
    page.locator('[data-widget="call"]').click()
    handle = page.locator('[data-widget="call"] [data-handle="e"]')
    hb = handle.bounding_box()
    hx, hy = hb["x"] + hb["width"] / 2, hb["y"] + hb["height"] / 2
    page.keyboard.down("Alt")                             # the grid only: no snapping to other widgets
    page.mouse.move(hx, hy)
    page.mouse.down()
    page.mouse.move(hx + 40, hy + 30, steps=5)            # an e handle moves the right edge only
    page.mouse.up()
    page.keyboard.up("Alt")
    wait_version_change(page, version_of(before))
    after = page.studio.scene.read_bytes()
    w = round(40 / px_per_mm(page) / 0.5) * 0.5
    assert widget(tomllib.loads(after.decode()), "call")["size"] == f"{36 + w:g}x16 mm"
    assert [t for _, t, _ in changed_lines(before, after)] == ['size = "36x16 mm"']
    # arrow keys: one grid step, Shift: ten
    v = page.evaluate("studio.version")
    page.keyboard.press("ArrowUp")
    v = wait_version_change(page, v)
    page.keyboard.press("Shift+ArrowLeft")
    wait_version_change(page, v)
    assert widget(tomllib.loads(page.studio.scene.read_text()), "call")["position"] == "0,28.5 mm"
    v = page.evaluate("studio.version")
    page.keyboard.press("Control+z")
    v = wait_version_change(page, v)
    page.keyboard.press("Control+z")
    v = wait_version_change(page, v)
    assert page.studio.scene.read_bytes() == after
    undo_to(page, before)


# ------------------------------------------------------------------ inspector and palette
def test_inspector_writes_one_key_validates_live_and_the_new_table_plays(fresh):
    page = fresh
    before = page.studio.scene.read_bytes()
    if page.evaluate("studio.node === null"):
        page.click("#feel")
        page.wait_for_function("studio.node !== null && studio.ctx.state === 'running'", timeout=20000)
    page.locator('[data-widget="call"]').click()
    field = page.locator("#inspector input[name=ramp]")
    assert field.input_value() == "5 mm"
    field.fill("-1")                                       # live check: the loader's message, nothing written
    page.wait_for_function("document.querySelector('#inspector input[name=ramp]').classList.contains('invalid')",
                           timeout=10000)
    msg = page.locator("#inspector input[name=ramp] ~ .msg").inner_text()
    assert "`widget[9].ramp` must be a length > 0 (got '-1 mm')" in msg
    assert page.studio.scene.read_bytes() == before
    field.fill("8")
    field.press("Enter")
    wait_version_change(page, version_of(before))
    after = page.studio.scene.read_bytes()
    assert changed_lines(before, after) == [(119, 'ramp = "5 mm"', 'ramp = "8 mm"')]
    gen = page.evaluate("studio.state.table_generation")
    page.wait_for_function(f"studio.playing && studio.playing.generation === {gen}", timeout=20000)
    assert page.evaluate("studio.playing.checksum") == page.evaluate("studio.state.checksum")
    # a strength key replaces the others: force -> height
    page.locator("#inspector input[name=height]").fill("1.5")
    page.locator("#inspector input[name=height]").press("Enter")
    wait_version_change(page, version_of(after))
    call = widget(tomllib.loads(page.studio.scene.read_text()), "call")
    assert call["height"] == "1.5 mm" and "force" not in call
    undo_to(page, after)
    undo_to(page, before)


def test_inspector_writes_the_reaction_keys(fresh):
    """press (a bare number gets N), movable (a true/false choice written as a TOML boolean)."""
    page = fresh
    before = page.studio.scene.read_bytes()
    page.locator('[data-widget="call"]').click()
    field = page.locator("#inspector input[name=press]")
    field.fill("3")
    field.press("Enter")
    wait_version_change(page, version_of(before))
    mid = page.studio.scene.read_bytes()
    assert widget(tomllib.loads(mid.decode()), "call")["press"] == "3 N"
    page.locator("#inspector select[name=movable]").select_option("true")
    wait_version_change(page, version_of(mid))
    assert widget(tomllib.loads(page.studio.scene.read_text()), "call")["movable"] is True
    assert page.locator("#inspector select[name=movable]").count() == 1
    page.locator('[data-widget="wifi"]').click()                     # a toggle flips: it has no movable
    assert page.locator("#inspector select[name=movable]").count() == 0
    assert page.locator("#inspector input[name=press]").count() == 1
    undo_to(page, mid)
    undo_to(page, before)


def test_palette_adds_duplicates_and_deletes_and_undo_restores_each(fresh):
    page = fresh
    original = page.studio.scene.read_bytes()
    page.click('#palette [data-add="button"]')
    wait_version_change(page, version_of(original))
    data = tomllib.loads(page.studio.scene.read_text())
    assert data["widget"][-1] == {"id": "button-1", "type": "button", "position": "30,70 mm", "size": "20x20 mm"}
    assert page.studio.scene.read_bytes().startswith(original.rstrip(b"\n"))
    assert page.evaluate("studio.design.selected") == "button-1"
    page.wait_for_selector('[data-widget="button-1"]')
    undo_to(page, original)
    page.locator('[data-widget="app-3"]').click()
    page.click("#duplicate")
    wait_version_change(page, version_of(original))
    ids = [w["id"] for w in tomllib.loads(page.studio.scene.read_text())["widget"]]
    assert ids[:4] == ["frame", "app-1", "app-2", "app-3"] and ids[4] == "app-7" and len(ids) == 12
    assert page.evaluate("studio.design.selected") == "app-7"
    undo_to(page, original)
    page.locator('[data-widget="home"]').click()
    page.click("#delete")
    wait_version_change(page, version_of(original))
    text = page.studio.scene.read_text()
    assert 'id = "home"' not in text and "# ---- home" not in text
    assert page.locator('[data-widget="home"]').count() == 0
    undo_to(page, original)
    # redo, then undo once more: the same bytes each way
    v = page.evaluate("studio.version")
    page.click("#redo")
    wait_version_change(page, v)
    assert 'id = "home"' not in page.studio.scene.read_text()
    undo_to(page, original)


# ------------------------------------------------------------------ text, undo, history
def test_a_text_edit_followed_by_undo_never_leaves_invalid_toml(fresh):
    page = fresh
    scene = page.studio.scene
    before = scene.read_bytes()
    text = before.decode()
    # unparsable text is not saved: the file stays, the line is marked
    page.fill("#text", text.replace('track = "groove"', 'trak = '))
    page.keyboard.press("Control+s")
    page.wait_for_function("document.getElementById('status').textContent.startsWith('not saved')", timeout=10000)
    assert scene.read_bytes() == before
    # a saved text edit (valid TOML, an unknown key: the compile shows the error) ...
    page.fill("#text", text.replace('track = "groove"', 'trak = "groove"'))
    page.keyboard.press("Control+s")
    wait_version_change(page, version_of(before))
    assert b'trak = "groove"' in scene.read_bytes()
    page.wait_for_selector("#error:not([hidden])", timeout=20000)
    page.wait_for_function("document.getElementById('status').textContent.startsWith('error at line')",
                           timeout=10000)
    # ... and undo from the editor (Ctrl+Z with nothing unsaved): the exact bytes before, valid TOML
    page.focus("#text")
    v = page.evaluate("studio.version")
    page.keyboard.press("Control+z")
    wait_version_change(page, v)
    assert scene.read_bytes() == before
    tomllib.loads(scene.read_text())
    page.wait_for_selector("#error", state="hidden", timeout=20000)
    assert page.input_value("#text") == text


def test_history_is_listed_and_survives_a_reload(fresh):
    page = fresh
    before = page.studio.scene.read_bytes()
    page.locator('[data-widget="volume"]').click()
    page.locator("#inspector input[name=value]").fill("0.7")
    page.locator("#inspector input[name=value]").press("Enter")
    wait_version_change(page, version_of(before))
    assert page.locator("#history li.current").text_content() == "volume.value = 0.7"
    page.reload()
    page.wait_for_function("window.studio && studio.shownGeneration !== null && studio.design && "
                           "studio.design.schema && studio.state.history", timeout=30000)
    assert page.locator("#history li.current").text_content() == "volume.value = 0.7"
    assert page.is_enabled("#undo")
    edited = page.studio.scene.read_bytes()
    page.evaluate("document.getElementById('history-box').open = true")
    v = page.evaluate("studio.version")
    page.click("#revert")                                   # the file as the studio opened it: a step of its own
    wait_version_change(page, v)
    assert page.studio.scene.read_bytes() == ORIGINAL
    assert page.locator("#history li.current").text_content() == "revert to the file as opened"
    undo_to(page, edited)
    undo_to(page, before)
    assert page.locator("#history li.current").text_content() == "the file as the history began" or \
        page.locator("#history li.undone").count() >= 1


# ------------------------------------------------------------------ conflicts
def test_an_external_write_during_an_unsaved_edit_is_a_conflict_until_the_designer_chooses(fresh):
    page = fresh
    scene = page.studio.scene
    text = scene.read_text()
    page.fill("#text", text.replace("value = 0.4 ", "value = 0.6 "))           # unsaved in the page
    external = text.replace('force = "3.5 N"', 'force = "3 N"')
    scene.write_text(external)                                                  # another editor saves
    page.wait_for_function(f"studio.state.scene_version === '{version_of(external.encode())}'", timeout=20000)
    assert page.evaluate("studio.dirty")
    page.keyboard.press("Control+s")
    page.wait_for_selector("#conflict:not([hidden])", timeout=10000)
    assert scene.read_text() == external                                        # nothing overwritten
    assert "value = 0.6" in page.inner_text("#conflict-mine") and 'force = "3 N"' in page.inner_text("#conflict-disk")
    page.wait_for_timeout(300)
    assert scene.read_text() == external                                        # ... until the designer chooses
    v = page.evaluate("studio.version")
    page.click("#merge")
    page.wait_for_selector("#conflict", state="hidden", timeout=10000)
    wait_version_change(page, v)
    merged = scene.read_text()
    assert merged == external.replace("value = 0.4 ", "value = 0.6 ")
    assert page.input_value("#text") == merged
    # a canvas edit made on a stale version (a second page) is a conflict too
    other = page.browser.new_page(viewport={"width": 1500, "height": 1000}, bypass_csp=True)
    try:
        other.goto(page.studio.url)
        other.wait_for_function("window.studio && studio.shownGeneration !== null && studio.design && "
                                "studio.design.schema", timeout=30000)
        stale = page.evaluate("studio.version")
        other.evaluate(f"studio.version = '{version_of(text.encode())}'")           # as if it had missed the news
        other.evaluate("studio.design.edit([{op: 'box', widget: 'home', d: [1, 0, 1, 0]}], 'move home')")
        other.wait_for_selector("#conflict:not([hidden])", timeout=10000)
        assert scene.read_text() == merged
        other.click("#take-disk")
        other.wait_for_selector("#conflict", state="hidden", timeout=10000)
        assert scene.read_text() == merged and page.evaluate("studio.version") == stale
    finally:
        other.close()


# ------------------------------------------------------------------ A/B and feel
def test_ab_switch_alternates_the_table_the_worklet_plays(fresh):
    page = fresh
    before = page.studio.scene.read_bytes()
    if page.evaluate("studio.node === null"):
        page.click("#feel")
        page.wait_for_function("studio.node !== null && studio.ctx.state === 'running'", timeout=20000)
    page.click("#pin")                                         # A = the phone scene as it is
    page.wait_for_function("studio.state.ab.a_checksum === studio.state.checksum", timeout=10000)
    a = page.evaluate("studio.state.checksum")
    page.locator('[data-widget="call"]').click()
    page.locator("#inspector input[name=force]").fill("1.5")
    page.locator("#inspector input[name=force]").press("Enter")
    wait_version_change(page, version_of(before))
    page.wait_for_function("studio.state.checksum !== studio.state.ab.a_checksum && studio.playing && "
                           "studio.playing.checksum === studio.state.checksum", timeout=20000)
    b = page.evaluate("studio.state.checksum")
    assert "call: normal force 3.5 → 1.5 N" in page.text_content("#ab-diff")
    seen = []
    for _ in range(4):
        page.click("#ab")
        page.wait_for_function(f"studio.playing.which === '{'A' if len(seen) % 2 == 0 else 'B'}'", timeout=10000)
        seen.append(page.evaluate("studio.playing.checksum"))
    assert seen == [a, b, a, b]
    # one key, also while stroking: the stroke goes on over the other table
    page.evaluate("studio.lastStroke = null")
    sx, sy = page.evaluate("studio.screenOf(0.062, 0.010)")
    page.mouse.move(sx, sy)
    page.mouse.down()
    for k in range(1, 16):
        page.mouse.move(sx, sy - 8 * k)
        page.wait_for_timeout(15)
        if k == 8:
            page.keyboard.press("a")
    page.wait_for_function("studio.playing.which === 'A'", timeout=10000)
    page.mouse.up()
    page.wait_for_function("studio.lastStroke !== null && studio.lastStroke.reason === 'up' && "
                           "studio.lastStroke.ticks > 0", timeout=20000)        # played on to the release
    page.keyboard.press("a")
    page.wait_for_function("studio.playing.which === 'B'", timeout=10000)
    # feel toggles off and on
    page.click("#feel")
    page.wait_for_function("studio.ctx.state === 'suspended'", timeout=10000)
    assert page.get_attribute("#feel", "aria-pressed") == "false"
    page.click("#feel")
    page.wait_for_function("studio.ctx.state === 'running'", timeout=10000)
    if SCREENSHOT_DIR:
        page.locator('[data-widget="call"]').click()
        page.evaluate("for (const id of ['history-box', 'ab-box']) document.getElementById(id).open = true;"
                      "document.querySelector('#side details:not(#design):not(#history-box):not(#ab-box)').open = false")
        page.mouse.move(*page.evaluate("studio.screenOf(0.040, 0.128)"))
        page.screenshot(path=str(Path(SCREENSHOT_DIR) / "studio-design.png"))
    undo_to(page, before)


# ------------------------------------------------------------------ exports
def test_exports_take_their_options_and_say_which_table_they_hold(fresh):
    page = fresh
    page.locator("#exports").locator("xpath=..").locator("summary").click()        # open the Export panel
    sel = page.locator('#exports select[name="friction-png-quantity"]')
    # the default shows the phone's shape (mu is uniform: the friction level mu_s N), and says so
    assert sel.input_value() == "auto"
    assert page.text_content("#bitmap-note").startswith("friction-png auto: breakaway_force (mu is uniform")
    sel.select_option("mu")
    assert "mu is uniform on this table: the image is flat" in page.text_content("#bitmap-note")
    sel.select_option("normal_force")
    href = page.get_attribute('#exports a[data-format="friction-png"]', "href")
    assert "quantity=normal_force" in href and "bits=16" in href
    r = page.evaluate(f"fetch('{href}').then(async r => [r.status, r.headers.get('X-Export-Table'), "
                      "(await r.arrayBuffer()).byteLength])")
    assert r[0] == 200 and r[1] == f"table {page.evaluate('studio.tableGeneration')}" and r[2] > 100
    assert (page.studio.folder / "studio-out" / "phone.png").is_file()
    # the AHAP of a stroke the page played (rendered offline through the same worklet)
    doc = page.evaluate("""(async () => { const s = await studio.renderOffline(
        Array.from({length: 6000}, (_, i) => 0.062), Array.from({length: 6000}, (_, i) => 0.01 + i * 2e-5));
        const r = await fetch(`/api/export-ahap?token=${document.body.dataset.token}`, {method: 'POST',
          body: JSON.stringify({event_time: Array.from(s.event_time), event_amplitude: Array.from(s.event_amplitude),
                                audio: Array.from(s.audio), t0: s.t[0]})});
        return [r.status, await r.json()]; })()""")
    assert doc[0] == 200 and doc[1]["Version"] == 1.0 and len(doc[1]["Pattern"]) > 3
    assert (page.studio.folder / "studio-out" / "phone-stroke.ahap").is_file()
    # while the scene has an error, an export says it holds the last good table
    gen = page.evaluate("studio.tableGeneration")
    page.studio.scene.write_text(ORIGINAL.decode().replace('size = "36x16 mm"', 'size = "36x16 furlong"'))
    page.wait_for_selector("#error:not([hidden])", timeout=20000)
    assert page.text_content("#export-note") == f"exports table {gen} — the last good one: the scene has an error, see above"
    note = page.evaluate("fetch(document.querySelector('#exports a[data-format=\"json\"]').href)"
                         ".then(r => r.headers.get('X-Export-Table'))")
    assert note == f"table {gen} (the last good one: the scene has an error)"
    page.wait_for_function("document.getElementById('status').textContent.startsWith('error at line')",
                           timeout=10000)


def test_a_locked_colour_scale_keeps_its_range_across_edits(fresh):
    page = fresh
    s = page.studio
    st, auto = s.get("/api/map.png?channel=normal_force")
    st2, locked = s.get("/api/map.png?channel=normal_force&range=0:10")
    assert st == st2 == 200 and auto != locked and locked.startswith(b"\x89PNG")
    assert s.get("/api/map.png?channel=normal_force&range=zero:ten")[0] == 400
    before = s.scene.read_bytes()
    hi = page.text_content("#scale-hi")
    page.check("#lock-scale")
    page.locator('[data-widget="call"]').click()
    page.locator("#inspector input[name=force]").fill("5.5")
    page.locator("#inspector input[name=force]").press("Enter")
    wait_version_change(page, version_of(before))
    page.wait_for_function("studio.state.ranges.normal_force[1] > 5", timeout=20000)
    assert page.text_content("#scale-hi") == hi                       # 3.50 N: the scale did not move
    assert "range=" in page.get_attribute("#map", "src")
    page.uncheck("#lock-scale")
    page.wait_for_function("document.getElementById('scale-hi').textContent.startsWith('5.5')", timeout=10000)
    undo_to(page, before)
