"""Film: running sums of per-pixel samples, their mean and variance, and the
image files the tools write (PNG through zlib, EXR through OpenEXR).

Images are (height, width, channels) float32 with row 0 at the bottom, as
Blender's render result stores them; files are written top row first.
"""

import struct
import zlib

import numpy as np

from ..util.vectors import luminance


class Film:
    """Accumulates passes of one sample per pixel for a width x height image."""

    def __init__(self, width, height):
        self.width, self.height = int(width), int(height)
        n = self.width * self.height
        self.count = 0
        self.sum = np.zeros((n, 3), np.float64)
        self.sum_lum2 = np.zeros(n, np.float64)
        self.aov_sum = {}

    def add(self, color, **aovs):
        color = np.nan_to_num(np.asarray(color, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
        self.sum += color
        self.sum_lum2 += luminance(color) ** 2
        for name, value in aovs.items():
            prev = self.aov_sum.get(name)
            value = np.asarray(value, np.float64)
            self.aov_sum[name] = value.copy() if prev is None else prev + value
        self.count += 1

    def mean(self):
        """(H, W, 3) float32 mean colour; black before the first sample."""
        m = self.sum / max(self.count, 1)
        return m.reshape(self.height, self.width, 3).astype(np.float32)

    def aov(self, name, channels):
        value = self.aov_sum.get(name)
        if value is None:
            return np.zeros((self.height, self.width, channels), np.float32)
        return (value / max(self.count, 1)).reshape(self.height, self.width, channels).astype(np.float32)

    def variance_of_mean(self):
        """(H, W) estimated variance of the mean luminance per pixel."""
        c = max(self.count, 1)
        mean = luminance(self.sum / c)
        var = np.maximum(self.sum_lum2 / c - mean ** 2, 0.0) / max(c - 1, 1)
        return var.reshape(self.height, self.width).astype(np.float32)


def to_rgba(rgb, alpha=1.0):
    """(H, W, 3) -> (H, W, 4) float32 with non-finite values replaced by 0."""
    rgb = np.nan_to_num(np.asarray(rgb, np.float32), nan=0.0, posinf=0.0, neginf=0.0)
    a = np.broadcast_to(np.asarray(alpha, np.float32), rgb.shape[:2] + (1,))
    return np.concatenate([rgb, a], axis=2)


def srgb_encode(linear):
    x = np.clip(np.asarray(linear, np.float32), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def write_png(path, linear_rgb):
    """8-bit sRGB PNG of a linear (H, W, 3) image, bottom row first in memory."""
    img = (srgb_encode(linear_rgb)[::-1] * 255.0 + 0.5).astype(np.uint8)
    h, w = img.shape[:2]
    raw = b"".join(b"\x00" + img[y].tobytes() for y in range(h))

    def chunk(tag, data):
        body = tag + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)))
        f.write(chunk(b"IDAT", zlib.compress(raw, 6)))
        f.write(chunk(b"IEND", b""))


def write_exr(path, linear_rgb):
    """32-bit float RGB EXR (linear), bottom row first in memory."""
    import OpenEXR  # noqa: PLC0415 (loaded for EXR files only)
    img = np.ascontiguousarray(np.asarray(linear_rgb, np.float32)[::-1])
    channels = {"RGB": img}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, channels) as f:
        f.write(str(path))


def read_exr(path):
    """(H, W, 3) float32, bottom row first, from an EXR written by us or by Blender
    (single-part RGB(A), or the Combined pass of a multilayer file)."""
    import OpenEXR  # noqa: PLC0415
    with OpenEXR.File(str(path), separate_channels=True) as f:
        for part in f.parts:
            ch = part.channels
            names = list(ch)
            for prefix in ("", "ViewLayer.Combined.", "Combined."):
                keys = [prefix + c for c in "RGB"]
                if all(k in ch for k in keys):
                    img = np.stack([ch[k].pixels for k in keys], axis=2).astype(np.float32)
                    return img[::-1].copy()
            if "RGB" in ch:
                return np.asarray(ch["RGB"].pixels, np.float32)[::-1].copy()
            if "RGBA" in ch:
                return np.asarray(ch["RGBA"].pixels, np.float32)[::-1, :, :3].copy()
            del names
    raise ValueError(f"no RGB channels in {path}")
