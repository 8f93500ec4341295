"""Image textures: texels stored as Cycles stores them, looked up as Cycles does.

Storage (``Image``). Texels are an (H, W, 4) RGBA array, row 0 the BOTTOM row
(v = 0), as Blender's ``Image.pixels`` and Cycles keep them. Two kinds:
- float32, linear (float images): 16 bytes per texel;
- uint8 (byte images): 4 bytes per texel, decoded as byte / 255 at lookup and,
  when ``encoding == "srgb"``, linearised only AFTER filtering. Cycles keeps
  8-bit sRGB images that way ("compress as sRGB") and so filters in sRGB
  space; doing the same makes Linear and Cubic lookups match it, not just
  Closest ones. Any float array may carry ``encoding="srgb"`` too.
Non-finite texels are replaced at construction, as Cycles does when it loads
an image: a texel with any NaN or Inf channel becomes (0, 0, 0, 0) (all four
channels, so no texel changes hue). Outputs are finite in any case.

Alpha (Blender's ``Image.alpha_mode``; Cycles' ImageAlphaType). Cycles stores
colour images with associated (premultiplied) alpha and filters premultiplied
texels, so transparent texels do not bleed their colour into neighbours:
- "STRAIGHT" / "PREMUL": stored premultiplied. Blender hands straight bytes
  (it un-premultiplies premultiplied byte files on load) and premultiplied
  floats; ``from_pixels(premultiplied=...)`` says which it got. Bytes are
  premultiplied as Cycles does it, in integers: (c * a) // 255, in the encoded
  (sRGB) values.
- "CHANNEL_PACKED": stored as given; alpha is an independent channel.
- "NONE": stored as given with alpha set to 1 (Cycles' "ignore").
- Non-Color (``data=True``) images: stored as given, whatever the mode.
The Image Texture node's Color output is un-premultiplied (divided by the
filtered alpha where 0 < alpha < 1, before sRGB decoding) only when its Alpha
output is linked and the image is stored premultiplied (Cycles'
NODE_IMAGE_ALPHA_UNASSOCIATE); otherwise Color is the premultiplied value. The
Environment Texture node never un-premultiplies. ``lookup(unassociate=...)``
takes that decision from the caller (the node evaluator knows the links).

Lookup (Cycles' ``kernel/device/cpu/image.h``), x = u W, y = v H:
- "Closest": texel floor(x), floor(y).
- "Linear": bilinear over texels floor(x - 0.5) and the next, weights from
  the fractional part (the -0.5 puts texel centres at (i + 0.5) / W).
- "Cubic": uniform cubic B-spline over 4 x 4 texels, weights
  ((1-t)^3, 3t^3 - 6t^2 + 4, -3t^3 + 3t^2 + 3t + 1, t^3) / 6. It smooths: at
  a texel centre the weights are (1/6, 2/3, 1/6), so an isolated bright texel
  reads (2/3)^2 there.
- "Smart": Cubic, as Cycles' CPU kernel treats it (Smart only means something
  to Blender's GPU viewport).
floor is Cycles' ``(int)x - (x < 0)``, which differs from floor only at exact
negative integers (x = -1 gives -2 with fraction 1): reproduced on purpose.
Extension, per tap: "REPEAT" wraps, "EXTEND" clamps to the edge texel,
"MIRROR" reflects with the edge texel repeated (-1 -> 0, W -> W-1), "CLIP"
reads transparent black (0, 0, 0, 0) for taps outside the image, so filtered
lookups fade to zero across the border over half a texel (Linear) or two
texels (Cubic), and Closest is zero outside [0, 1).
Non-finite uv are read as 0; |uv| is clamped to 1e6 (float32 uv carry no
sub-texel precision beyond that).

UDIM (``ImageSet.tiled``): tile = 1001 + tx + 10 ty with tx, ty = uv
truncated toward zero, as Cycles does (so u in (-1, 0) still lands in column
0); the tile is read at uv - (tx, ty). A uv with tx < 0, ty < 0, tx >= 10,
or on a tile the set lacks reads Cycles' missing-image colour (1, 0, 1) with
alpha 1, with no further processing. A set that is not tiled uses its one
image for every uv. A missing or unreadable image is a 1 x 1 magenta image
(``magenta``): Cycles reads its missing-image colour at every uv, whatever
the extension mode (a Clip texture is magenta outside [0, 1] too).
"""

from dataclasses import dataclass, field

import numpy as np

ALPHA_MODES = ("STRAIGHT", "PREMUL", "CHANNEL_PACKED", "NONE")
INTERPOLATIONS = ("CLOSEST", "LINEAR", "CUBIC", "SMART")
EXTENSIONS = ("REPEAT", "EXTEND", "CLIP", "MIRROR")
MISSING_RGBA = (1.0, 0.0, 1.0, 1.0)
UV_LIMIT = np.float32(1e6)

_CHUNK = 1 << 20   # texels per block when scanning for non-finite values


def srgb_to_linear(x):
    """The sRGB EOTF, piecewise and exact (float32): x / 12.92 below 0.04045,
    ((x + 0.055) / 1.055)^2.4 above; negative input gives 0, as Cycles'
    color_srgb_to_linear does."""
    x = np.asarray(x, np.float32)
    low = np.maximum(x, np.float32(0.0)) * np.float32(1.0 / 12.92)
    base = (np.maximum(x, np.float32(0.04045)) + np.float32(0.055)) * np.float32(1.0 / 1.055)
    high = np.power(base, np.float32(2.4), dtype=np.float32)
    return np.where(x < np.float32(0.04045), low, high).astype(np.float32, copy=False)


def _finite_texels(pixels):
    """pixels with every texel holding a non-finite channel set to (0, 0, 0, 0);
    the input array itself when it is clean (scanned in blocks, no full-size
    temporaries)."""
    flat = pixels.reshape(-1, 4)
    fixed = None
    for start in range(0, len(flat), _CHUNK):
        block = flat[start:start + _CHUNK]
        if np.isfinite(block).all():
            continue
        if fixed is None:
            fixed = pixels.copy()
        f = np.isfinite(block)
        bad = ~(f[:, 0] & f[:, 1] & f[:, 2] & f[:, 3])
        fixed.reshape(-1, 4)[start:start + _CHUNK][bad] = 0.0
    return pixels if fixed is None else fixed


@dataclass
class Image:
    """One image's texels, ready for lookups (see the module notes).

    pixels: (H, W, 4) float32 (linear or encoded) or uint8 (byte / 255), row 0
    the bottom row, RGBA, already premultiplied when ``associated``.
    alpha: Blender's alpha_mode; data: Non-Color; encoding: "linear" | "srgb".
    Construction checks the layout and zeroes non-finite texels; use
    ``from_pixels`` to build one from what Blender hands over."""
    pixels: np.ndarray
    name: str = ""
    alpha: str = "STRAIGHT"
    data: bool = False
    encoding: str = "linear"
    missing: bool = False       # Cycles' stand-in for an image it could not load

    def __post_init__(self):
        p = np.asarray(self.pixels)
        if p.dtype != np.uint8:
            with np.errstate(over="ignore"):     # overflow -> Inf -> zeroed below
                p = p.astype(np.float32, copy=False)
        if p.ndim != 3 or p.shape[2] != 4 or p.shape[0] < 1 or p.shape[1] < 1:
            raise ValueError(f"Image '{self.name}': pixels must be (H, W, 4) with H, W >= 1, "
                             f"got {p.shape}")
        if self.alpha not in ALPHA_MODES:
            raise ValueError(f"Image '{self.name}': unknown alpha mode {self.alpha!r}")
        if self.encoding not in ("linear", "srgb"):
            raise ValueError(f"Image '{self.name}': unknown encoding {self.encoding!r}")
        p = np.ascontiguousarray(p)
        if p.dtype == np.float32:
            p = _finite_texels(p)
        self.pixels = p

    @property
    def width(self):
        return self.pixels.shape[1]

    @property
    def height(self):
        return self.pixels.shape[0]

    @property
    def associated(self):
        """True if texels are stored premultiplied (Cycles' associated alpha)."""
        return not self.data and self.alpha in ("STRAIGHT", "PREMUL")

    @property
    def nbytes(self):
        return self.pixels.nbytes


@dataclass
class ImageSet:
    """What an Image Texture node reads: one image, or UDIM tiles.

    tiles: tile number (1001, 1002, ...) -> Image. When ``tiled`` is False the
    set holds one image (under 1001), used for every uv."""
    tiles: dict = field(default_factory=dict)
    tiled: bool = False
    name: str = ""

    @classmethod
    def single(cls, image):
        return cls({1001: image}, False, image.name)

    @property
    def nbytes(self):
        return sum(im.nbytes for im in self.tiles.values())


def _expand_channels(p):
    """(H, W) or (H, W, C), C in 1..4 -> (H, W, 4): grey to RGB, grey + alpha,
    RGB with opaque alpha (the layouts Cycles expands images to)."""
    if p.ndim == 2:
        p = p[:, :, None]
    c = p.shape[2]
    if c == 4:
        return p
    one = 255 if p.dtype == np.uint8 else 1.0
    out = np.empty(p.shape[:2] + (4,), p.dtype)
    if c in (1, 2):
        out[..., 0:3] = p[..., 0:1]
        out[..., 3] = p[..., 1] if c == 2 else one
    elif c == 3:
        out[..., 0:3] = p
        out[..., 3] = one
    else:
        raise ValueError(f"images have 1 to 4 channels, got {c}")
    return out


def from_pixels(pixels, name="", alpha="STRAIGHT", data=False, srgb=False,
                premultiplied=False, warn=None, copy=True):
    """An Image from pixels as Blender gives them (row 0 at the bottom).

    pixels: (H, W) or (H, W, C) with C in 1..4; uint8 (byte images, kept as
    bytes) or float (stored float32). srgb: the values are sRGB-encoded
    (decoded after filtering). premultiplied: colour is already multiplied by
    alpha (Blender's float buffers in the STRAIGHT and PREMUL modes); straight
    input is premultiplied here when the mode stores premultiplied texels.
    copy=False lets this work in the given array (no second full-size copy).
    An empty array gives the 1 x 1 magenta image, reported through warn(text)."""
    if alpha not in ALPHA_MODES:
        raise ValueError(f"Image '{name}': unknown alpha mode {alpha!r}")
    p = np.asarray(pixels)
    if p.dtype != np.uint8:
        with np.errstate(over="ignore"):         # overflow -> Inf -> zeroed by Image
            p = p.astype(np.float32, copy=False)
    if p.size == 0 or p.ndim not in (2, 3):
        if warn is not None:
            warn(f"Image '{name}' has no pixels; it renders magenta")
        return _magenta_image(name)
    p = _expand_channels(p)
    associate = not data and alpha in ("STRAIGHT", "PREMUL") and not premultiplied
    if (alpha == "NONE" or associate) and copy and np.may_share_memory(p, pixels):
        p = p.copy()
    if alpha == "NONE":
        p[..., 3] = 255 if p.dtype == np.uint8 else 1.0
    elif associate:
        a = p[..., 3]
        for c in range(3):
            if p.dtype == np.uint8:     # Cycles' integer rule for bytes: (c * a) // 255
                p[..., c] = p[..., c].astype(np.uint16) * a // 255
            else:
                with np.errstate(invalid="ignore", over="ignore"):
                    p[..., c] *= a
    return Image(p, name=name, alpha=alpha, data=bool(data),
                 encoding="srgb" if srgb else "linear")


def _magenta_image(name=""):
    return Image(np.array(MISSING_RGBA, np.float32).reshape(1, 1, 4), name=name,
                 alpha="STRAIGHT", missing=True)


def magenta(name=""):
    """What a missing image renders as in Cycles: a 1 x 1 image of (1, 0, 1, 1)."""
    return ImageSet.single(_magenta_image(name))


# --- lookup -----------------------------------------------------------------

def _floor(x):
    """Cycles' frac(): integer part (int)x - (x < 0) and the float32 remainder."""
    i = x.astype(np.int64)
    i -= x < 0
    return i, x - i.astype(np.float32)


def _wrap(i, size, extension):
    """Texel indices along one axis and a validity mask (CLIP only, else None)."""
    if extension == "REPEAT":
        return i % size, None
    if extension == "EXTEND":
        return np.clip(i, 0, size - 1), None
    if extension == "MIRROR":
        m = np.abs(i + (i < 0)) % (2 * size)
        return np.where(m >= size, 2 * size - 1 - m, m), None
    valid = (i >= 0) & (i < size)
    return np.where(valid, i, 0), valid


def _bspline_weights(t):
    """Cycles' cubic B-spline weights for taps -1, 0, +1, +2 at fraction t."""
    t2 = t * t
    t3 = t2 * t
    sixth = np.float32(1.0 / 6.0)
    return [sixth * (1 - t) ** 3,
            np.float32(0.5) * t3 - t2 + np.float32(2.0 / 3.0),
            np.float32(-0.5) * t3 + np.float32(0.5) * t2 + np.float32(0.5) * t + sixth,
            sixth * t3]


def _axis(coord, size, interpolation, extension):
    """Per-axis taps: lists of index arrays and of float32 weight arrays (None =
    weight 1). Taps outside a CLIP image get index 0 and weight 0."""
    x = coord * np.float32(size)
    if interpolation == "CLOSEST":
        i, _ = _floor(x)
        offsets, weights = [0], [None]
    else:
        i, t = _floor(x - np.float32(0.5))
        if interpolation == "LINEAR":
            offsets, weights = [0, 1], [1 - t, t]
        else:
            offsets, weights = [-1, 0, 1, 2], _bspline_weights(t)
    idx, wts = [], []
    for k, w in zip(offsets, weights):
        j, valid = _wrap(i + k, size, extension)
        if valid is not None:
            one = np.float32(1.0) if w is None else w
            w = np.where(valid, one, np.float32(0.0)).astype(np.float32)
        idx.append(j)
        wts.append(w)
    return idx, wts


def _sample(image, u, v, interpolation, extension):
    """Filtered RGBA (four float32 arrays) in the image's stored form
    (premultiplied if associated, encoded if sRGB)."""
    h, w = image.height, image.width
    ix, wx = _axis(u, w, interpolation, extension)
    iy, wy = _axis(v, h, interpolation, extension)
    byte = image.pixels.dtype == np.uint8
    # One item per texel: a uint32 per byte texel, a row of four floats otherwise.
    flat = image.pixels.reshape(-1).view(np.uint32) if byte else image.pixels.reshape(-1, 4)
    scale = np.float32(1.0 / 255.0) if byte else None
    n = len(u)
    acc = [np.zeros(n, np.float32) for _ in range(4)]
    for jy, ay in zip(iy, wy):
        row = jy * w
        for jx, ax in zip(ix, wx):
            weight = ay if ax is None else (ax if ay is None else ay * ax)
            if scale is not None:
                weight = scale if weight is None else weight * scale
            taps = np.take(flat, row + jx, axis=0)
            if byte:
                taps = taps.view(np.uint8).reshape(n, 4)
            for c in range(4):
                if weight is None:
                    acc[c] += taps[:, c]
                else:
                    acc[c] += taps[:, c] * weight
    return acc


def _finish(rgba, image, unassociate):
    """Un-premultiply (when asked and the image is stored premultiplied), then
    decode sRGB, as Cycles' svm_image_texture orders them."""
    r, g, b, a = rgba
    if unassociate and image.associated:
        partial = (a != 0) & (a != 1)
        inv = np.divide(np.float32(1.0), a, out=np.ones_like(a), where=partial)
        r, g, b = r * inv, g * inv, b * inv
    if image.encoding == "srgb":
        r, g, b = srgb_to_linear(r), srgb_to_linear(g), srgb_to_linear(b)
    return r, g, b, a


def _clean_uv(uv):
    uv = np.asarray(uv)
    if uv.ndim != 2 or uv.shape[1] < 2:
        raise ValueError(f"uv must be (N, 2) or (N, 3), got {uv.shape}")
    u = np.asarray(uv[:, 0], np.float32)
    v = np.asarray(uv[:, 1], np.float32)
    u = np.clip(np.where(np.isfinite(u), u, np.float32(0.0)), -UV_LIMIT, UV_LIMIT)
    v = np.clip(np.where(np.isfinite(v), v, np.float32(0.0)), -UV_LIMIT, UV_LIMIT)
    return u.astype(np.float32, copy=False), v.astype(np.float32, copy=False)


def _option(value, allowed, what):
    key = str(value).upper()
    if key not in allowed:
        raise ValueError(f"unknown {what} {value!r}; expected one of {allowed}")
    return key


def _texels(image, u, v, interpolation, extension, unassociate):
    """(r, g, b, a) arrays of one image's lookup at (u, v)."""
    if image.missing:
        return tuple(np.full(len(u), c, np.float32) for c in MISSING_RGBA)
    return _finish(_sample(image, u, v, interpolation, extension), image, unassociate)


def _lookup(image_set, u, v, interpolation, extension, unassociate):
    """(N, 4) float32 RGBA of the lookup, before the final finiteness check."""
    n = len(u)
    out = np.empty((n, 4), np.float32)
    if not image_set.tiled:
        image = next(iter(image_set.tiles.values()))
        for c, x in enumerate(_texels(image, u, v, interpolation, extension, unassociate)):
            out[:, c] = x
        return out
    out[:] = MISSING_RGBA
    tx = u.astype(np.int64)     # truncation toward zero, as Cycles' (int)u
    ty = v.astype(np.int64)
    tile = np.where((tx >= 0) & (ty >= 0) & (tx < 10), 1001 + tx + 10 * ty, -1)
    for number, image in image_set.tiles.items():
        where = np.flatnonzero(tile == number)
        if len(where) == 0:
            continue
        su = u[where] - tx[where].astype(np.float32)
        sv = v[where] - ty[where].astype(np.float32)
        rgba = _texels(image, su, sv, interpolation, extension, unassociate)
        for c, x in enumerate(rgba):
            out[where, c] = x
    return out


def lookup(image_set, uv, interpolation="Linear", extension="REPEAT", unassociate=False):
    """Cycles' image lookup for a batch: (rgb (N, 3) float32, alpha (N,) float32).

    image_set: an ImageSet (or a single Image). uv: (N, 2) or (N, 3) texture
    coordinates, u right, v up, (0, 0) the bottom-left corner; a third column
    is ignored. interpolation: Blender's "Closest" | "Linear" | "Cubic" |
    "Smart" (= Cubic); extension: "REPEAT" | "EXTEND" | "CLIP" | "MIRROR".
    unassociate: True for an Image Texture node whose Alpha output is linked
    (see the module notes); False for Environment Texture nodes."""
    interpolation = _option(interpolation, INTERPOLATIONS, "interpolation")
    if interpolation == "SMART":
        interpolation = "CUBIC"
    extension = _option(extension, EXTENSIONS, "extension")
    if isinstance(image_set, Image):
        image_set = ImageSet.single(image_set)
    u, v = _clean_uv(uv)
    with np.errstate(over="ignore", invalid="ignore"):   # caught by the final check
        out = _lookup(image_set, u, v, interpolation, extension, unassociate)
    f = np.isfinite(out)
    bad = ~(f[:, 0] & f[:, 1] & f[:, 2] & f[:, 3])
    if bad.any():
        out[bad] = 0.0
    return np.ascontiguousarray(out[:, :3]), np.ascontiguousarray(out[:, 3])
