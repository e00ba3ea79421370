"""The Cortex-M4F build (arm-none-eabi-gcc, newlib-nano libm) under QEMU (mps2-an386).

`make -C runtime-c m4` builds a bare-metal harness that reads the shared vectors through Arm
semihosting and plays them. The default build is single precision (-DSD_SINGLE, the FPU's
fpv4-sp-d16): it is compared with the host's double-precision engine (``Renderer``) within the
derived bounds of runtime_vectors.float_bounds; the double build (M4_PRECISION=double) within
derived_bounds (newlib's libm is not glibc's).
"""
import shutil

import numpy as np
import pytest

from runtime_vectors import (CASES, REACT_CASES, assert_same_reactions, assert_within_derived_bounds,
                             assert_within_float_bounds, build_m4, case_setup, image_payload, m4_instructions,
                             parse_events, parse_outputs, parse_reactions, py_render_events, py_render_reactions,
                             react_payload, react_setup, run_m4, tick_path_functions)
from test_c_runtime import py_render

_MISSING = [t for t in ("arm-none-eabi-gcc", "qemu-system-arm", "make") if shutil.which(t) is None]
pytestmark = pytest.mark.skipif(
    bool(_MISSING) and shutil.which("apt-get") is None,
    reason=f"no {_MISSING} and no apt-get to install them (scripts/install-system-deps.sh --with-toolchains)")


@pytest.fixture(scope="module")
def m4(tmp_path_factory):
    assert not _MISSING, f"{_MISSING} missing: run scripts/install-system-deps.sh --with-toolchains"
    return build_m4(tmp_path_factory.mktemp("m4"))


@pytest.fixture(scope="module")
def m4_double(tmp_path_factory):
    assert not _MISSING, f"{_MISSING} missing: run scripts/install-system-deps.sh --with-toolchains"
    return build_m4(tmp_path_factory.mktemp("m4d"), precision="double")


@pytest.mark.parametrize("dtype, kind, policy, tick, audio, model", CASES)
def test_m4_single_precision_plays_the_shared_vectors(m4, tmp_path, dtype, kind, policy, tick, audio, model):
    """Same events (count; times, amplitudes within the derived bounds), drive, audio and force within
    the derived bounds of the single-precision build."""
    elf, _ = m4
    table, r, x, y, img = case_setup(dtype, kind, policy, tick, audio, model, seconds=0.12)
    po, pa, pt, pA = py_render_events(r, x, y)
    raw = run_m4(elf, "vectors", image_payload(img, r, x, y), tmp_path)
    co, ca, (cclip, cev, cdrop, cfault) = parse_outputs(raw, len(x))
    ct, cA = parse_events(raw, len(x))
    assert len(pt) > 10 and cev == len(pt) and cdrop == 0 and ca.size == pa.size
    assert_within_float_bounds(r, table, x, y, po, pa, pt, pA, co, ca, ct, cA)


@pytest.mark.parametrize("dtype, kind, policy, tick, audio, model", CASES[:2])
def test_m4_double_build_plays_the_shared_vectors(m4_double, tmp_path, dtype, kind, policy, tick, audio, model):
    elf, _ = m4_double
    table, r, x, y, img = case_setup(dtype, kind, policy, tick, audio, model, seconds=0.06)
    po, pa, (pclip, pev) = py_render(r, x, y)
    co, ca, (cclip, cev, cdrop, cfault) = parse_outputs(run_m4(elf, "vectors", image_payload(img, r, x, y), tmp_path),
                                                        len(x))
    assert pev > 10 and cev == pev and cdrop == 0 and ca.size == pa.size
    assert_within_derived_bounds(r, po, pa, co, ca)


def test_m4_single_precision_tick_path_calls_no_double_arithmetic(m4, m4_double):
    """No software double-precision helper (__aeabi_d*) or double libm function is reachable from
    sd_renderer_step or the pad ticks in the single-precision build; the double build has them (the
    check sees calls)."""
    double_fns = {"sin", "cos", "exp", "log", "atan2", "sqrt", "fmod", "floor", "ceil", "pow"}

    def doubles(elf):
        fns = tick_path_functions(elf)
        assert {"sd_renderer_step", "sd_jump_tick", "sd_exact_tick", "sinf", "expf"} <= set(fns) or \
            {"sd_renderer_step", "sd_jump_tick", "sd_exact_tick", "sin", "exp"} <= set(fns)
        return sorted(f for f in fns if f.startswith("__aeabi_d") or f in double_fns
                      or f.startswith("__aeabi_f2d"))
    assert doubles(m4[0]) == []
    assert "__aeabi_dmul" in doubles(m4_double[0])


def test_m4_instruction_counts_are_measured(m4, tmp_path):
    """The benchmark's counter: per-tick instruction counts under -icount are positive, repeatable,
    and a tick with stick-slip events costs more than a tick stuck throughout."""
    elf, (text, data, bss) = m4
    assert 10_000 < text < 200_000
    table, r, x, y, img = case_setup("uint16", "diagonal", "retrigger", 10_000.0, 48_000.0, "jump", seconds=0.03)
    payload = image_payload(img, r, x, y)
    a = m4_instructions(run_m4(elf, "bench", payload, tmp_path, icount=True))
    b = m4_instructions(run_m4(elf, "bench", payload, tmp_path, icount=True))
    np.testing.assert_array_equal(a, b)                  # deterministic: counts, not time
    po, _, _ = py_render(r, x, y)
    ev = po["events"] > 0
    assert a.size == len(x) and (a > 50).all()
    assert np.median(a[ev]) > np.median(a[~ev])


@pytest.mark.parametrize("name, stroke, model, tick, audio", REACT_CASES)
def test_m4_single_precision_plays_the_reaction_vectors(m4, tmp_path, name, stroke, model, tick, audio):
    """The reactive scene with a press per tick on the M4F: the same reaction events (kind, widget, tick; values
    within float rounding), outputs within the derived bounds of the single-precision build."""
    elf, _ = m4
    table, r, x, y, press, img = react_setup(name, stroke, model, tick, audio)
    po, pa, pt, pA, prev = py_render_reactions(r, x, y, press)
    raw = run_m4(elf, "react", react_payload(img, r, x, y, press), tmp_path)
    co, ca, (cclip, cev, cdrop, cfault) = parse_outputs(raw, len(x))
    ct, cA = parse_events(raw, len(x))
    assert cev == len(pt) and cdrop == 0 and ca.size == pa.size
    assert_same_reactions(parse_reactions(raw, len(x)), prev, value_tol=1e-5)
    assert_within_float_bounds(r, table, x, y, po, pa, pt, pA, co, ca, ct, cA)


def test_m4_tick_with_reactions_within_budget(m4, tmp_path):
    """Instructions per tick on the M4F with reactions active (the reactive scene: a button pressed, a toggle
    flipped, a thumb dragged, an object dragged, a list scrolling under the finger), jump model, 10 kHz ticks,
    48 kHz audio: the mean stays within 8,400 (half the 16.8k cycles of a 168 MHz core, instructions being at
    most cycles)."""
    from runtime_vectors import REACT_BENCH
    elf, _ = m4
    table, r, x, y, press, img = react_setup("bench", REACT_BENCH, "jump", 10_000.0, 48_000.0)
    ins = m4_instructions(run_m4(elf, "react-bench", react_payload(img, r, x, y, press), tmp_path, icount=True))
    assert ins.size == len(x) and ins.mean() <= 8_400, (ins.mean(), ins.max())
