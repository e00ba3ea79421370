"""Gradient analysis against analytic slopes; walls and how they are limited."""
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from shapedisplay.author import sources
from shapedisplay.errors import InputError
from shapedisplay.author.gradients import (GRADIENT_METHODS, detect_walls, gradient, limit_walls, slope_along,
                                    slope_magnitude)

A, S = 1e-3, 2e-3          # bump height and sigma, m


def _bump(dx):
    return sources.gaussian_bump(A, S, (0.016, 0.012), dx, center=(0.0081, 0.0059))


def _analytic(hf):
    x, y = hf.x[None, :] - 0.0081, hf.y[:, None] - 0.0059
    h = A * np.exp(-(x * x + y * y) / (2 * S * S))
    return -x / S ** 2 * h, -y / S ** 2 * h


def _third_derivative_bound():
    # max |d^3/dx^3 exp(-x^2/2s^2)| * A = A/s^3 * max |(3u - u^3) exp(-u^2/2)|
    u = np.linspace(-6, 6, 200001)
    return A / S ** 3 * np.abs((3 * u - u ** 3) * np.exp(-u * u / 2)).max()


def test_central_matches_analytic_within_stated_error():
    m3 = _third_derivative_bound()
    errs = []
    for dx in (0.2e-3, 0.1e-3):
        hf = _bump(dx)
        gx, gy = gradient(hf, "central")
        ax, ay = _analytic(hf)
        err = max(np.abs(gx - ax).max(), np.abs(gy - ay).max())
        # central: h^2/6 f'''; one-sided second-order edges: h^2/3 f'''
        assert err <= dx * dx / 3 * m3
        errs.append(err)
    assert errs[0] / errs[1] == pytest.approx(4.0, rel=0.05)   # O(h^2)


def test_central_is_exact_on_quadratics():
    hf = sources.from_array(np.zeros((5, 6)), 1e-3, 2e-3)
    x, y = hf.x[None, :], hf.y[:, None]
    hf = hf.with_heights(0.3 * x * x - 0.2 * x * y + 0.7 * y * y + 0.01 * x)
    gx, gy = gradient(hf)
    assert np.allclose(gx, 0.6 * x - 0.2 * y + 0.01, rtol=0, atol=1e-15)
    assert np.allclose(gy, -0.2 * x + 1.4 * y, rtol=0, atol=1e-15)


def test_gaussian_method_is_the_slope_of_the_smoothed_bump():
    # a Gaussian bump smoothed by a Gaussian of sigma s is a Gaussian of sigma^2 + s^2
    hf = _bump(0.05e-3)
    s = 0.5e-3
    gx, gy = gradient(hf, "gaussian", sigma="0.5 mm")
    v = S * S + s * s
    x, y = hf.x[None, :] - 0.0081, hf.y[:, None] - 0.0059
    hs = A * (S * S / v) * np.exp(-(x * x + y * y) / (2 * v))
    inner = (slice(40, -40), slice(40, -40))
    peak = np.abs(-x / v * hs).max()
    assert np.abs(gx - (-x / v * hs))[inner].max() <= 2e-3 * peak
    assert np.abs(gy - (-y / v * hs))[inner].max() <= 2e-3 * peak


def test_savgol_exact_on_cubics():
    hf = sources.from_array(np.zeros((15, 20)), 0.5e-3)
    x, y = hf.x[None, :], hf.y[:, None]
    hf = hf.with_heights(2.0 * x ** 3 - x * x * y + 5.0 * y ** 3 + 0.1 * x)
    gx, gy = gradient(hf, "savgol", window=7, order=3)
    assert np.allclose(gx, 6.0 * x * x - 2 * x * y + 0.1, rtol=0, atol=1e-12)
    assert np.allclose(gy, -x * x + 15.0 * y * y, rtol=0, atol=1e-12)
    gx2, _ = gradient(hf, "savgol", window="3.5 mm", order=3)   # 7 samples
    assert np.allclose(gx2, gx, atol=1e-14)


def test_one_d_fields_have_no_y_slope():
    hf = sources.tent_profile(0.01, 0.02, 0.04, n2=1.5, dx=1e-4)
    for m in GRADIENT_METHODS:
        gx, gy = gradient(hf, m)
        assert gx.shape == (1, hf.cols) and np.all(gy == 0)
    gx, _ = gradient(hf)
    inside = (hf.x > 0.0102) & (hf.x < 0.0198)
    assert np.allclose(gx[0, inside], 1.0 / 1000.0 * 100.0)   # k / n_gain = 0.1 N/mm / 1 N/mm


def test_method_errors():
    hf = _bump(0.5e-3)
    with pytest.raises(InputError, match=r"unknown gradient method 'gauss' \(did you mean 'gaussian'\?\)"):
        gradient(hf, "gauss")
    with pytest.raises(InputError, match="unknown option of gradient method 'gaussian' 'sigam'"):
        gradient(hf, "gaussian", sigam=1e-3)
    with pytest.raises(InputError, match="must exceed `order`"):
        gradient(hf, "savgol", window=3, order=3)
    with pytest.raises(InputError, match="`sigma` must be a length > 0"):
        gradient(hf, "gaussian", sigma=-1.0)
    with pytest.raises(InputError, match=r"`sigma` must not exceed the map extent \(0.016 m x 0.012 m; got sigma=1000 m\)"):
        gradient(hf, "gaussian", sigma="1000 m")   # would otherwise build a 10^7-tap kernel
    with pytest.raises(InputError, match=r"`window` must be an odd number of samples .* \(got 4\)"):
        gradient(hf, "savgol", window=4)


def test_slope_along_and_magnitude():
    gx, gy = np.array([[3.0]]), np.array([[4.0]])
    assert slope_along(gx, gy, 0.0) == pytest.approx(3.0)
    assert slope_along(gx, gy, math.pi / 2) == pytest.approx(4.0)
    assert slope_along(gx, gy, (1.0, 1.0)) == pytest.approx(7 / math.sqrt(2))
    assert slope_magnitude(gx, gy) == pytest.approx(5.0)
    with pytest.raises(InputError, match="non-zero"):
        slope_along(gx, gy, (0.0, 0.0))


def test_step_is_a_wall_where_it_is():
    hf = sources.step_edge("1mm", "10x2mm", "0.1mm", position="5mm")
    gx, gy = gradient(hf)
    rep = detect_walls(hf, gx, gy, max_slope=1.0)
    # the central difference spreads the jump over the two samples beside it: slope 1mm/0.2mm = 5
    assert rep.count == 2 * hf.rows and rep.regions == 1
    assert rep.steepest == pytest.approx(5.0)
    assert rep.boxes_mm == [[pytest.approx(4.95), pytest.approx(5.05), pytest.approx(0.05), pytest.approx(1.95)]]
    smooth = _bump(0.2e-3)
    assert detect_walls(smooth, *gradient(smooth), 1.0).count == 0


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(st.floats(-50, 50), st.floats(-50, 50)), min_size=1, max_size=30),
       st.floats(0.01, 10))
def test_limit_walls_clips_magnitude_keeps_direction(pairs, limit):
    gx = np.array([[p[0] for p in pairs]])
    gy = np.array([[p[1] for p in pairs]])
    lx, ly = limit_walls(gx, gy, limit)
    mag, lmag = np.hypot(gx, gy), np.hypot(lx, ly)
    assert np.all(lmag <= limit * (1 + 1e-12))
    keep = mag <= limit
    assert np.array_equal(lx[keep], gx[keep]) and np.array_equal(ly[keep], gy[keep])
    over = ~keep
    assert np.allclose(lmag[over], limit)
    # same direction: cross product zero, dot product positive
    assert np.allclose(lx[over] * gy[over] - ly[over] * gx[over], 0, atol=1e-9 * (1 + mag[over].max(initial=0)))
    assert np.all(lx[over] * gx[over] + ly[over] * gy[over] > 0)


def test_max_slope_must_be_positive():
    with pytest.raises(InputError, match="`max_slope` must be > 0"):
        limit_walls(np.zeros((1, 2)), np.zeros((1, 2)), 0.0)


@pytest.mark.parametrize("cols", [8, 512])   # numpy path and C kernel path
def test_overflowing_slopes_are_refused_not_zeroed(cols):
    """|g|^2 overflowing to inf used to clip the wall slopes to 0 (direction lost)."""
    from shapedisplay.author.heightfield import HeightField
    h = np.zeros((max(2, (1 << 16) // cols + 1), cols))
    h[:, cols // 2:] = 1e-3
    hf = HeightField(h, 1e-300, 1e-300)
    gx, gy = gradient(hf)
    with pytest.raises(InputError, match=r"slopes overflow float64 .* dx=1e-300 m"):
        detect_walls(hf, gx, gy, 1.0)
    with pytest.raises(InputError, match="slopes overflow float64"):
        limit_walls(gx, gy, 1.0)
    # a steep but representable wall keeps its direction at the limit
    gx, gy = gradient(HeightField(h, 1e-9, 1e-9))
    lx, ly = limit_walls(gx, gy, 1.0)
    assert lx.max() == pytest.approx(1.0) and np.all(np.isfinite(lx))


def test_limit_walls_with_subnormal_slopes_warns_nothing_and_keeps_them():
    import warnings
    gx = np.array([[1e-160, 0.0, 5.0]])    # |g|^2 = 1e-320 is subnormal
    with warnings.catch_warnings():
        warnings.simplefilter("error")       # 1/|g|^2 overflowed with a RuntimeWarning
        lx, _ = limit_walls(gx, np.zeros_like(gx), 1.0)
    assert lx.tolist() == [[1e-160, 0.0, 1.0]]


def _regions_by_scipy(mask, k):
    """Reference: label with scipy, order every region by (size descending, label), boxes by search."""
    from scipy import ndimage
    labels, n = ndimage.label(mask)
    sizes = np.bincount(labels.ravel(), minlength=n + 1)
    sizes[0] = 0
    top = np.lexsort((np.arange(n + 1), -sizes))[:min(k, n)]
    spans = []
    for t in top:
        r, c = np.nonzero(labels == t)
        spans.append((int(r.min()), int(r.max()), int(c.min()), int(c.max())))
    return n, [int(t) for t in top], spans


def _regions_both_ways(mask, k):
    """wall_regions' result (the C count), as the lists _regions_by_scipy gives (one way: the engine's)."""
    from shapedisplay.author import gradients
    n, top, spans = gradients.wall_regions(mask, k)
    assert top.dtype == np.int64 and all(type(v) is int for box in spans for v in box)
    return [(n, top.tolist(), spans)]


@settings(max_examples=80, deadline=None)
@given(st.integers(1, 40), st.integers(1, 40), st.floats(0.0, 1.0), st.integers(0, 30), st.integers(0, 2 ** 32 - 1))
def test_wall_regions_match_scipy_labelling(rows, cols, density, k, seed):
    mask = np.random.default_rng(seed).random((rows, cols)) < density
    for found in _regions_both_ways(mask, k):
        assert found == _regions_by_scipy(mask, k)


def test_wall_regions_beyond_the_size_histogram_and_ties():
    mask = np.zeros((700, 700), bool)
    mask[10:310, 20:320] = True             # 90 000 samples: beyond the histogram's top bin (65 536)
    mask[400:690, 400:690] = True           # 84 100 samples: also beyond it
    mask[350:352, ::2] = True               # 350 regions of 2 samples: ties filled in label order
    mask[360, 1::2] = True                  # 350 single samples
    for k in (1, 2, 3, 20, 400, 1000):
        for found in _regions_both_ways(mask, k):
            assert found == _regions_by_scipy(mask, k)
    assert found[2][0] == (10, 309, 20, 319) and found[2][1] == (400, 689, 400, 689)
    for found in _regions_both_ways(np.zeros((5, 5), bool), 20):
        assert found == (0, [], [])


def test_wall_regions_of_shapes_that_merge_late():
    """Regions whose runs meet only rows later (a U, a comb, a spiral, a full mask, single rows and columns):
    the one-pass count keeps the lowest-numbered run as each region's root, so the labels stay scipy's."""
    u = np.zeros((30, 40), bool)
    u[2:28, 3] = u[2:28, 36] = u[27, 3:37] = True          # two arms joined at the bottom row
    comb = np.zeros((25, 61), bool)
    comb[:20, ::4] = True
    comb[22, :] = True                                     # teeth joined by a bar below them
    spiral = np.zeros((41, 41), bool)
    for i in range(0, 20, 4):
        spiral[i, i:41 - i] = spiral[i:41 - i, 40 - i] = spiral[40 - i, i:41 - i] = True
        spiral[i + 2:41 - i, i] = True
        if i + 2 < 41 - i - 2:
            spiral[i + 2, i:i + 4] = True
    rng = np.random.default_rng(5)
    for mask in (u, comb, spiral, np.ones((17, 23), bool), rng.random((1, 300)) < 0.5,
                 rng.random((300, 1)) < 0.5, rng.random((257, 263)) < 0.59):
        for k in (1, 5, 50):
            for found in _regions_both_ways(mask, k):
                assert found == _regions_by_scipy(mask, k)


def test_wall_regions_out_of_memory_is_one_line(monkeypatch):
    """The C count reports that it ran out of memory (-1): one line naming the map, no partial result."""
    import types

    from shapedisplay.author import kernels as _kernels, gradients
    mask = np.random.default_rng(8).random((60, 70)) < 0.5
    monkeypatch.setattr(_kernels, "library", lambda: types.SimpleNamespace(sd_regions=lambda *args: -1))
    with pytest.raises(InputError, match=r"not enough memory to count the wall regions of a 70 x 60 map"):
        gradients.wall_regions(mask, 6)
