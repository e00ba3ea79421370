"""Reactive widgets and moving surfaces in the C runtime's builds on the host: the same vectors everywhere.

The bundled reactive scene (assets/scenes/reactive.toml) is played with a press force per tick
(runtime_vectors.REACT_CASES: a button pressed, a toggle flipped, a slider's thumb dragged across its
detents, an object dragged, a finger on a scrolling list) by `sd_vectors react`, built in double precision
(bit for bit the package's engine, ``Renderer``) and in single precision with the sanitizers (within the
derived bounds of runtime_vectors.float_bounds, and the same reaction events: kind, widget and tick).
"""
import numpy as np
import pytest

from runtime_vectors import (REACT_CASES, assert_same_reactions, assert_within_float_bounds, parse_events,
                             parse_outputs, parse_reactions, py_render_reactions, react_payload, react_setup)
from shapedisplay.render.cursor import parse_stroke
from test_c_runtime import assert_outputs_equal
from test_c_runtime_robust import _run
from test_c_runtime_single import sd_double, sd_single   # noqa: F401  (fixtures)


@pytest.mark.parametrize("name, stroke, model, tick, audio", REACT_CASES)
def test_host_double_build_plays_reactions_bit_for_bit(sd_double, tmp_path, name, stroke, model, tick, audio):
    table, r, x, y, press, img = react_setup(name, stroke, model, tick, audio)
    po, pa, pt, pA, prev = py_render_reactions(r, x, y, press)
    raw = _run(sd_double, "react", react_payload(img, r, x, y, press), tmp_path)
    co, ca, (_, cev, cdrop, _) = parse_outputs(raw, len(x))
    ct, cA = parse_events(raw, len(x))
    crev = parse_reactions(raw, len(x))
    assert prev.size >= 4 and len(pt) > 10 and cev == len(pt) and cdrop == 0
    assert_outputs_equal(co, po)
    np.testing.assert_array_equal(ca, pa)
    np.testing.assert_array_equal(ct, pt)
    assert_same_reactions(crev, prev)


def test_reaction_vectors_exercise_every_event_kind():
    """Between them the shared vectors fire every kind of event and move every kind of part."""
    from shapedisplay.render.layouts import EVENT_KINDS
    seen = set()
    for name, stroke, model, tick, audio in REACT_CASES:
        table, r, x, y, press, img = react_setup(name, stroke, model, tick, audio)
        seen |= set(r.render(parse_stroke(stroke, tick)).event_kind)
    assert seen == set(EVENT_KINDS)


@pytest.mark.parametrize("name, stroke, model, tick, audio", REACT_CASES)
def test_single_precision_build_plays_reactions_within_derived_bounds(sd_single, tmp_path, name, stroke, model, tick,
                                                                      audio):
    table, r, x, y, press, img = react_setup(name, stroke, model, tick, audio)
    po, pa, pt, pA, prev = py_render_reactions(r, x, y, press)
    raw = _run(sd_single, "react", react_payload(img, r, x, y, press), tmp_path)
    co, ca, (_, cev, cdrop, _) = parse_outputs(raw, len(x))
    ct, cA = parse_events(raw, len(x))
    assert cev == len(pt) and cdrop == 0
    assert_same_reactions(parse_reactions(raw, len(x)), prev, value_tol=1e-5)
    assert_within_float_bounds(r, table, x, y, po, pa, pt, pA, co, ca, ct, cA)
