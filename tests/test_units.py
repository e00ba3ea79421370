"""Quantities with units: exact conversions and one-line errors naming the field."""
import math

import pytest
from hypothesis import given, settings, strategies as st

from shapedisplay.errors import InputError, UnitError
from shapedisplay.units import format_quantity, parse_pair, parse_quantity, parse_unit


@pytest.mark.parametrize("text, unit, expected", [
    ("2 N/mm", "N/m", 2000.0),
    ("1e-5 N*s/mm", "N*s/m", 1e-2),
    ("80 mm/(N*s)", "m/(N*s)", 0.08),
    ("316 mm/(N*s)", "m/(N*s)", 0.316),
    ("0.5N", "N", 0.5),
    ("10kHz", "Hz", 1e4),
    ("2.0 N/mm", "N/m", 2000.0),
    ("0.25 mm", "m", 2.5e-4),
    ("12.5 mm/s", "m/s", 0.0125),
    ("1 N s/m", "N*s/m", 1.0),
    ("5 ms", "s", 0.005),
    ("90 deg", "rad", math.pi / 2),
    ("1 kg", "kg", 1.0),
    ("300 g", "kg", 0.3),
    ("2 N/mm", "N/mm", 2.0),
    ("1 m/s^2", "m/s^2", 1.0),
])
def test_exact_conversions(text, unit, expected):
    assert parse_quantity(text, unit, "f") == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("value", ["2", 2, 2.0, " 2 "])
def test_bare_number_needs_unit_and_names_field(value):
    with pytest.raises(UnitError, match=r"`n_gain` needs a unit"):
        parse_quantity(value, "N/m", "n_gain")


def test_bare_number_allowed_when_asked():
    assert parse_quantity("2000", "N/m", "stiffness", bare_ok=True) == 2000.0
    assert parse_quantity(0.3, "1", "mu_k") == 0.3  # dimensionless needs no unit


@pytest.mark.parametrize("text, match", [
    ("2 N/furlong", r"unknown unit 'furlong'"),
    ("2 N/", r"ends too early"),
    ("2 (N/mm", r"unbalanced"),
    ("two N", r"must be a number"),
    ("1e400 N", r"finite"),
    ("2 kN^999 / kN^998", r"unit power must be between -9 and 9 \(got '\^999' in 'kN\^999 / kN\^998'\)"),
    ("2 mN^-400 * mN^401", r"unit power must be between -9 and 9"),    # used to raise OverflowError
])
def test_bad_units(text, match):
    with pytest.raises(UnitError, match=match):
        parse_quantity(text, "N", "force")


def test_wrong_dimension_is_named():
    with pytest.raises(UnitError, match=r"`size` must be a length in m \(got '2 N', a force\)"):
        parse_quantity("2 N", "m", "size")


def test_unknown_unit_suggests_nearest():
    with pytest.raises(UnitError, match=r"did you mean 'mm'"):
        parse_quantity("2 mmm", "m", "width")


def test_pairs():
    assert parse_pair("60x4mm", "x", "m", "size") == pytest.approx((0.06, 0.004))
    assert parse_pair("0:2mm", ":", "m", "height") == pytest.approx((0.0, 0.002))
    assert parse_pair("1 cm x 20 mm", "x", "m", "size") == pytest.approx((0.01, 0.02))
    with pytest.raises(UnitError, match="`size` must look like"):
        parse_pair("60mm", "x", "m", "size")
    with pytest.raises(UnitError, match="needs a unit"):
        parse_pair("0:2", ":", "m", "height")


def test_parse_unit_dimensions():
    assert parse_unit("N/m") == (1.0, (0, 1, -2))
    scale, dim = parse_unit("mm/(N*s)")
    assert scale == pytest.approx(1e-3) and dim == (0, -1, 1)


def test_format_quantity():
    assert format_quantity(2000.0, "N/mm") == "2 N/mm"


@settings(max_examples=60, deadline=None)
@given(st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False),
       st.sampled_from([("mm", 1e-3), ("um", 1e-6), ("cm", 1e-2), ("m", 1.0)]))
def test_length_prefixes_scale_exactly(v, unit_scale):
    unit, scale = unit_scale
    assert parse_quantity(f"{v!r} {unit}", "m", "x") == pytest.approx(v * scale, rel=1e-12, abs=1e-300)


def test_byte_sizes_parse_with_units_and_ranges():
    from shapedisplay.units import parse_byte_size
    assert parse_byte_size("64 KiB", "memory") == 65536
    assert parse_byte_size("65536", "memory") == 65536
    assert parse_byte_size("1.5 kB", "memory") == 1500
    assert parse_byte_size("2 GiB", "memory", lo=1024, hi=2**31) == 2**31
    for bad, rule in (("12 parsecs", "a size like"), ("0.5 B", "a whole number"), ("nan B", "a size like|a whole"),
                      ("3 GiB", r"within 1 KiB\.\.2 GiB"), ("100 B", r"within 1 KiB\.\.2 GiB")):
        with pytest.raises(InputError, match=rf"`memory` must be ({rule})"):
            parse_byte_size(bad, "memory", lo=1024, hi=2**31)
