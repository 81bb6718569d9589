"""Analytic "room photos" of a ranging target: the failure modes of real phone photos, with exact truth.

A pinhole camera (no distortion) sees a planar target card at a known pose (depth 0.5-3 m, yaw and
pitch up to 45 degrees) in front of a wooden door, with what real photos hold around it: a printed
drawing, text and a filled blob inside a light sheet, a black square or disc printed on a white sheet,
a handle-like dark box, a tape-measure-like strip with ticks crossing the view, a second sheet, uneven
light (a gradient, vignetting and a soft shadow), Gaussian blur, noise, 8-bit rounding and JPEG.

Exactness: every outline that carries truth (the target's) is a polygon projected through the camera
and filled on a canvas ``SUPERSAMPLE`` times finer (``cv2.fillPoly`` with 4 fractional bits), blurred
there, and area-averaged to the output pixels, so a pixel's value is its coverage to 1/(16 ss)^2; the
truth is the projected corners (TL, TR, BR, BL) or the projected circle (720 points), in OpenCV
pixel coordinates, and the depth Z of the target's centre.  The prints and the background are
textures (no truth is read from them).  Fast: a 640 x 480 photo takes ~0.1 s.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

SUPERSAMPLE = 4
#: the kinds of target card: what is measured, its polarity, what surrounds it
KINDS = ("dark_square", "dark_circle", "light_sheet", "light_card")
DISTRACTORS = ("handle", "tape", "second_sheet", "shadow")


@dataclass
class RoomPhoto:
    """One photo's design (metres, degrees, pixels)."""

    kind: str = "dark_square"
    z_m: float = 1.0
    x_m: float = 0.0
    y_m: float = 0.0
    yaw_deg: float = 0.0
    pitch_deg: float = 0.0
    roll_deg: float = 0.0
    distractors: tuple = DISTRACTORS
    jpeg_quality: int | None = 85
    noise_dn: float = 1.5
    blur_px: float = 0.7
    light_gradient: float = 0.35
    width_px: int = 640
    height_px: int = 480
    fx_px: float = 800.0
    seed: int = 0
    extras: dict = field(default_factory=dict)

    @property
    def shape(self) -> str:
        return {"dark_square": "square", "dark_circle": "circle", "light_sheet": "rectangle",
                "light_card": "square"}[self.kind]

    @property
    def polarity(self) -> str:
        return "dark" if self.kind.startswith("dark") else "light"

    @property
    def size_m(self) -> tuple[float, float]:
        """(width, height) of the measured outline."""
        return {"dark_square": (0.13, 0.13), "dark_circle": (0.13, 0.13), "light_sheet": (0.297, 0.21),
                "light_card": (0.15, 0.15)}[self.kind]

    def K(self) -> np.ndarray:
        return np.array([[self.fx_px, 0, (self.width_px - 1) / 2], [0, self.fx_px, (self.height_px - 1) / 2],
                         [0, 0, 1.0]])


def rotation(yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """Card axes (u right, v down, normal) in the camera frame (x right, y down, z forward)."""
    a, b, c = np.radians([yaw_deg, pitch_deg, roll_deg])
    ry = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    rz = np.array([[np.cos(c), -np.sin(c), 0], [np.sin(c), np.cos(c), 0], [0, 0, 1]])
    return ry @ rx @ rz


def plane_homography(p: RoomPhoto) -> np.ndarray:
    """3x3 map from card-plane metres (u, v, 1) to output pixels (OpenCV convention)."""
    R = rotation(p.yaw_deg, p.pitch_deg, p.roll_deg)
    t = np.array([p.x_m, p.y_m, p.z_m])
    return p.K() @ np.column_stack([R[:, 0], R[:, 1], t])


def project(H: np.ndarray, uv: np.ndarray) -> np.ndarray:
    q = np.column_stack([uv, np.ones(len(uv))]) @ H.T
    return q[:, :2] / q[:, 2:3]


def _to_canvas(pts: np.ndarray, ss: int) -> np.ndarray:
    return (np.asarray(pts, float) + 0.5) * ss - 0.5


def _fill(canvas: np.ndarray, pts_px: np.ndarray, value: float, ss: int) -> None:
    """Fill a polygon given in output px into the supersampled canvas with 4 fractional bits."""
    q = np.round(_to_canvas(pts_px, ss) * 16).astype(np.int32).reshape(-1, 1, 2)
    cv2.fillPoly(canvas, [q], float(value), lineType=cv2.LINE_8, shift=4)


def _alpha(shape, pts_px: np.ndarray, ss: int) -> np.ndarray:
    a = np.zeros(shape, np.float32)
    _fill(a, pts_px, 1.0, ss)
    return a


def _rect(w: float, h: float, cu: float = 0.0, cv: float = 0.0) -> np.ndarray:
    return np.array([[cu - w / 2, cv - h / 2], [cu + w / 2, cv - h / 2], [cu + w / 2, cv + h / 2],
                     [cu - w / 2, cv + h / 2]])


def _circle(d: float, n: int = 720) -> np.ndarray:
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([d / 2 * np.cos(t), d / 2 * np.sin(t)])


def wood(shape, rng) -> np.ndarray:
    """A wood-grain door: vertical rings warped by low-frequency noise, knots of darker grain."""
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    low = cv2.resize(rng.normal(0, 1, (8, 8)).astype(np.float32), (w, h), interpolation=cv2.INTER_CUBIC)
    fine = cv2.GaussianBlur(rng.normal(0, 1, (h, w)).astype(np.float32), (0, 0), 1.5 * w / 640 + 0.5)
    period = w / rng.uniform(18, 30)
    phase = 2 * np.pi * (xx + 0.08 * w * low + 3 * np.sin(yy / (0.2 * h))) / period
    grain = 0.5 + 0.5 * np.sin(phase) ** 3
    return (95 + 35 * grain + 8 * fine * (w / 640) + 10 * low).astype(np.float32)


def _print_texture(kind: str, rng, res: int) -> tuple[np.ndarray, float, float]:
    """A light card's print: (texture 0-1 reflectance, width m, height m) at ``res`` px per metre."""
    w_m, h_m = (0.297, 0.21) if kind == "light_sheet" else (0.15, 0.15)
    tw, th = int(w_m * res), int(h_m * res)
    tex = np.full((th, tw), 219, np.uint8)  # reflectance 0.86 (x 255: OpenCV draws text on 8-bit images)
    mx, my = int(0.12 * tw), int(0.12 * th)
    for _ in range(int(rng.integers(4, 9))):  # pen strokes of a drawing
        pts = np.column_stack([rng.integers(mx, tw - mx, 5), rng.integers(my, th - my, 5)]).astype(np.int32)
        cv2.polylines(tex, [pts.reshape(-1, 1, 2)], False, 30, thickness=max(1, res // 250))
    bx, by = int(rng.integers(mx, tw // 2)), int(rng.integers(my, th // 2))
    cv2.rectangle(tex, (bx, by), (bx + int(0.22 * tw), by + int(0.16 * th)), 25, -1)  # a filled blob (a logo)
    cv2.putText(tex, "EDGE 13cm", (mx, th - my), cv2.FONT_HERSHEY_SIMPLEX, res / 900 * (w_m / 0.3), 38,
                max(1, res // 300))
    return tex.astype(np.float32) / 255.0, w_m, h_m


def _warp_onto(canvas: np.ndarray, tex: np.ndarray, H_px: np.ndarray, w_m: float, h_m: float, ss: int,
               outline_px: np.ndarray, scale: float) -> None:
    """Composite a plane texture (reflectance x ``scale``) into the canvas inside its projected outline."""
    th, tw = tex.shape
    # texture px -> plane metres -> output px -> canvas px
    T = np.array([[w_m / tw, 0, -w_m / 2 + 0.5 * w_m / tw], [0, h_m / th, -h_m / 2 + 0.5 * h_m / th], [0, 0, 1]])
    C = np.array([[ss, 0, 0.5 * ss - 0.5], [0, ss, 0.5 * ss - 0.5], [0, 0, 1]])
    M = C @ H_px @ T
    warped = cv2.warpPerspective(tex, M, (canvas.shape[1], canvas.shape[0]), flags=cv2.INTER_LINEAR,
                                 borderMode=cv2.BORDER_REPLICATE)
    a = _alpha(canvas.shape, outline_px, ss)
    canvas[:] = canvas * (1 - a) + a * warped * scale


def render_room_photo(p: RoomPhoto) -> tuple[np.ndarray, dict]:
    """(8-bit gray image after the JPEG round trip if any, truth dict) of one design."""
    rng = np.random.default_rng(p.seed)
    ss = SUPERSAMPLE
    W, H = p.width_px, p.height_px
    shape = (H * ss, W * ss)
    canvas = cv2.resize(wood((H, W), rng), (W * ss, H * ss), interpolation=cv2.INTER_LINEAR)
    Hp = plane_homography(p)
    white = 225.0
    card_w, card_h = (0.21, 0.297)  # the white sheet a dark target is printed on (A4 portrait)
    card = _rect(card_w, card_h) if p.kind.startswith("dark") else _rect(*p.size_m)
    if "second_sheet" in p.distractors:  # a second light sheet (A5 portrait) beside the card, clear of it
        side = 1 if p.x_m <= 0 else -1
        own = project(Hp, card)
        z2, y2, roll2 = p.z_m * rng.uniform(1.0, 1.3), p.y_m + rng.uniform(-0.1, 0.1) * p.z_m, rng.uniform(-8, 8)
        for gap in np.arange(0.3, 1.5, 0.05):
            sec = RoomPhoto(z_m=z2, x_m=p.x_m + side * gap * p.z_m, y_m=y2, roll_deg=roll2, width_px=W, height_px=H,
                            fx_px=p.fx_px)
            poly = project(plane_homography(sec), _rect(0.148, 0.21))
            gap_px = poly[:, 0].min() - own[:, 0].max() if side > 0 else own[:, 0].min() - poly[:, 0].max()
            if gap_px > 0.03 * W:
                break
        _fill(canvas, poly, white * 0.95, ss)
    if p.kind.startswith("dark"):
        _fill(canvas, project(Hp, card), white, ss)
        outline = _rect(0.13, 0.13) if p.kind == "dark_square" else _circle(0.13)
        _fill(canvas, project(Hp, outline), 22.0, ss)
    else:
        tex, w_m, h_m = _print_texture(p.kind, rng, 1600)
        outline = _rect(w_m, h_m)
        _warp_onto(canvas, tex, Hp, w_m, h_m, ss, project(Hp, outline), white / 0.86)
    truth_px = project(Hp, outline)
    if "tape" in p.distractors:  # a tape measure lying across the view, clear of the target
        box = truth_px
        y_clear = float(box[:, 1].max()) + rng.uniform(0.06, 0.15) * H
        if y_clear > 0.9 * H:
            y_clear = float(box[:, 1].min()) - rng.uniform(0.06, 0.15) * H
        t0, t1 = np.array([-10.0, y_clear + 0.05 * H]), np.array([W + 10.0, y_clear - 0.05 * H])
        d = (t1 - t0) / np.linalg.norm(t1 - t0)
        n = np.array([-d[1], d[0]]) * 0.012 * W
        _fill(canvas, np.array([t0 - n, t1 - n, t1 + n, t0 + n]), 175.0, ss)
        for k in np.linspace(0, 1, 40)[1:-1]:
            c = t0 + k * (t1 - t0)
            cv2.line(canvas, tuple(np.round(_to_canvas(c - 0.8 * n, ss)).astype(int)),
                     tuple(np.round(_to_canvas(c, ss)).astype(int)), 40.0, max(1, ss // 2))
    if "handle" in p.distractors:  # a dark door handle with a highlight beside the target
        bx = float(truth_px[:, 0].max()) + 0.05 * W if p.x_m <= 0 else float(truth_px[:, 0].min()) - 0.2 * W
        by = float(truth_px[:, 1].mean())
        if 0.02 * W < bx < 0.8 * W:
            hw, hh = 0.17 * W, 0.035 * W
            _fill(canvas, _rect(hw, hh, bx + hw / 2, by), 35.0, ss)
            _fill(canvas, _rect(hw * 0.9, hh * 0.2, bx + hw / 2, by - hh * 0.2), 160.0, ss)
            _fill(canvas, _rect(0.05 * W, 0.16 * W, bx + 0.03 * W, by + 0.02 * W), 45.0, ss)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    ang = rng.uniform(0, 2 * np.pi)
    light = 1 - p.light_gradient * (0.5 + 0.5 * ((xx / W - 0.5) * np.cos(ang) + (yy / H - 0.5) * np.sin(ang)) * 1.4)
    light *= 1 - 0.25 * (((xx - W / 2) / W) ** 2 + ((yy - H / 2) / H) ** 2)
    if "shadow" in p.distractors:  # a soft shadow falling across part of the target
        c = truth_px.mean(axis=0) + rng.normal(0, 0.15, 2) * np.ptp(truth_px, axis=0)
        r = 0.6 * float(np.ptp(truth_px[:, 0]))
        light *= 1 - 0.3 * np.exp(-(((xx - c[0]) ** 2 + (yy - c[1]) ** 2) / (2 * r * r)))
    img = cv2.GaussianBlur(canvas, (0, 0), p.blur_px * ss)
    img = cv2.resize(img, (W, H), interpolation=cv2.INTER_AREA) * light
    img = img + rng.normal(0, p.noise_dn, img.shape) + rng.normal(0, 0.02, img.shape) * np.sqrt(np.maximum(img, 0))
    img = np.clip(np.round(img), 0, 255).astype(np.uint8)
    if p.jpeg_quality:
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(p.jpeg_quality)])
        img = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
    w_m, h_m = p.size_m
    truth = {"kind": p.kind, "shape": p.shape, "polarity": p.polarity, "size_m": w_m,
             "height_m": h_m if p.shape == "rectangle" else None, "true_distance_m": p.z_m, "fx_px": p.fx_px,
             "K": p.K().tolist(), "outline_px": truth_px.tolist(),
             "design": {k: getattr(p, k) for k in ("x_m", "y_m", "yaw_deg", "pitch_deg", "roll_deg",
                                                   "jpeg_quality", "noise_dn", "blur_px", "seed")}
             | {"distractors": list(p.distractors)}}
    return img, truth


def hard_set(n: int = 64, seed: int = 0, width_px: int = 640, height_px: int = 480,
             jpeg: bool = True) -> list[RoomPhoto]:
    """``n`` designs cycling through the kinds, distances 50-300 cm (light sheets from 75 cm, so they fit),
    yaw and pitch up to 45 degrees, both polarities, every distractor (each left out in a quarter)."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        kind = KINDS[k % len(KINDS)]
        zmin = 0.75 if kind == "light_sheet" else 0.5
        z = float(zmin + (3.0 - zmin) * ((k * 0.618034) % 1.0))
        tilt = 45.0 * ((k * 0.414214) % 1.0)
        az = rng.uniform(0, 2 * np.pi)
        yaw, pitch = tilt * np.cos(az), tilt * np.sin(az)
        lat = 0.25 * z * max(0.0, 1.0 - 0.3 / z)
        dis = tuple(d for j, d in enumerate(DISTRACTORS) if (k // len(KINDS) + j) % 4 != 0)
        out.append(RoomPhoto(kind=kind, z_m=round(z, 3), x_m=float(rng.uniform(-lat, lat) * 0.5),
                             y_m=float(rng.uniform(-lat, lat) * 0.3), yaw_deg=float(yaw), pitch_deg=float(pitch),
                             roll_deg=float(rng.uniform(-10, 10)), distractors=dis,
                             jpeg_quality=int(rng.integers(75, 95)) if jpeg else None,
                             width_px=width_px, height_px=height_px, seed=seed * 1000 + k))
    return out
