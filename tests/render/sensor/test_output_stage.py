"""The output stage of a video camera and a palette file (edgetruth.render.sensor.pipeline), against analytic forms.

- fewer levels: the levels are round(255 k / (N - 1)) (the 3-3-2 palette's 0, 36, 73, ..., 255 and 0, 85, 170,
  255); without dither each pixel goes to its nearest level;
- Floyd-Steinberg: the wavefront implementation equals the pixel-by-pixel loop of the definition exactly; it
  keeps the mean (a flat field, and every 16 x 16 block of a ramp, to 0.1 of a level step); on an RGB palette
  the gray is the rounded BT.601 luma of the channels, each the gray times its gain;
- sharpening: the unsharp mask of a step has the analytic overshoot a (1 - Phi(1/sigma)) ... (sampled Gaussian:
  computed here from the kernel) and keeps a flat field;
- gain, offset and output noise: e -> g e + o / 255, noise of the stated SD (measured to 2 %), drawn only when on;
- off (the defaults): the same pixels as before, no random numbers drawn, nothing new in the identity or the JSON.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from edgetruth.errors import InputError
from edgetruth.render.sensor import pipeline
from edgetruth.render.sensor.linear_model import SensorModel, make_rng, sensor_from_dict


def _reference_fs(v: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """Floyd-Steinberg by its definition: pixel by pixel, raster order."""
    v = np.array(v, float)
    h, w = v.shape
    out = np.empty_like(v)
    for y in range(h):
        for x in range(w):
            q = pipeline.nearest_level(np.array([v[y, x]]), levels)[0]
            e = v[y, x] - q
            out[y, x] = q
            if x + 1 < w:
                v[y, x + 1] += e * 7 / 16
            if y + 1 < h:
                if x > 0:
                    v[y + 1, x - 1] += e * 3 / 16
                v[y + 1, x] += e * 5 / 16
                if x + 1 < w:
                    v[y + 1, x + 1] += e * 1 / 16
    return out


def test_levels_are_the_palette_levels():
    assert pipeline.even_levels(8).tolist() == [0, 36, 73, 109, 146, 182, 219, 255]
    assert pipeline.even_levels(4).tolist() == [0, 85, 170, 255]
    lv = pipeline.even_levels(5)
    v = np.linspace(0, 255, 1001)
    q = pipeline.nearest_level(v, lv)
    assert np.all(np.abs(v - q) <= np.min(np.abs(v[:, None] - lv[None, :]), axis=1) + 1e-12)


def test_floyd_steinberg_equals_its_definition_and_keeps_the_mean():
    rng = np.random.default_rng(3)
    img = rng.uniform(0, 255, (19, 31))
    lv = pipeline.even_levels(8)
    np.testing.assert_array_equal(pipeline.floyd_steinberg(img[None], [lv])[0], _reference_fs(img, lv))
    flat = np.full((64, 96), 100.3)
    out = pipeline.floyd_steinberg(flat[None], [lv])[0]
    assert set(np.unique(out)) <= set(lv) and len(np.unique(out)) == 2  # 73 and 109
    assert abs(out[:-4, :-4].mean() - 100.3) < 0.1 * 36  # the error leaving the last row/column aside
    ramp = np.tile(np.linspace(10, 245, 128), (128, 1))
    out = pipeline.floyd_steinberg(ramp[None], [lv])[0]
    blocks = lambda a: a[:112, :112].reshape(7, 16, 7, 16).mean(axis=(1, 3))  # noqa: E731
    assert np.max(np.abs(blocks(out) - blocks(ramp))) < 0.1 * 36


def test_rgb_palette_gray_is_the_luma_of_the_channels():
    s = SensorModel(output="srgb8", output_levels_rgb=(8, 8, 4), output_rgb_gains=(1.07, 1.0, 0.85),
                    output_dither="floyd_steinberg")
    flat = np.full((48, 64), 200, np.uint8)
    out = pipeline.quantise(flat, s)
    chans = [pipeline.floyd_steinberg(np.clip(g * flat.astype(float), 0, 255)[None], [pipeline.even_levels(n)])[0]
             for g, n in zip((1.07, 1.0, 0.85), (8, 8, 4))]
    want = np.clip(np.rint(0.299 * chans[0] + 0.587 * chans[1] + 0.114 * chans[2]), 0, 255)
    np.testing.assert_array_equal(out, want)
    assert abs(out[:-4, :-4].mean() - (0.299 * 1.07 + 0.587 + 0.114 * 0.85) * 200) < 2.0
    # without dither: every pixel the luma of the nearest levels
    nd = pipeline.quantise(flat, replace(s, output_dither="none"))
    assert len(np.unique(nd)) == 1


def test_sharpening_overshoot_matches_the_kernel():
    """A step through e + a (e - G*e): the first pixel past the step rises by a * (sum of the kernel's weights
    beyond it), computed from the sampled Gaussian; a flat field is unchanged."""
    a, sigma = 1.5, 1.0
    step = np.zeros((4, 40))
    step[:, 20:] = 0.5
    step += 0.25
    out = pipeline.sharpen(step, a, sigma, "x")
    r = int(5 * sigma + 0.5)
    j = np.arange(-r, r + 1)
    g = np.exp(-0.5 * (j / sigma) ** 2)
    g /= g.sum()
    blurred_at_20 = 0.25 + 0.5 * g[j >= 0].sum()  # the pixel at 20 sees the step from offset 0 on
    assert out[0, 20] == pytest.approx(0.75 + a * (0.75 - blurred_at_20), abs=1e-12)
    assert np.allclose(pipeline.sharpen(np.full((5, 9), 0.4), a, sigma, "xy"), 0.4)
    assert np.allclose(out[:, :10], 0.25) and np.allclose(out[:, 30:], 0.75)  # far from the step: unchanged
    assert np.allclose(pipeline.sharpen(step.T, a, sigma, "x"), step.T)  # along x only


def test_gain_offset_and_output_noise():
    raw = np.full((200, 300), 256 + 2000, np.uint16)  # a flat field
    base = SensorModel(output="srgb8")
    e = pipeline.srgb_encode((2000) / (4095 - 256))
    s = replace(base, output_gain=1.2, output_offset_dn=-10.0)
    out = pipeline.develop(raw, s)
    assert np.all(out == np.rint(255 * (1.2 * e) - 10.0))
    noisy = pipeline.develop(raw, replace(base, output_noise_dn=6.0), np.random.default_rng(1)).astype(float)
    assert noisy.std() == pytest.approx(np.sqrt(36 + 1 / 12), rel=0.02)
    assert abs(noisy.mean() - 255 * e) < 0.1
    with pytest.raises(ValueError):
        pipeline.develop(raw, replace(base, output_noise_dn=6.0))


def test_off_changes_nothing():
    """Defaults: the pixels of the old pipeline, no random numbers drawn, no new key in identity or JSON."""
    rng_img = np.random.default_rng(0)
    raw = rng_img.integers(256, 4095, (40, 50)).astype(np.uint16)
    s = SensorModel(output="srgb8")
    v = (raw.astype(float) - 256) / (4095 - 256)
    assert np.array_equal(pipeline.develop(raw, s, None), np.rint(255 * pipeline.srgb_encode(v)).astype(np.uint8))
    r1, r2 = make_rng(5, 2), make_rng(5, 2)
    pipeline.develop(raw, s, r1)
    assert r1.random() == r2.random()  # nothing drawn
    for k in ("output_levels", "output_levels_rgb", "output_rgb_gains", "output_dither", "output_gain",
              "output_offset_dn", "sharpen_amount", "sharpen_sigma_px", "sharpen_axis", "output_noise_dn",
              "output_gamma", "output_clip_dn"):
        assert k not in s.identity() and k not in s.to_dict()
    assert not {"quantisation", "video", "transfer_curve", "clip_dn"} & set(pipeline.describe(s))
    on = replace(s, output_levels_rgb=(8, 8, 4), output_dither="floyd_steinberg", sharpen_amount=1.0)
    assert on.identity()["output_levels_rgb"] == (8, 8, 4) and on.identity()["sharpen_amount"] == 1.0
    assert pipeline.describe(on)["quantisation"]["rgb_levels"][2] == [0, 85, 170, 255]


def test_output_gamma_is_a_pure_power_of_the_linear_signal():
    """output_gamma G: e = v^(1/G) instead of the sRGB curve (G = 1: stored values linear in light), and the board
    study's --tone power:G decodes it back to within the 8-bit rounding."""
    from edgetruth.evaluate.board.tone.values import decode, parse_tone

    s = SensorModel(output="srgb8")
    raw = np.tile(np.linspace(s.dark_offset_dn, s.max_dn, 512).astype(np.uint16), (2, 1))
    v = (raw - s.dark_offset_dn) / (s.max_dn - s.dark_offset_dn)
    for g in (1.0, 1.8, 2.2):
        out = pipeline.develop(raw, replace(s, output_gamma=g))
        assert np.array_equal(out, np.rint(255 * v ** (1 / g)).astype(np.uint8))
        back = decode(out.astype(float), parse_tone(f"power:{g}"), 255.0) / 255.0
        # within half an 8-bit step of the curve, read on the encoded axis
        assert np.all(np.abs(back ** (1 / g) - v ** (1 / g)) <= 0.5 / 255 + 1e-12)
    assert pipeline.describe(replace(s, output_gamma=1.0))["transfer_curve"]["gamma"] == 1.0
    assert replace(s, output_gamma=1.0).identity()["output_gamma"] == 1.0


def test_output_clip_flattens_the_white_below_255():
    """output_clip_dn c: every value that would exceed c is c, after the output noise (so the clipped flat has no
    noise), and nothing below c moves."""
    raw = np.full((200, 300), 256 + 3000, np.uint16)
    s = SensorModel(output="srgb8", output_noise_dn=3.0)
    free = pipeline.develop(raw, s, np.random.default_rng(2)).astype(float)
    clipped = pipeline.develop(raw, replace(s, output_clip_dn=220.0), np.random.default_rng(2)).astype(float)
    assert free.std() > 2.5 and free.min() >= 210 and free.mean() > 225
    assert np.all(clipped == np.minimum(free, 220.0)) and np.mean(clipped == 220.0) > 0.9
    ramp = np.tile(np.linspace(256, 4095, 400).astype(np.uint16), (3, 1))
    a = pipeline.develop(ramp, SensorModel(output="srgb8"))
    b = pipeline.develop(ramp, SensorModel(output="srgb8", output_clip_dn=200.0))
    assert np.array_equal(b, np.minimum(a, 200)) and b.max() == 200
    assert pipeline.describe(SensorModel(output="srgb8", output_clip_dn=200.0))["clip_dn"]["value"] == 200.0


def test_capture_draws_output_noise_after_the_exposure():
    """With output_noise_dn the exposure's own noise is unchanged (its numbers come first)."""
    from edgetruth.render.optics.camera import load_camera
    from edgetruth.render.sensor.capture import capture

    cam = load_camera()
    rad = np.full((32, 48), 0.2, np.float32)
    s = SensorModel(output="srgb8")
    a, _ = capture(rad, cam, s, make_rng(9, 2))
    b, truth = capture(rad, cam, replace(s, output_noise_dn=3.0), make_rng(9, 2))
    assert not np.array_equal(a, b) and truth["image"]["video"]["output_noise_dn"] == 3.0
    raw_a = s.expose(rad, cam.f_number, cam.pitch_um, make_rng(9, 2))
    raw_b = replace(s, output_noise_dn=3.0).expose(rad, cam.f_number, cam.pitch_um, make_rng(9, 2))
    assert np.array_equal(raw_a, raw_b)


@pytest.mark.parametrize("table, fix", [
    ({"output_levels": 1}, "output_levels"),
    ({"output_levels_rgb": [8, 8, 3.5]}, "output_levels_rgb"),
    ({"output_levels": 8, "output_levels_rgb": [8, 8, 4]}, "both set"),
    ({"output_dither": "floyd_steinberg"}, "needs output_levels"),
    ({"output_levels": 8, "output": "raw"}, "8-bit output"),
    ({"sharpen_amount": 1.0, "output": "raw"}, "encoded output"),
    ({"output_rgb_gains": [1.1, 1.0, 0.9]}, "applies to output_levels_rgb"),
    ({"sharpen_axis": "z"}, "sharpen_axis"),
    ({"output_gamma": 0.1}, "output_gamma"),
    ({"output_gamma": 1.0, "output": "raw"}, "8-bit output"),
    ({"output_clip_dn": 300}, "output_clip_dn"),
])
def test_bad_keys_are_one_line_errors(table, fix):
    with pytest.raises(InputError, match=fix):
        sensor_from_dict({"output": "srgb8", **table} if "output" not in table else table)
