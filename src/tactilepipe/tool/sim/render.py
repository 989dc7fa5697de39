"""Gel height field -> a DIGIT-looking frame (portrait QVGA, 240 wide x 320 high, BGR uint8).

Optics and gel model (docs/digit_rendering.md), all numbers from ``render`` parameters:
- Geometry: the camera sees the gel at ``px_per_mm`` (~17 px/mm at QVGA, so the view is about
  14 x 19 mm). Image x runs across the pad (pad coordinate u), image y down the finger towards
  the fingertip (pad coordinate z points up, towards the palm). The two DIGITs face each other,
  so the right-hand sensor sees u mirrored.
- Height field: the handle pressed into the gel along a contact line. Indentation depth along
  the line comes from the mechanics (simulate.py); across it the handle's cross-section
  (cylinder of radius R, or a flat band with rounded edges for a flat handle) sets the profile
  h = max(0, depth(s) - gap(d)), gap(d) = max(0, |d| - w/2)^2 / (2R), so the contact half-width
  is b = sqrt(2 R depth) (= sqrt(4 q R / (pi E*)) with the line-load law depth = 2q / (pi E*)).
  The handle's surface texture (flutes, knurl, ribs, wood grain) is extra gap where the grooves
  are, so it shows only where the handle touches. The butt end of the handle is rounded.
  Computed at reduced resolution (``height_downsample``) and upsampled after shading.
- Gel softening (Taxim style): repeated Gaussian blurs with the contact region re-imposed
  (h <- max(blur(h), h_contact)), then saturation at the gel's depth limit
  h_max * tanh(h / h_max).
- Shear: the gel surface sticks to the handle; the surface displacement (a smooth field, equal
  to the handle's tangential displacement on the contact and decaying away from it) moves the
  height field (``cv2.remap``). The LED illumination does not move.
- Background: a real DIGIT's no-contact frame (digit_background.py; the shipped one or the
  sensor's own), as tacto and Taxim draw on one. Each simulated unit moves it by a few whole
  pixels and gives each channel its own small gain and offset, so two fingers are not identical.
- Shading: normals from Sobel gradients; three coloured LEDs around the gel, each lighting every
  pixel from its own direction at a grazing elevation:
  I_c = bg_c + sum_l m_cl k_l(x) (n . L_l(x) - n0 . L_l(x)), with the LED directions measured on
  the background (where its colour floods the gel) and k_l(x) = shading_gain x the background's
  local level in the LED's channel (a tilt redistributes the light that is there); m_cl: a small
  crosstalk into the other channels. Static gel blemishes (tiny bumps) move with the gel surface.
- Camera: the background already holds one frozen draw of the camera's noise; each frame adds
  Gaussian noise of its own (sigma per sensor, per channel; a precomputed bank of noise frames,
  sampled with random offsets per frame, keeps rendering fast and deterministic), small
  per-frame LED gain jitter and a slow background drift (given by the caller per frame).

Everything is float32 with cv2 for blur / Sobel / remap / resize; ``Renderer.render`` runs at
several hundred QVGA frames per second on one core.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from tactilepipe.core.errors import ArgumentError
from tactilepipe.tool.sim.background import led_azimuths, load_background, shading_level
from tactilepipe.tool.formats.native_layout import FRAME_H, FRAME_W

TEXTURES = ("none", "flutes", "knurl", "ribs", "grain")
LUT_SIZE = 1024                         # resolution of the along-line lookup tables


@dataclass(frozen=True)
class Grid:
    """Pixel grid of the (reduced-resolution) height field, in pad millimetres."""
    px_per_mm: float = 17.0
    down: int = 2
    margin: int = 24            # reduced pixels of gel simulated beyond each image edge (shear moves it in)
    coarse: int = 4             # the smooth shear field is computed on a grid this much coarser

    @property
    def h(self) -> int:
        return FRAME_H // self.down

    @property
    def w(self) -> int:
        return FRAME_W // self.down

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) of the height field including the margin."""
        return self.h + 2 * self.margin, self.w + 2 * self.margin

    @property
    def mm_per_px(self) -> float:
        """Size of one reduced-resolution pixel in mm."""
        return self.down / self.px_per_mm

    @property
    def half_width_mm(self) -> float:
        return FRAME_W / 2 / self.px_per_mm

    @property
    def half_height_mm(self) -> float:
        return FRAME_H / 2 / self.px_per_mm

    @property
    def coarse_shape(self) -> tuple[int, int]:
        rows, cols = self.shape
        return rows // self.coarse, cols // self.coarse

    def coarse_pixels(self) -> tuple[np.ndarray, np.ndarray]:
        """Reduced-pixel coordinates (x, y) of the coarse grid's nodes."""
        rows, cols = self.coarse_shape
        f = self.coarse
        return (np.arange(cols) + 0.5) * f - 0.5, (np.arange(rows) + 0.5) * f - 0.5

    def pad_coords(self, mirror: bool, coarse: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """(u, z) in mm of every reduced pixel centre (margin included), or of the coarse grid's
        nodes; origin at the image centre, z up."""
        if coarse:
            px, py = self.coarse_pixels()
        else:
            px, py = np.arange(self.shape[1], dtype=float), np.arange(self.shape[0], dtype=float)
        x = (px - self.margin + 0.5) * self.down
        y = (py - self.margin + 0.5) * self.down
        u = (x - FRAME_W / 2) / self.px_per_mm
        if mirror:
            u = -u
        z = (FRAME_H / 2 - y) / self.px_per_mm
        uu, zz = np.meshgrid(u, z)
        return uu.astype(np.float32), zz.astype(np.float32)


@dataclass(frozen=True)
class HandleProfile:
    """Cross-section and surface of the part of the tool that touches the gel."""
    radius_mm: float                    # radius of curvature across the contact
    flat_width_mm: float = 0.0          # flat band (flat-ish handles); 0 for round handles
    end_radius_mm: float = 4.0          # rounding of the butt end
    texture: str = "none"
    texture_period_mm: float = 2.0
    texture_depth_mm: float = 0.0

    def __post_init__(self):
        if self.texture not in TEXTURES:
            raise ArgumentError(f"texture '{self.texture}' must be one of {TEXTURES}")


def _texture_gap(profile: HandleProfile, s: np.ndarray, d: np.ndarray, roll: float,
                 rng: np.random.Generator) -> np.ndarray:
    """Depth (mm) of the handle's grooves at along-axis s, across-axis d (0 on the ridges)."""
    a, p = profile.texture_depth_mm, profile.texture_period_mm
    if profile.texture == "none" or a <= 0:
        return np.zeros_like(s)
    r = max(profile.radius_mm, 1e-3)
    # arc length around the handle for round handles (the surface wraps away from the gel)
    arc = r * np.arcsin(np.clip(d / r, -1, 1)) if profile.flat_width_mm == 0 else d
    arc = arc + roll * r
    if profile.texture == "flutes":         # grooves along the axis, evenly around the handle
        g = (0.5 + 0.5 * np.cos(2 * np.pi * arc / p)) ** 6
    elif profile.texture == "ribs":         # grooves around the handle, evenly along it
        g = (0.5 + 0.5 * np.cos(2 * np.pi * (s + roll) / p)) ** 6
    elif profile.texture == "knurl":        # two crossed helical groove sets
        g1 = (0.5 + 0.5 * np.cos(2 * np.pi * (s + arc) / p)) ** 8
        g2 = (0.5 + 0.5 * np.cos(2 * np.pi * (s - arc) / p)) ** 8
        g = np.maximum(g1, g2)
    else:                                   # wood grain: fine lines along the axis, slowly wandering
        g = np.zeros_like(s)
        for k in range(6):
            fd = rng.uniform(0.6, 1.6) / p
            fs = rng.uniform(0.02, 0.12) / p
            g += rng.uniform(0.5, 1.0) * np.cos(2 * np.pi * (fd * arc + fs * s) + rng.uniform(0, 2 * np.pi))
        g = np.clip(g / 3.0, 0, 1) ** 2
    return (a * g).astype(np.float32)


class LineContact:
    """Precomputed geometry of one handle contact line on one pad (reduced resolution).

    The line starts at the butt end ``butt_uz`` (pad mm) and runs along the unit vector
    ``axis_uz`` towards the tool tip; s is the distance along it from the butt, d across it.
    Per frame the caller gives per-sample indentation depths and tangential displacements at the
    along-line positions ``s_k`` (increasing).
    """

    def __init__(self, grid: Grid, mirror: bool, butt_uz, axis_uz, s_k: np.ndarray,
                 profile: HandleProfile, roll: float, rng: np.random.Generator,
                 drag_sigma_mm: float = 2.5):
        self.grid, self.mirror = grid, mirror
        a = np.asarray(axis_uz, np.float64)
        a = a / np.linalg.norm(a)
        perp = np.array([-a[1], a[0]])

        def line_coords(coarse: bool):
            uu, zz = grid.pad_coords(mirror, coarse)
            du, dz = uu - butt_uz[0], zz - butt_uz[1]
            return (du * a[0] + dz * a[1]).astype(np.float32), (du * perp[0] + dz * perp[1]).astype(np.float32)

        s, d = line_coords(False)
        r, re_ = profile.radius_mm, profile.end_radius_mm
        across = np.maximum(np.abs(d) - profile.flat_width_mm / 2, 0) ** 2 / (2 * r)
        # the handle ends at the butt (s = 0) with its edge rounded over the last end_radius mm
        x = np.clip(re_ - s, 0, re_)
        butt = re_ - np.sqrt(np.maximum(re_ ** 2 - x ** 2, 0))
        self.gap = (across + butt + _texture_gap(profile, s, d, roll, rng)).astype(np.float32)
        self.gap[s < 0] = np.float32(1e3)
        self.s_k = np.asarray(s_k, np.float64)
        lo, hi = float(s.min()), float(s.max())
        self.lut_s = np.linspace(lo, hi, LUT_SIZE)
        self.lut_idx = np.clip(np.rint((s - lo) / (hi - lo) * (LUT_SIZE - 1)), 0, LUT_SIZE - 1).astype(np.intp)
        # the shear field on the coarse grid: how strongly the gel surface follows the handle,
        # 1 on the contact band, Gaussian decay away from it
        sc, dc = line_coords(True)
        self.lut_idx_coarse = np.clip(np.rint((sc - lo) / (hi - lo) * (LUT_SIZE - 1)), 0,
                                      LUT_SIZE - 1).astype(np.intp)
        band = profile.flat_width_mm / 2 + 0.5 * r
        w = np.exp(-np.maximum(np.abs(dc) - band, 0) ** 2 / (2 * drag_sigma_mm ** 2))
        w *= np.exp(-np.maximum(-sc, 0) ** 2 / (2 * drag_sigma_mm ** 2))
        self.drag = w.astype(np.float32)
        scale = 1.0 / grid.mm_per_px                 # mm -> reduced pixels
        self.px_u = np.float32(-scale if mirror else scale)
        self.px_z = np.float32(-scale)               # image y runs down, pad z up

    def _along(self, values: np.ndarray, coarse: bool = False) -> np.ndarray:
        table = np.interp(self.lut_s, self.s_k, values).astype(np.float32)
        return table[self.lut_idx_coarse if coarse else self.lut_idx]

    def height(self, depth_k: np.ndarray) -> np.ndarray:
        """Raw indentation (mm, >= 0) for per-sample depths ``depth_k`` (before softening)."""
        h = self._along(np.maximum(depth_k, 0.0)) - self.gap
        return np.maximum(h, 0, out=h)

    def displacement(self, du_k: np.ndarray, dz_k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Gel surface displacement (dx, dy) in reduced image pixels, on the coarse grid, for
        per-sample tangential displacements (mm) along the line."""
        dx = self._along(du_k, True) * self.drag * self.px_u
        dy = self._along(dz_k, True) * self.drag * self.px_z
        return dx, dy


@dataclass
class DigitLook:
    """One DIGIT's appearance (fixed for a session): background, LED fields, noise, blemishes."""
    background: np.ndarray      # (H, W, 3) float32 BGR, full resolution
    light_a: np.ndarray         # (3, h, w) float32: -k_l(x) L_x of each LED at each reduced pixel
    light_b: np.ndarray         # (3, h, w) float32: -k_l(x) L_y
    light_c: np.ndarray         # (3, h, w) float32: k_l(x) L_z   (k_l: DN per unit of n.L change)
    colour: np.ndarray          # (3, 3) float32: BGR share of each LED's light (row per channel)
    blemish: np.ndarray         # grid.shape float32 mm: static bumps on the gel surface
    noise_std: np.ndarray       # (3,) DN per channel (B, G, R), added to what the background holds


def sensor_background(rng: np.random.Generator, cfg: dict, frame: np.ndarray) -> np.ndarray:
    """This sensor's no-contact frame: the real one moved by a few whole pixels (the gel and the
    camera sit a little differently in every unit; whole pixels keep its grain and noise as they
    are), with a per-channel LED gain and a small offset of its own."""
    m = int(cfg["background_shift_px"])
    dx, dy = (int(v) for v in rng.integers(-m, m + 1, 2)) if m > 0 else (0, 0)
    bg = frame
    if dx or dy:
        shift = np.float32([[1, 0, dx], [0, 1, dy]])
        bg = cv2.warpAffine(frame, shift, (FRAME_W, FRAME_H), flags=cv2.INTER_NEAREST,
                            borderMode=cv2.BORDER_REFLECT_101)
    gain = 1.0 + cfg["background_gain_jitter"] * rng.standard_normal(3)
    offset = cfg["background_jitter_dn"] * rng.standard_normal(3)
    return (bg * gain.astype(np.float32) + offset.astype(np.float32)).astype(np.float32)


def make_look(rng: np.random.Generator, cfg: dict, grid: Grid, frame: np.ndarray | None = None) -> DigitLook:
    """Draw one sensor's look from the ``render`` parameters and a real no-contact ``frame``
    (float32 BGR, default: the one ``cfg["background"]`` names); per-sensor variations included."""
    if frame is None:
        frame = load_background(cfg["background"])
    bg = sensor_background(rng, cfg, frame)
    # LED directions from the layout of the colours; shading strength from the local level of
    # each channel (a tilt of the gel moves that much light), both per sensor
    azimuths = led_azimuths(bg) + np.deg2rad(rng.normal(0, 2.0, 3))
    level = shading_level(bg, (grid.h, grid.w))
    xs = (np.arange(grid.w) + 0.5) * grid.down
    ys = (np.arange(grid.h) + 0.5) * grid.down
    gx, gy = np.meshgrid(xs, ys)
    elev = np.deg2rad(cfg["light_elevation_deg"])
    dist = cfg["led_distance_px"] * rng.uniform(0.95, 1.05, 3)
    gain = float(cfg["shading_gain"]) * rng.uniform(0.95, 1.05, 3)
    la, lb, lc = [], [], []
    for k in range(3):                          # the blue, green and red LED
        lx = FRAME_W / 2 + dist[k] * np.cos(azimuths[k])
        ly = FRAME_H / 2 + dist[k] * np.sin(azimuths[k])
        vx, vy = lx - gx, ly - gy
        norm = np.hypot(vx, vy) + 1e-6
        L = np.stack([vx / norm * np.sin(elev), vy / norm * np.sin(elev), np.full_like(vx, np.cos(elev))])
        strength = gain[k] * level[k]
        la.append(-strength * L[0]), lb.append(-strength * L[1]), lc.append(strength * L[2])
    x = float(cfg["led_crosstalk"])
    colour = np.full((3, 3), x, np.float32)
    np.fill_diagonal(colour, 1.0)
    # blemishes: dust and tiny bumps on the gel surface (move with the gel)
    blemish = np.zeros(grid.shape, np.float32)
    by, bx = np.mgrid[0:grid.shape[0], 0:grid.shape[1]].astype(np.float32)
    n_spots = int(rng.integers(cfg["blemish_count"][0], cfg["blemish_count"][1] + 1))
    for _ in range(n_spots):
        px, py = rng.uniform(0, grid.shape[1]), rng.uniform(0, grid.shape[0])
        s = rng.uniform(0.6, 2.0)
        amp = rng.uniform(-1, 1) * cfg["blemish_height_mm"]
        blemish += amp * np.exp(-((bx - px) ** 2 + (by - py) ** 2) / (2 * s ** 2))
    lo, hi = cfg["noise_std_dn"]
    noise = rng.uniform(lo, hi) * np.asarray(cfg["noise_channel_scale"], np.float32)
    return DigitLook(background=bg, light_a=np.asarray(la, np.float32),
                     light_b=np.asarray(lb, np.float32), light_c=np.asarray(lc, np.float32),
                     colour=colour, blemish=blemish, noise_std=noise.astype(np.float32))


class Renderer:
    """Renders frames of one sensor: soften -> saturate -> shear remap -> shade -> camera."""

    NOISE_PAD = 16

    def __init__(self, look: DigitLook, grid: Grid, cfg: dict, rng: np.random.Generator,
                 noise_bank: int = 3):
        self.look, self.grid = look, grid
        self.h_max = float(cfg["h_max_mm"])
        self.blur_sigma = float(cfg["soften_sigma_mm"]) / grid.mm_per_px
        k = 2 * int(np.ceil(3 * self.blur_sigma)) + 1
        self.blur_ksize = (k, k)
        self.blur_iter = int(cfg["soften_iterations"])
        self.grad_scale = np.float32(1.0 / (8.0 * grid.mm_per_px))
        rows, cols = grid.shape
        xs, ys = np.meshgrid(np.arange(cols, dtype=np.float32), np.arange(rows, dtype=np.float32))
        self.base = cv2.merge([xs, ys])
        cx, cy = grid.coarse_pixels()
        self.base_coarse = cv2.merge([a.astype(np.float32) for a in np.meshgrid(cx, cy)])
        m = grid.margin
        self.crop = (slice(m, m + grid.h), slice(m, m + grid.w))
        p = self.NOISE_PAD
        std = np.broadcast_to(np.asarray(look.noise_std, np.float32), (3,))
        self.noise = (rng.standard_normal((noise_bank, FRAME_H + p, FRAME_W + p, 3), dtype=np.float32)
                      * std) if std.max() > 0 else None

    def inverse_map(self, disp: tuple[np.ndarray, np.ndarray], iterations: int = 3) -> np.ndarray:
        """Where each output pixel comes from: x_src = x - u(x_src), by fixed-point iteration on
        the coarse grid (u is given at the material points; shifts reach a few mm), then
        upsampled. Returns an (rows, cols, 2) float32 map for cv2.remap."""
        u = cv2.merge(disp)
        f = np.float32(self.grid.coarse)
        u_src = u
        for _ in range(iterations):
            pos = (self.base_coarse - u_src + np.float32(0.5)) / f - np.float32(0.5)
            u_src = cv2.remap(u, pos, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        rows, cols = self.grid.shape
        return self.base - cv2.resize(u_src, (cols, rows), interpolation=cv2.INTER_LINEAR)

    def gel_height(self, h_raw: np.ndarray) -> np.ndarray:
        """Softened and saturated gel indentation (mm) from the raw contact height."""
        h = h_raw
        for _ in range(self.blur_iter):
            h = np.maximum(cv2.GaussianBlur(h, self.blur_ksize, self.blur_sigma), h_raw)
        return (self.h_max * np.tanh(h / self.h_max)).astype(np.float32)

    def shading(self, h: np.ndarray) -> np.ndarray:
        """Colour change (h, w, 3) float32 DN of the LED shading for gel height ``h`` (mm)."""
        gx = cv2.Sobel(h, cv2.CV_32F, 1, 0, ksize=3) * self.grad_scale
        gy = cv2.Sobel(h, cv2.CV_32F, 0, 1, ksize=3) * self.grad_scale
        inv = 1.0 / np.sqrt(1.0 + gx * gx + gy * gy)
        gx *= inv
        gy *= inv
        inv -= 1.0
        lk = self.look
        # k_l (n.L_l - n0.L_l) = k_l (-L_x gx - L_y gy + L_z) / |(gx, gy, 1)| - k_l L_z, per LED
        dots = [lk.light_a[k] * gx + lk.light_b[k] * gy + lk.light_c[k] * inv for k in range(3)]
        return cv2.transform(cv2.merge(dots), lk.colour)

    def render(self, h_raw: np.ndarray | None, disp: tuple[np.ndarray, np.ndarray] | None = None,
               gain: np.ndarray | None = None, offset: np.ndarray | None = None,
               rng: np.random.Generator | None = None) -> np.ndarray:
        """One frame (FRAME_H, FRAME_W, 3) uint8 BGR.

        h_raw: raw contact height (reduced resolution, gel-material coordinates) or None (no
        contact); disp: gel surface displacement (dx, dy) in reduced pixels; gain: per-channel
        LED gain; offset: per-channel DN added (background drift); rng: camera noise draw
        (None: no noise).
        """
        if h_raw is None:
            h = self.look.blemish
        else:
            h = self.gel_height(h_raw) + self.look.blemish
        if disp is not None:
            h = cv2.remap(h, self.inverse_map(disp), None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        h = np.ascontiguousarray(h[self.crop])
        img = cv2.resize(self.shading(h), (FRAME_W, FRAME_H), interpolation=cv2.INTER_LINEAR)
        if gain is None:
            cv2.add(img, self.look.background, dst=img)
        else:
            cv2.add(img, cv2.multiply(self.look.background, _scalar(gain)), dst=img)
        if offset is not None:
            cv2.add(img, _scalar(offset), dst=img)
        if rng is not None and self.noise is not None:
            k = int(rng.integers(len(self.noise)))
            oy, ox = rng.integers(0, self.NOISE_PAD, 2)
            patch = self.noise[k, oy:oy + FRAME_H, ox:ox + FRAME_W]
            if rng.integers(2):
                cv2.add(img, patch, dst=img)
            else:
                cv2.subtract(img, patch, dst=img)
        cv2.max(img, 0.0, dst=img)
        return cv2.convertScaleAbs(img)          # rounds to nearest and saturates at 255


def _scalar(values) -> tuple[float, float, float, float]:
    v = [float(x) for x in values]
    return (v[0], v[1], v[2], 0.0)
