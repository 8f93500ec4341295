"""A ReSTIR GI image stream carried to another resolution of the same view.

The viewport renders a still view coarse first and then finer (restir_addon's
viewport/progress.py). Starting each finer resolution from empty reservoirs
and running means would throw away what the coarse frames learnt: the
samples in the reservoirs, and each pixel's mean light. Here every pixel of
the new resolution takes the state of the pixel of the old one that covers
its centre (nearest neighbour): its G-buffer history, its reservoirs, its
running means and the per-pixel flags. The next frame then reprojects that
history onto itself (the camera did not move); where the nearest old pixel
saw another surface (edges), the normal and depth tests of temporal.py and
accumulation.py reject it and the pixel starts over.

A coarse pixel's mean stands for the light over its whole footprint: at the
finer resolution it is blurred across edges and texture. Its weight in the
running mean is therefore capped at ``carry`` frames, so the finer frames
take over within a few frames while the image keeps its level and most of
its smoothness from the first finer frame on.
"""

from dataclasses import fields, replace

import numpy as np

from ..util.rows import gather
from .accumulation import restart

CARRY_FRAMES = 2    # frames of history a resized running mean counts as at most: its
                    # blocks are blurred across edges (the viewport's MSE at 10 s after the
                    # step to 1/2: 4 frames 239, 2 206; bench/viewport_refine.py --clock)


def nearest_rows(old_width, old_height, width, height):
    """(width * height,) int64: the row (y * old_width + x) of the old
    image's pixel under the centre of each pixel of the new one (both
    images span the same view)."""
    x = ((np.arange(width, dtype=np.float64) + 0.5) * (old_width / width)).astype(np.int64)
    y = ((np.arange(height, dtype=np.float64) + 0.5) * (old_height / height)).astype(np.int64)
    x = np.minimum(x, old_width - 1)
    y = np.minimum(y, old_height - 1)
    return (y[:, None] * old_width + x[None, :]).ravel()


def _rows(obj, index, n_old):
    """A copy of a dataclass (reservoirs, running means) with every array
    field of n_old rows gathered at index; other fields as they are."""
    if obj is None:
        return None
    changes = {}
    for f in fields(obj):
        value = getattr(obj, f.name)
        if isinstance(value, np.ndarray) and value.ndim >= 1 and len(value) == n_old:
            changes[f.name] = gather(value, index)
    return replace(obj, **changes)


def resize_history(history, width, height, carry=CARRY_FRAMES):
    """The FrameHistory ``history`` carried to a width x height image of the
    same view (a new object; ``history`` is left as it was). None stays None."""
    if history is None:
        return None
    if (history.width, history.height) == (width, height):
        return history
    n_old = history.width * history.height
    index = nearest_rows(history.width, history.height, width, height)
    temporal = _rows(history.temporal, index, n_old)
    spatial = temporal if history.spatial is history.temporal else _rows(history.spatial, index, n_old)
    changes = {"temporal": temporal, "spatial": spatial}
    for name in ("p", "n", "ng", "depth", "valid", "object_id", "noise_hold", "visibility", "sky_share",
                 "temporal_owner", "spatial_owner"):
        value = getattr(history, name)
        changes[name] = None if value is None else gather(value, index)
    acc = _rows(history.accumulation, index, n_old)
    if acc is not None:
        restart(acc, carry)
    changes["accumulation"] = acc
    signature = (width, height) + tuple(history.signature[2:])
    return replace(history, width=width, height=height, signature=signature, **changes)


def resize_stream(restir, width, height, carry=CARRY_FRAMES):
    """Carry a ReSTIRGI's state (its history) to a width x height image of
    the same view, in place; the next render_frame at that size goes on
    from it instead of starting over."""
    restir.history = resize_history(restir.history, width, height, carry)


def upscale_bilinear(image, width, height):
    """(height, width, C) bilinear resize of an image (H, W, C) of the same
    view, pixel centres aligned and edges clamped (as a linearly filtered
    texture is drawn); float32."""
    h, w = image.shape[:2]
    image = np.asarray(image, np.float32)
    if (h, w) == (height, width):
        return image.copy()

    def axis(n_new, n_old):
        s = np.clip((np.arange(n_new, dtype=np.float64) + 0.5) * (n_old / n_new) - 0.5, 0.0, n_old - 1)
        i0 = np.minimum(s.astype(np.int64), max(n_old - 2, 0))
        i1 = np.minimum(i0 + 1, n_old - 1)
        return i0, i1, (s - i0).astype(np.float32)

    x0, x1, fx = axis(width, w)
    y0, y1, fy = axis(height, h)
    fx, fy = fx[None, :, None], fy[:, None, None]
    top = image[y0][:, x0] * (1 - fx) + image[y0][:, x1] * fx
    bottom = image[y1][:, x0] * (1 - fx) + image[y1][:, x1] * fx
    return (top * (1 - fy) + bottom * fy).astype(np.float32)


def resize_image(image, width, height):
    """(height, width, ...) nearest-neighbour resize of a whole image
    (H, W, ...) of the same view."""
    old_h, old_w = image.shape[:2]
    index = nearest_rows(old_w, old_h, width, height)
    flat = image.reshape(old_h * old_w, *image.shape[2:])
    return gather(flat, index).reshape(height, width, *image.shape[2:])
