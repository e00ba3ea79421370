"""Signed channels keep zero exact: flat ground must not read as a slope."""
import numpy as np
from hypothesis import given, settings, strategies as st

from shapedisplay.table.model import choose_quantization


@settings(max_examples=200, deadline=None)
@given(lo=st.floats(-1e3, -1e-9), hi=st.floats(1e-9, 1e3), dtype=st.sampled_from(["uint8", "uint16"]))
def test_zero_decodes_exactly_and_bound_holds(lo, hi, dtype):
    v = np.concatenate([np.linspace(lo, hi, 257), [0.0]])
    q = choose_quantization(v, dtype)
    assert q.decode(q.encode(np.array([0.0])))[0] == 0.0
    assert np.max(np.abs(q.decode(q.encode(v)) - v)) <= q.max_error
    # the zero-aligned grid costs at most one code step of resolution
    top = np.iinfo(dtype).max
    assert q.max_error <= (hi - lo) / (top - 1)


def test_one_sided_range_uses_its_minimum():
    v = np.linspace(0.5, 3.0, 11)
    q = choose_quantization(v, "uint8")
    assert q.offset == 0.5 and q.decode(q.encode(v))[0] == 0.5
