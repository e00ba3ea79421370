"""Force mapping: height mapping, lateral cue sign, skin stretch, perceptual scaling, channel needs."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from shapedisplay.author import sources
from shapedisplay.table.devices import load_device
from shapedisplay.errors import InputError
from shapedisplay.author.gradients import gradient
from shapedisplay.author.forces import (EXPONENTS, MappingOptions, force_channels, lateral_force, needed_channels,
                                   perceived, perceptual_scale)

RIG = load_device("desktop-rig")          # burst + lateral, N range 0.5..8 N, lateral max 1.5 N


def _slope(k=0.2, size=(0.02, 0.004), dx=0.5e-3):
    hf = sources.from_array(np.zeros((int(size[1] / dx), int(size[0] / dx))), dx)
    return hf.with_heights(np.broadcast_to(k * hf.x[None, :], hf.shape))


def test_parse_specs():
    m = MappingOptions.parse("height+lateral", n_base="0.5N", n_gain="2N/mm", lateral_gain="1.5 N")
    assert (m.height, m.n_base, m.n_gain, m.lateral, m.lateral_gain) == (True, 0.5, 2000.0, "gradient", 1.5)
    assert MappingOptions.parse("slope").height is False
    assert MappingOptions.parse("slope").slope_friction_gain == 0.2
    assert MappingOptions.parse("height+lateral-normal").lateral == "normal"
    assert MappingOptions.parse("height,stretch").skin_stretch == pytest.approx(0.55e-3)
    assert MappingOptions.parse("height+perceptual").perceptual_exponent == EXPONENTS["bumpiness"]
    assert MappingOptions.parse("height", perceptual_exponent="friction").perceptual_exponent == 1.26
    assert MappingOptions.parse("height+slope+lateral").spec == "height+slope+lateral"


def test_parse_errors():
    with pytest.raises(InputError, match=r"unknown mapping term 'lateal' \(did you mean 'lateral'\?\)"):
        MappingOptions.parse("height+lateal")
    with pytest.raises(InputError, match=r"unknown mapping option 'n_bse'"):
        MappingOptions.parse("height", n_bse=1.0)
    with pytest.raises(InputError, match="`n_gain` must be finite and >= 0"):
        MappingOptions(n_gain=-1.0)
    with pytest.raises(InputError, match="needs a unit"):
        MappingOptions.parse("height", n_gain="2")
    with pytest.raises(InputError, match="lateral_gain` must be > 0"):
        MappingOptions(lateral="gradient")
    with pytest.raises(InputError, match="mapping `perceptual_exponent` must be > 0"):
        MappingOptions(perceptual_exponent=-1.0)
    with pytest.raises(InputError, match=r"`mapping` may hold one lateral law, .* \(got 'lateral\+lateral-normal'\)"):
        MappingOptions.parse("lateral+lateral-normal")
    with pytest.raises(InputError, match=r"`lateral_gain` is K of the 'lateral' law .* mapping 'height\+lateral-normal'"):
        MappingOptions.parse("height+lateral-normal", lateral_gain="2N")


def test_a_gain_turns_its_term_on():
    """--lateral-gain with `--mapping height` was silently ignored; every gain now asks for its term."""
    m = MappingOptions.parse("height", lateral_gain="2N")
    assert m.lateral == "gradient" and m.lateral_gain == 2.0 and m.spec == "height+lateral"
    assert MappingOptions.parse("height", slope_friction_gain=0.3).spec == "height+slope"
    assert MappingOptions.parse("height", skin_stretch="0.4mm").spec == "height+stretch"


def test_height_mapping_and_clamping():
    hf = sources.from_array(np.array([[-1e-3, 0.0, 1e-3, 2e-3, 5e-3]]), 1e-3)
    ch = force_channels(hf, RIG, MappingOptions(n_base=0.5, n_gain=2000.0))
    assert list(ch) == ["normal_force"]
    assert np.allclose(ch["normal_force"], [[0.5, 0.5, 2.5, 4.5, 8.0]])   # -1.5 -> 0.5 and 10.5 -> 8
    c = ch.clamped["normal_force"]
    assert (c["below"], c["above"]) == (1, 1) and c["max_excess"] == pytest.approx(2.5)
    assert c["fraction"] == pytest.approx(0.4)


def test_lateral_cue_opposes_uphill():
    hf = _slope(k=0.2)                                  # uphill towards +x
    m = MappingOptions(lateral="gradient", lateral_gain=1.0)
    ch = force_channels(hf, RIG, m)
    assert np.allclose(ch["lateral_x"], -0.2) and np.allclose(ch["lateral_y"], 0.0)
    # moving in +x (uphill) the cue resists; moving in -x (downhill) it assists
    v = np.array([1.0, 0.0])
    assert np.all(ch["lateral_x"] * v[0] < 0)
    down = hf.with_heights(-hf.heights)
    assert np.allclose(force_channels(down, RIG, m)["lateral_x"], +0.2)


def test_lateral_normal_law_uses_rendered_force():
    hf = _slope(k=0.1)
    m = MappingOptions(height=True, n_base=0.5, n_gain=1000.0, lateral="normal")
    ch = force_channels(hf, RIG, m)
    assert np.allclose(ch["lateral_x"], -ch["normal_force"] * 0.1)
    m_const = MappingOptions(height=False, n_base=0.7, lateral="normal")
    assert np.allclose(force_channels(hf, RIG, m_const)["lateral_x"], -0.07)


def test_lateral_magnitude_clamped_direction_kept():
    gx, gy = np.array([[3.0, 0.3]]), np.array([[4.0, 0.4]])
    fx, fy, note = lateral_force(gx, gy, RIG, MappingOptions(lateral="gradient", lateral_gain=1.0))
    assert np.hypot(fx, fy)[0, 0] == pytest.approx(1.5)          # device lateral_force_max
    assert fx[0, 0] / fy[0, 0] == pytest.approx(0.75)
    assert (fx[0, 1], fy[0, 1]) == (pytest.approx(-0.3), pytest.approx(-0.4))
    assert note["above"] == 1 and note["max_excess"] == pytest.approx(3.5)


@pytest.mark.parametrize("shape", [(1, 3), (300, 300)])   # numpy path and C kernel path
def test_lateral_clipping_never_gives_nan_or_loses_direction(shape):
    """A tiny force limit squared underflowed to 0 and 0/0 made NaN; an overflowing |F|^2 clipped to 0."""
    gx = np.resize(np.array([0.0, 1.0, 2.0]), shape)
    tiny = RIG.with_(lateral_force_max=1e-170)
    fx, fy, _ = lateral_force(gx, np.zeros(shape), tiny, MappingOptions(lateral="gradient", lateral_gain=1.0))
    assert np.all(np.isfinite(fx)) and np.all(np.abs(fx) <= 1e-170) and np.all(fx[gx == 0] == 0)
    with pytest.raises(InputError, match=r"lateral forces overflow float64"):
        lateral_force(np.full(shape, 1e200), np.zeros(shape), RIG, MappingOptions(lateral="gradient", lateral_gain=1.0))


def test_skin_stretch_follows_breakaway_force():
    tactor = load_device("skin-stretch-tactor")            # N range 1..1.5 N, stretch max 0.75 mm
    hf = sources.from_array(np.array([[0.0, 0.1e-3, 0.3e-3, 1e-3]]), 1e-3)
    m = MappingOptions(n_base=1.0, n_gain=1000.0, skin_stretch=0.55e-3)
    ch = force_channels(hf, tactor, m)
    n = ch["normal_force"]
    assert np.allclose(n, [[1.0, 1.1, 1.3, 1.5]])
    # delta = mu_s N / k_s with k_s = mu_s n_base / target, i.e. target * N / n_base, capped at 0.75 mm
    assert np.allclose(ch["skin_stretch"], np.minimum(0.55e-3 * n / 1.0, 0.75e-3))
    assert ch.clamped["skin_stretch"]["above"] == 1


def test_perceptual_scale_makes_equal_steps():
    beta = EXPONENTS["bumpiness"]
    d = np.linspace(0.0, 2.0, 9)
    phi = perceptual_scale(d, 2.0, 4.0, beta)
    psi = perceived(phi, 1.0, beta)
    assert np.allclose(np.diff(psi), psi[1] - psi[0])            # equal perceived steps
    assert phi[-1] == pytest.approx(4.0) and phi[0] == 0.0
    # threshold-corrected form: psi = k (phi - phi_th)^beta is linear in d
    phi_t = perceptual_scale(d[1:], 2.0, 4.0, beta, phi_th=0.5)
    psi_t = perceived(phi_t, 1.0, beta, phi_th=0.5)
    assert np.allclose(psi_t / psi_t[-1], d[1:] / 2.0)
    assert phi_t[-1] == pytest.approx(4.0)
    with pytest.raises(InputError, match="phi_th < phi0"):
        perceptual_scale(d, 2.0, 4.0, beta, phi_th=5.0)


def test_perceptual_height_mapping_keeps_extremes():
    hf = sources.from_array(np.linspace(0, 1e-3, 11)[None, :], 1e-4)
    lin = force_channels(hf, RIG, MappingOptions(n_base=0.5, n_gain=2000.0))["normal_force"]
    per = force_channels(hf, RIG, MappingOptions(n_base=0.5, n_gain=2000.0, perceptual_exponent=0.76))["normal_force"]
    assert per[0, 0] == pytest.approx(lin[0, 0]) and per[0, -1] == pytest.approx(lin[0, -1])
    psi = perceived(per - 0.5, 1.0, 0.76)
    assert np.allclose(np.diff(psi[0]), psi[0, 1] - psi[0, 0])


def test_needed_channels_follow_device_outputs():
    m = MappingOptions.parse("height+lateral+slope+stretch")
    kept, left = needed_channels(RIG, m)
    assert kept == ["normal_force", "grad_x", "grad_y", "lateral_x", "lateral_y"]
    assert "no 'skin_stretch' output" in left["skin_stretch"]
    kept, left = needed_channels(load_device("handheld-stick"), m)
    assert "lateral_x" not in kept and "no 'lateral' output" in left["lateral_x"]
    kept, left = needed_channels(load_device("skin-stretch-tactor"), m)
    assert "skin_stretch" in kept and "lateral_x" not in kept
    kept, left = needed_channels(RIG, m, is_1d=True)
    assert "grad_y" not in kept and "lateral_y" not in kept and "1-D" in left["lateral_y"]
    assert set(kept) | set(left) == set(__import__("shapedisplay.table.model", fromlist=["CHANNELS"]).CHANNELS)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3), min_size=4, max_size=40),
       st.sampled_from(["height", "height+lateral", "height+lateral-normal+slope", "slope+lateral"]))
def test_no_nan_from_finite_input(values, spec):
    hf = sources.from_array(np.array(values).reshape(2, -1) if len(values) % 2 == 0 else np.array(values), 1e-4)
    ch = force_channels(hf, RIG, MappingOptions.parse(spec), grad=gradient(hf))
    for v in ch.values():
        assert np.all(np.isfinite(v))
    if "normal_force" in ch:
        assert ch["normal_force"].min() >= 0.5 and ch["normal_force"].max() <= 8.0
    if "lateral_x" in ch:
        assert np.hypot(ch["lateral_x"], ch.get("lateral_y", 0)).max() <= 1.5 * (1 + 1e-12)


def test_equal_steps_is_the_one_inverted_power_law():
    """psi of equal_steps(t) is linear in t, with and without a threshold; the plain form is exact."""
    from shapedisplay.author.forces import equal_steps
    t = np.linspace(0.0, 1.0, 11)
    for lo, hi, beta, th in ((0.0, 4.0, 0.76, 0.0), (0.8, 1.5, 1.26, 0.0), (0.5, 2.0, 0.6, 0.3), (0.3, 2.0, 0.6, 0.3)):
        psi = perceived(equal_steps(t, lo, hi, beta, th), 1.0, beta, th)
        np.testing.assert_allclose(psi, psi[0] + t * (psi[-1] - psi[0]), rtol=1e-12, atol=1e-15)
    # level i of n asks for F (i/n)^(1/beta), bit for bit
    assert equal_steps(3 / 5, 0.0, 4.0, 0.76) == 4.0 * (3 / 5) ** (1 / 0.76)
    with pytest.raises(InputError):
        equal_steps(t, 1.0, 0.5, 0.76)
    with pytest.raises(InputError):
        equal_steps(t, 0.0, 1.0, 0.0)
