"""Device profiles: bundled TOMLs with published parameters, and clear errors for bad files."""
import math

import pytest

from shapedisplay.table.devices import DeviceProfile, bundled_devices, load_device
from shapedisplay.errors import FileFormatError, InputError, ModelError, UnitError


def test_bundled_devices_load_and_validate():
    names = bundled_devices()
    assert {"handheld-stick", "desktop-rig", "linear-slider", "skin-stretch-tactor",
            "lateral-contactor"} <= set(names)
    for name in names:
        d = load_device(name)
        assert d.name == name
        assert DeviceProfile.from_json(d.to_json()) == d


def test_published_cursor_gains():
    assert load_device("handheld-stick").cursor_gain == pytest.approx(0.080)    # 80 mm/(N s)
    assert load_device("desktop-rig").cursor_gain == pytest.approx(0.316)       # 316 mm/(N s)


def test_published_konyo_pad():
    pad = load_device("desktop-rig").pad   # written with units: 2.0 N/mm, 1e-5 N*s/mm
    assert pad.stiffness == pytest.approx(2000.0) and pad.damping == pytest.approx(0.01)
    assert pad.mass == pytest.approx(1e-6)
    assert pad.omega_n == pytest.approx(math.sqrt(2e9))                       # ~4.47e4 rad/s
    assert pad.omega_n / (2 * math.pi) == pytest.approx(7118, rel=1e-3)       # ~7.1 kHz
    assert pad.zeta == pytest.approx(0.01 / (2 * math.sqrt(2000 * 1e-6)))    # ~0.11
    assert pad.zeta == pytest.approx(0.1118, abs=1e-4)


def test_skin_stretch_tactor_is_karnopp():
    d = load_device("skin-stretch-tactor")
    assert d.friction.mu_k == pytest.approx(0.9 * d.friction.mu_s)
    assert "skin_stretch" in d.outputs and d.skin_stretch_max == pytest.approx(0.75e-3)


def test_stribeck_contactor_parameters():
    d = load_device("lateral-contactor")
    assert (d.pad.mass, d.pad.stiffness, d.pad.damping) == (1e-4, 1e3, 1.0)
    assert (d.friction.mu_s, d.friction.mu_k) == (2.1, 1.4)
    assert d.extra["stribeck"]["a"] == 55.0 and d.extra["stribeck"]["b"] == 1.9


def _write(tmp_path, text):
    p = tmp_path / "dev.toml"
    p.write_text(text)
    return p


BASE = """
[device]
name = "t"
tick_rate = "1 kHz"
[pad]
mass = 1e-6
stiffness = 2000.0
damping = 0.01
"""


def test_mu_k_above_mu_s(tmp_path):
    p = _write(tmp_path, BASE + "[friction]\nmu_s = 0.5\nmu_k = 0.7\n")
    with pytest.raises(ModelError, match=r"`mu_k` must be <= `mu_s` \(got mu_k=0.7, mu_s=0.5\)"):
        load_device(p)


def test_unknown_key_suggests(tmp_path):
    p = _write(tmp_path, BASE + "[friction]\nmu_s = 0.5\nmu_kk = 0.3\n")
    with pytest.raises(InputError, match=r"unknown \[friction\] key 'mu_kk' \(did you mean 'mu_k'\?\)"):
        load_device(p)


def test_unknown_section_suggests(tmp_path):
    p = _write(tmp_path, BASE + "[frictoin]\nmu_s = 0.5\n")
    with pytest.raises(InputError, match=r"did you mean 'friction'"):
        load_device(p)


def test_bare_number_where_unit_required(tmp_path):
    p = _write(tmp_path, BASE.replace('"1 kHz"', "1000"))
    with pytest.raises(UnitError, match=r"`device.tick_rate` needs a unit"):
        load_device(p)


def test_unknown_unit_in_device(tmp_path):
    p = _write(tmp_path, BASE.replace('"1 kHz"', '"1 kHzz"'))
    with pytest.raises(UnitError, match=r"unknown unit 'kHzz'"):
        load_device(p)


def test_unknown_bundled_name_suggests():
    with pytest.raises(InputError, match=r"unknown device 'handheld-stik' \(did you mean 'handheld-stick'\?\)"):
        load_device("handheld-stik")


def test_missing_and_invalid_files(tmp_path):
    with pytest.raises(FileFormatError, match="no such file"):
        load_device(tmp_path / "nope.toml")
    p = _write(tmp_path, "[device\n")
    with pytest.raises(FileFormatError, match="invalid TOML"):
        load_device(p)


def test_negative_mass_rejected(tmp_path):
    p = _write(tmp_path, BASE.replace("mass = 1e-6", "mass = -1e-6"))
    with pytest.raises(ModelError, match=r"pad `mass` must be finite and > 0"):
        load_device(p)


def test_default_device_is_konyo():
    d = load_device(None)
    assert d.pad.stiffness == 2000.0 and d.burst.carrier_hz == 300.0
    assert d.burst.rise_s == 0.005 and d.burst.decay_s == 0.030


@pytest.mark.parametrize("text, match", [
    ('outputs = "burst"', r"`device.outputs` must be a list of names such as \[\"burst\"\] \(got 'burst'\)"),
    ("name = 5", r"`device.name` must be a string \(got 5\)"),
])
def test_device_keys_of_the_wrong_type(tmp_path, text, match):
    """A string for the outputs list used to be split into letters ("unknown output 'b'")."""
    p = _write(tmp_path, BASE.replace('name = "t"', text if text.startswith("name") else 'name = "t"\n' + text))
    with pytest.raises(InputError, match=match):
        load_device(p)


def test_section_that_is_not_a_table(tmp_path):
    p = _write(tmp_path, 'friction = "high"\n' + BASE)
    with pytest.raises(InputError, match=r"`friction` must be a \[friction\] table of keys \(got 'high'\)"):
        load_device(p)


def test_burst_carrier_below_nyquist(tmp_path):
    p = _write(tmp_path, BASE + '[burst]\ncarrier = "30 kHz"\n')
    with pytest.raises(InputError, match=r"burst `carrier` must be below half the audio rate, 24000 Hz "
                                         r"\(got carrier=30000 Hz, audio_rate=48000 Hz\)"):
        load_device(p)
