"""Blender images to core ImageSets (core/materials/texture.py), each read once per export.

``ImageCache.key(image)`` registers an image and returns a plain string key;
every node using the image shares the one ImageSet. What Blender hands over
(bpy 5.0) and what is done with it:
- Pixels come from ``Image.pixels.foreach_get`` into one float32 buffer, rows
  bottom to top. Byte images arrive as byte / 255, straight alpha, still in
  their colour space; they are kept as uint8 (4 bytes per texel): "sRGB" is
  decoded after filtering (as Cycles does), Non-Color and Linear Rec.709 are
  read raw, other linear spaces raw with a warning (primaries are not
  converted) and any other space as sRGB with a warning. Float images arrive
  scene-linear and premultiplied (Blender premultiplies float buffers on load
  except Non-Color and "Channel Packed" ones) and are kept as float32 (16
  bytes per texel). ``alpha_mode`` and Non-Color decide the storage and the
  un-premultiplying, as in Cycles (see core/materials/texture.py).
- UDIM (source 'TILED'): ``Image.pixels`` reads only the first tile. The
  others are read from a temporary copy of the image whose leading tiles are
  removed one at a time. The copy reloads tiles from their files, packed data
  or generator settings, so unsaved paint on tiles after the first is not
  seen (warned when the image has unsaved changes).
- Image sequences: the frame Cycles would use (scene frame through the node's
  image user: start, cyclic, offset) is loaded from its file as a temporary
  image. Movies cannot be read through bpy: magenta with a warning.
- Missing files, unreadable or empty images: Cycles' 1 x 1 magenta, with a
  warning naming the image and its file.
- Large images: a long side above ``max_size`` (8192) is halved until it fits
  (Cycles' texture-limit rule) by averaging boxes of texels (``shrink``, a
  box filter) from the pixels as they are, unsaved paint included, with a
  warning giving both sizes. Bands of rows are averaged at a time: the only
  full-size array is the one read.
- Temporary images (sequence frames, UDIM copies) are named ``TEMPORARY``
  (a leading dot hides them in Blender's lists) and removed after reading,
  except while a final render runs (``rendering()``, or a render job in the
  UI): removing a datablock then makes Blender 5.2 crash in the depsgraph
  update of the next frame of an animation with Persistent Data. They are
  kept, their pixels freed, until ``sweep()`` removes them once no render
  runs (a timer of the engine in the UI, or the next read outside a render).
  The user's images are never modified.
"""

import os
import re
from contextlib import contextmanager

import bpy
import numpy as np

from ...core.materials.texture import ImageSet, from_pixels, magenta

MAX_SIZE = 8192

SRGB_SPACES = {"sRGB"}
LINEAR_SPACES = {"Linear Rec.709", "Working Space", "Linear", "scene_linear"}
OTHER_LINEAR_SPACES = {"Linear Rec.2020", "ACEScg", "ACES2065-1", "Linear CIE-XYZ D65",
                       "Linear CIE-XYZ E", "Linear DCI-P3 D65", "Linear FilmLight E-Gamut"}
NONE_KEY = "<no image>"
TEMPORARY = ".restir_gi temporary"

_renders = 0            # final renders running in this process (rendering())
_kept = False           # temporary images wait for sweep()
SWEEP_INTERVAL = 2.0    # seconds between the engine's timer calls of sweep()


@contextmanager
def rendering():
    """Marks a final render: temporary images made meanwhile are kept until
    it ends (the engine's render() runs inside it)."""
    global _renders
    _renders += 1
    try:
        yield
    finally:
        _renders -= 1


def _removal_safe():
    """No final render runs: neither one of this process's (rendering()) nor a
    render job of the UI (whose depsgraph a viewport read must not disturb)."""
    return _renders == 0 and not bpy.app.is_job_running("RENDER")


def _temporaries():
    return [im for im in bpy.data.images
            if im.name.startswith(TEMPORARY) and im.users == 0 and im.library is None]


def sweep():
    """Remove the temporary images kept during renders, once none runs. The
    engine runs it from a timer on the UI's main thread (never from a render
    thread), and reads outside renders run it first. Returns the timer's
    next interval."""
    global _kept
    if _kept and _removal_safe():
        _kept = False
        for im in _temporaries():
            bpy.data.images.remove(im)
    return SWEEP_INTERVAL


def _discard(image):
    """Remove a temporary image now, or keep it (pixels freed) for sweep()."""
    global _kept
    if _removal_safe():
        bpy.data.images.remove(image)
        return
    image.buffers_free()
    _kept = True


def shrink(pixels, width, height):
    """(H, W, C) pixels averaged down to (height, width, C): each output texel
    the mean of its box of input texels (whole texels; box sizes differ by at
    most one). Bands of output rows are made one at a time."""
    h, w = pixels.shape[:2]
    ey = (np.arange(height + 1) * h) // height
    ex = (np.arange(width + 1) * w) // width
    wx = (1.0 / np.diff(ex)).astype(np.float32)[:, None]
    out = np.empty((height, width) + pixels.shape[2:], np.float32)
    for j0 in range(0, height, 256):
        j1 = min(j0 + 256, height)
        rows = np.add.reduceat(pixels[ey[j0]:ey[j1]], ey[j0:j1] - ey[j0], axis=0)
        rows *= (1.0 / np.diff(ey[j0:j1 + 1])).astype(np.float32)[:, None, None]
        out[j0:j1] = np.add.reduceat(rows, ex[:-1], axis=1) * wx
    return out


def sequence_frame(image_user, scene_frame):
    """The file frame of an image sequence at scene_frame, Blender's rule: frame
    scene_frame - start + 1 of a sequence of ``frame_duration`` frames, wrapped
    when cyclic, else held at 0 .. duration, then shifted by ``frame_offset``."""
    length = image_user.frame_duration
    if length == 0:
        return 0
    frame = scene_frame - image_user.frame_start + 1
    if image_user.use_cyclic:
        frame %= length
        if frame == 0:
            frame = length
    frame = min(max(frame, 0), length)
    return frame + image_user.frame_offset


def sequence_path(path, frame):
    """path with the last group of digits in its file name replaced by frame,
    zero-padded to the same width (how Blender numbers sequence files)."""
    head, name = os.path.split(path)
    match = None
    for match in re.finditer(r"\d+", name):
        pass
    if match is None:
        return path
    digits = match.group(0)
    name = name[:match.start()] + str(frame).zfill(len(digits)) + name[match.end():]
    return os.path.join(head, name)


def tile_path(path, number):
    """A UDIM tile's file: <UDIM> -> 1002, <UVTILE> -> u2_v1 (Blender's tokens)."""
    u, v = (number - 1001) % 10, (number - 1001) // 10
    return path.replace("<UDIM>", f"{number:04d}").replace("<UVTILE>", f"u{u + 1}_v{v + 1}")


def _abspath(image, path=None):
    return bpy.path.abspath(image.filepath_raw if path is None else path, library=image.library)


class ImageCache:
    """Reads each bpy image once per export into core ImageSets shared by every
    node that uses it. warn(text) reports a problem (the exporter keeps each
    distinct text once); max_size bounds the long side of what is stored."""

    def __init__(self, warn, max_size=MAX_SIZE):
        self.warn = warn
        self.max_size = int(max_size)
        self._sets = {}
        self.frame = 1          # the scene frame, which picks an image sequence's file

    @property
    def images(self):
        """key -> ImageSet, for the core scene."""
        return self._sets

    def get(self, key):
        return self._sets[key]

    def key(self, image, image_user=None, scene_frame=1):
        """Register a bpy.types.Image (or None: magenta, as Cycles renders a
        texture node without an image) and return its key. image_user and
        scene_frame choose the frame of an image sequence."""
        if image is None:
            if NONE_KEY not in self._sets:
                self.warn("A texture node has no image; it renders magenta")
                self._sets[NONE_KEY] = magenta(NONE_KEY)
            return NONE_KEY
        image = getattr(image, "original", None) or image
        key = image.name_full
        frame = None
        if image.source == "SEQUENCE":
            frame = sequence_frame(image_user, scene_frame) if image_user is not None else 1
            key = f"{key}@{frame}"
        if key not in self._sets:
            sweep()
            self._sets[key] = self._read(image, frame)
        return key

    # --- reading ---------------------------------------------------------------

    def _read(self, image, frame):
        name = image.name_full
        if image.source == "TILED":
            return self._read_tiled(image)
        if image.source == "SEQUENCE":
            path = sequence_path(_abspath(image), frame)
            return ImageSet.single(self._read_file(image, path, f"{name} (frame {frame})"))
        if image.source == "MOVIE":
            self.warn(f"Image '{name}': movie textures are not supported; it renders magenta")
            return magenta(name)
        if image.source == "VIEWER" or image.type in ("RENDER_RESULT", "COMPOSITING"):
            self.warn(f"Image '{name}': render results and viewer images are not supported; "
                      "it renders magenta")
            return magenta(name)
        return ImageSet.single(self._read_image(image, name))

    def _read_tiled(self, image):
        name = image.name_full
        numbers = [t.number for t in image.tiles]
        path = _abspath(image) if image.filepath_raw else ""
        tiles = {numbers[0]: self._read_image(image, f"{name} tile {numbers[0]}",
                                              tile_path(path, numbers[0]))}
        if len(numbers) > 1:
            if image.is_dirty:
                self.warn(f"Image '{name}': unsaved changes to UDIM tiles after {numbers[0]} "
                          "are not rendered; save the image")
            copy = image.copy()
            copy.name = TEMPORARY
            try:
                for n in numbers[1:]:
                    copy.tiles.remove(copy.tiles[0])
                    tiles[n] = self._read_image(copy, f"{name} tile {n}", tile_path(path, n))
            finally:
                _discard(copy)
        return ImageSet(tiles, tiled=True, name=name)

    def _read_file(self, like, path, label):
        """An image file loaded as a temporary image with like's colour settings."""
        if not os.path.isfile(path):
            self.warn(f"Image '{label}': cannot read '{path}'; it renders magenta")
            return from_pixels(np.zeros((0, 0, 4), np.float32), label)
        tmp = bpy.data.images.load(path, check_existing=False)
        tmp.name = TEMPORARY
        try:
            tmp.colorspace_settings.name = like.colorspace_settings.name
            tmp.alpha_mode = like.alpha_mode
            return self._read_image(tmp, label, path)
        finally:
            _discard(tmp)

    def _read_image(self, image, label, path=None):
        """The first (or only) tile's pixels as a core Image (magenta on failure);
        path names the file in warnings."""
        pixels = self._pixels(image)
        if pixels is None:
            path = path or (_abspath(image) if image.filepath_raw else "")
            where = f"cannot read '{path}'" if path else "has no pixels"
            self.warn(f"Image '{label}': {where}; it renders magenta")
            return from_pixels(np.zeros((0, 0, 4), np.float32), label)
        h, w = pixels.shape[:2]
        scale = 1.0
        while max(w, h) * scale > self.max_size:
            scale *= 0.5
        if scale < 1.0:
            w2, h2 = max(1, int(w * scale)), max(1, int(h * scale))
            self.warn(f"Image '{label}': {w} x {h} is larger than {self.max_size}; "
                      f"rendering it at {w2} x {h2}")
            pixels = shrink(pixels, w2, h2)
        return self._to_core(image, pixels, label)

    @staticmethod
    def _pixels(image):
        """(H, W, C) float32 from Image.pixels, or None if there are none."""
        n = len(image.pixels)
        w, h = image.size
        if n == 0 or w * h == 0 or n % (w * h):
            return None
        buf = np.empty(n, np.float32)
        image.pixels.foreach_get(buf)
        return buf.reshape(h, w, n // (w * h))

    def _to_core(self, image, pixels, label):
        settings = image.colorspace_settings
        space = settings.name
        data = bool(getattr(settings, "is_data", False)) or space == "Non-Color"
        alpha = image.alpha_mode
        if image.is_float:
            premultiplied = not data and alpha in ("STRAIGHT", "PREMUL")
            return from_pixels(pixels, label, alpha=alpha, data=data,
                               premultiplied=premultiplied, warn=self.warn, copy=False)
        srgb = False
        if not data and space not in LINEAR_SPACES:
            if space in OTHER_LINEAR_SPACES:
                self.warn(f"Image '{label}': colour space '{space}' is read as Linear Rec.709 "
                          "(its primaries are not converted)")
            else:
                srgb = True
                if space not in SRGB_SPACES:
                    self.warn(f"Image '{label}': colour space '{space}' is not supported; "
                              "reading it as sRGB")
        np.multiply(pixels, 255.0, out=pixels)
        np.rint(pixels, out=pixels)
        return from_pixels(pixels.astype(np.uint8), label, alpha=alpha, data=data, srgb=srgb,
                           warn=self.warn, copy=False)
