"""Reactive widgets in the studio, in a real headless Chromium (Playwright): a press on the bundled toggle
flips it (the page shows the new state, the worklet's event list has `toggle`), a press-drag on the slider's
thumb moves it (docs/reactive.md). The press is Space held while the pointer is down."""
from __future__ import annotations

import shutil

import pytest

from studio_helpers import require_chromium

require_chromium()                                        # skips the module without them

from studio_helpers import ROOT, studio_page  # noqa: E402


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    folder = tmp_path_factory.mktemp("studio-reactive")
    shutil.copy(ROOT / "assets" / "scenes" / "reactive.toml", folder / "reactive.toml")
    with studio_page(folder / "reactive.toml",
                     "window.studio && studio.shownGeneration !== null && studio.layout !== null") as pg:
        pg.select_option("#tool", "feel")
        pg.click("#feel")
        pg.wait_for_function("studio.node !== null && studio.ctx.state === 'running'", timeout=20000)
        pg.evaluate("document.activeElement && document.activeElement.blur()")
        yield pg
        errors = pg.js_errors
    assert not errors, errors


def _press_at(page, x, y, to=None, hold_ms=300, steps=30):
    """Pointer down at (x, y) m, Space held (the press), optionally dragged to ``to``, Space and pointer up."""
    sx, sy = page.evaluate(f"studio.screenOf({x}, {y})")
    page.mouse.move(sx, sy)
    page.mouse.down()
    page.wait_for_timeout(100)
    page.keyboard.down("Space")
    page.wait_for_timeout(hold_ms)
    if to is not None:
        bx, by = page.evaluate(f"studio.screenOf({to[0]}, {to[1]})")
        for i in range(1, steps + 1):
            page.mouse.move(sx + (bx - sx) * i / steps, sy + (by - sy) * i / steps)
            page.wait_for_timeout(20)
        page.wait_for_timeout(150)
    page.keyboard.up("Space")
    page.wait_for_timeout(150)
    page.mouse.up()


def test_press_flips_the_toggle_and_a_press_drag_moves_the_slider_thumb(page):
    assert page.evaluate("studio.layout.reactions.map((r) => r.id)") == ["button", "toggle", "slider", "object", "list"]
    assert page.evaluate("studio.widgetStates.toggle ? studio.widgetStates.toggle.state : 0") == 0
    _press_at(page, 0.060, 0.020)
    page.wait_for_function("studio.reactions.some((e) => e.kind === 'toggle' && e.widget === 'toggle')",
                           timeout=10000)
    page.wait_for_function("studio.widgetStates.toggle && studio.widgetStates.toggle.state === 1", timeout=10000)
    assert "toggle on" in page.text_content("#reactions")
    kinds = page.evaluate("studio.reactions.filter((e) => e.widget === 'toggle').map((e) => e.kind)")
    assert kinds[:3] == ["press", "toggle", "click"]
    # the slider's thumb rests at the track's start (x 13 mm, y 45 mm): grab it and drag it 25 mm
    start = page.evaluate("studio.widgetStates.slider.thumb")
    assert start == pytest.approx(0.013, abs=1e-6)
    _press_at(page, 0.0135, 0.045, to=(0.0385, 0.045))
    page.wait_for_function("studio.reactions.some((e) => e.kind === 'drop' && e.widget === 'slider')", timeout=10000)
    st = page.evaluate("studio.widgetStates.slider")
    assert st["thumb"] == pytest.approx(0.038, abs=1.5e-3) and st["value"] == pytest.approx(25 / 44, abs=0.05)
    assert "slider 0.5" in page.text_content("#reactions")
    # the toggle stayed flipped across strokes
    assert page.evaluate("studio.widgetStates.toggle.state") == 1
