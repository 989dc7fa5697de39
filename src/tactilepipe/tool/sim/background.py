"""A DIGIT's no-contact frame: the background every simulated frame of that sensor is drawn on.

The renderer (digit_render.py) draws a contact as a shading change on top of a real sensor's
no-contact frame, as tacto and Taxim do (see docs/digit_rendering.md for the choice and the
calibration). This module reads and checks that frame and measures what the renderer takes from
it: where each coloured LED sits (its light direction) and how bright each channel is locally
(how strongly a tilt of the gel changes it).

The project ships one real DIGIT frame (``assets/digit_background_240x320.jpg``, from the tacto
project, MIT licence: ``assets/LICENSE-tacto.txt`` beside it). ``simulate_tool.render.background``
names another sensor's frame instead (empty: the shipped one).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

from tactilepipe.core.errors import InputError
from tactilepipe.tool.formats.imagefile import read_image
from tactilepipe.tool.formats.native_layout import FRAME_H, FRAME_W

SHIPPED = Path(__file__).parent / "assets" / "digit_background_240x320.jpg"
MIN_SIDE = 120                  # px: the smallest frame (QQVGA) a background may be
MIN_MEAN, MAX_MEAN = 15.0, 240.0  # DN: a lit, unsaturated sensor
MIN_STD = 2.0                   # DN: a real gel frame has an LED layout, not a flat colour


def background_path(setting: str | None) -> Path:
    """The background frame ``simulate_tool.render.background`` names (empty or None: shipped)."""
    return Path(setting) if setting else SHIPPED


def to_portrait(img: np.ndarray) -> np.ndarray:
    """A landscape frame (as the DIGIT's camera streams it) transposed to the portrait layout
    digit-interface returns; a portrait frame as it is."""
    return np.ascontiguousarray(img.transpose(1, 0, 2)) if img.shape[1] > img.shape[0] else img


def check_background(img: np.ndarray, path: str | Path) -> np.ndarray:
    """``img`` as a (FRAME_H, FRAME_W, 3) float32 BGR background; InputError naming ``path``
    when it cannot be one (wrong channels, size or aspect, black, saturated or flat)."""
    what = "simulate_tool.render.background"
    if img.ndim != 3 or img.shape[2] != 3:
        channels = 1 if img.ndim == 2 else img.shape[2]
        raise InputError(path, f"{what} must be a 3-channel colour (BGR) frame; this one has {channels} channel(s)")
    if img.dtype != np.uint8:
        raise InputError(path, f"{what} must be 8-bit; this one is {img.dtype}")
    img = to_portrait(img)
    h, w = img.shape[:2]
    if w < MIN_SIDE or abs(h / w - FRAME_H / FRAME_W) > 0.02:
        raise InputError(path, f"{what} must be a DIGIT frame of 3:4 shape (e.g. {FRAME_W}x{FRAME_H} or "
                               f"{FRAME_H}x{FRAME_W}, at least {MIN_SIDE} px wide); this one is {w}x{h}")
    if (w, h) != (FRAME_W, FRAME_H):
        interp = cv2.INTER_AREA if w > FRAME_W else cv2.INTER_LINEAR
        img = cv2.resize(img, (FRAME_W, FRAME_H), interpolation=interp)
    img = img.astype(np.float32)
    mean, std = float(img.mean()), float(img.reshape(-1, 3).std(axis=0).max())
    if not MIN_MEAN <= mean <= MAX_MEAN:
        raise InputError(path, f"{what}: mean level {mean:.0f} DN is outside {MIN_MEAN:.0f}-{MAX_MEAN:.0f}: "
                               "not a lit, unsaturated sensor frame")
    if std < MIN_STD:
        raise InputError(path, f"{what}: the frame is flat (spatial std {std:.1f} DN): not a sensor's no-contact frame")
    return img


@lru_cache(maxsize=4)
def _load(path: str) -> np.ndarray:
    try:
        img = read_image(path, cv2.IMREAD_UNCHANGED)
    except InputError as exc:
        raise InputError(path, f"simulate_tool.render.background: {exc.problem}") from None
    return check_background(img, path)


def load_background(setting: str | None) -> np.ndarray:
    """The checked background frame (FRAME_H, FRAME_W, 3) float32 BGR (a read-only copy is cached)."""
    img = _load(str(background_path(setting)))
    img.flags.writeable = False
    return img


def led_azimuths(background: np.ndarray, smooth_px: float = 25.0) -> np.ndarray:
    """Image direction (rad, atan2(dy, dx) with y down) of the blue, green and red LEDs.

    Each LED floods the part of the gel nearest to it with its colour, so the centroid of where
    a channel exceeds the frame's mean colour points from the image centre towards that LED.
    """
    s = cv2.GaussianBlur(background, (0, 0), smooth_px)
    excess = np.maximum(s - s.mean(axis=2, keepdims=True), 0)
    h, w = s.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    out = []
    for c in range(3):
        wgt = excess[..., c]
        total = float(wgt.sum()) + 1e-6
        dx = float((wgt * (xx - w / 2)).sum()) / total
        dy = float((wgt * (yy - h / 2)).sum()) / total
        out.append(np.arctan2(dy, dx))
    return np.asarray(out)


def shading_level(background: np.ndarray, shape: tuple[int, int], smooth_px: float = 8.0) -> np.ndarray:
    """Local brightness (3, rows, cols) of each channel, smoothed and resized to ``shape``: the
    light a tilt of the gel redistributes (shading changes scale with it)."""
    s = cv2.GaussianBlur(background, (0, 0), smooth_px)
    small = cv2.resize(s, (shape[1], shape[0]), interpolation=cv2.INTER_AREA)
    return np.ascontiguousarray(small.transpose(2, 0, 1)).astype(np.float32)
