"""The tone a board study decodes stored values with (``--tone``): the option's forms, and each curve against its
analytic form."""
import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.evaluate.board.tone.values import POWER_RANGE, Tone, decode, parse_tone


@pytest.mark.parametrize("text, tone", [
    (None, Tone("stored")), ("stored", Tone("stored")), ("srgb", Tone("srgb")), ("SRGB", Tone("srgb")),
    ("power:2.2", Tone("power", power=2.2)), ("power:1", Tone("power", power=1.0)),
    ("auto", Tone("auto", method="erf4p_fixed11")), ("auto:canny_devernay", Tone("auto", method="canny_devernay")),
])
def test_each_form_of_the_option_parses_and_gives_back_its_text(text, tone):
    got = parse_tone(text)
    assert got == tone
    assert parse_tone(got.spec) == got


@pytest.mark.parametrize("text, says", [
    ("gamma", "unknown tone"), ("power", "must be a number"), ("power:x", "must be a number"),
    ("power:0.1", "from 0.4 to 3"), ("power:9", "from 0.4 to 3"), ("srgb:2", "unknown tone"),
])
def test_a_bad_tone_is_refused_naming_it(text, says):
    with pytest.raises(InputError, match=says) as exc:
        parse_tone(text)
    assert text in str(exc.value)


def test_stored_returns_the_stored_values_themselves():
    img = np.arange(12, dtype=np.uint8).reshape(3, 4)
    assert decode(img, Tone("stored"), 255.0) is img


def test_srgb_decodes_with_the_standards_curve():
    """IEC 61966-2-1: linear below 0.04045 (e / 12.92), ((e + 0.055) / 1.055) ** 2.4 above; white and black kept."""
    e = np.array([0.0, 0.02, 0.04045, 0.5, 0.8, 1.0])
    want = np.where(e <= 0.04045, e / 12.92, ((e + 0.055) / 1.055) ** 2.4)
    for full in (255.0, 65535.0, 1.0):
        assert np.allclose(decode(e * full, Tone("srgb"), full), want * full, rtol=1e-12, atol=0)
    assert decode(np.array([0.5 * 255]), Tone("srgb"), 255.0)[0] == pytest.approx(255 * 0.2140411404, rel=1e-9)


def test_a_power_decodes_on_the_full_scale_and_clips_outside_it():
    v = np.array([[0, 64, 128, 255]], dtype=np.uint8)
    got = decode(v, Tone("power", power=2.0), 255.0)
    assert got.dtype == np.float64
    assert np.allclose(got, 255.0 * (v / 255.0) ** 2, rtol=1e-14)
    assert np.allclose(decode(np.array([-3.0, 70000.0]), Tone("power", power=1.5), 65535.0), [0.0, 65535.0])
    assert POWER_RANGE == (0.4, 3.0)


def test_an_auto_tone_is_estimated_before_it_decodes():
    with pytest.raises(ValueError, match="estimated first"):
        decode(np.zeros((2, 2)), Tone("auto", method="erf4p_fixed11"), 255.0)
