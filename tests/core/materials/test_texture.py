"""Image textures (core/materials/texture.py): Cycles' lookup, storage, alpha and UDIM rules.

The vectorised lookup is checked against a scalar reference written here from
the definitions (B-spline as the basis function of the distance, wrapping by
cases), and at points whose values are known exactly."""

import numpy as np
import pytest

from restir_gi.core.materials.texture import Image, ImageSet, from_pixels, lookup, magenta, srgb_to_linear

INTERPS = ("Closest", "Linear", "Cubic")
EXTS = ("REPEAT", "EXTEND", "CLIP", "MIRROR")


# --- scalar reference ---------------------------------------------------------

def _cfloor(x):
    """Cycles' (int)x - (x < 0) and the remainder."""
    i = int(x) - (1 if x < 0 else 0)
    return i, x - i


def _wrap(i, n, ext):
    if ext == "REPEAT":
        return i % n
    if ext == "EXTEND":
        return min(max(i, 0), n - 1)
    if ext == "MIRROR":
        m = abs(i + (1 if i < 0 else 0)) % (2 * n)
        return 2 * n - m - 1 if m >= n else m
    return i if 0 <= i < n else None


def _bspline(d):
    d = abs(d)
    if d < 1:
        return (4 - 6 * d * d + 3 * d ** 3) / 6
    if d < 2:
        return (2 - d) ** 3 / 6
    return 0.0


def ref_sample(pix, u, v, interp, ext):
    """Filtered RGBA of an (H, W, 4) float64 array at one (u, v), stored form."""
    h, w = pix.shape[:2]

    def read(i, j):
        ii, jj = _wrap(i, w, ext), _wrap(j, h, ext)
        return np.zeros(4) if ii is None or jj is None else pix[jj, ii]

    # Texel coordinates in float32, as Cycles computes them (this decides the
    # texel at boundaries); everything after is double precision.
    x = np.float32(u) * np.float32(w)
    y = np.float32(v) * np.float32(h)
    if interp == "Closest":
        return read(_cfloor(float(x))[0], _cfloor(float(y))[0])
    i, tx = _cfloor(float(x - np.float32(0.5)))
    j, ty = _cfloor(float(y - np.float32(0.5)))
    if interp == "Linear":
        return ((1 - tx) * (1 - ty) * read(i, j) + tx * (1 - ty) * read(i + 1, j)
                + (1 - tx) * ty * read(i, j + 1) + tx * ty * read(i + 1, j + 1))
    out = np.zeros(4)
    for ky in range(-1, 3):
        for kx in range(-1, 3):
            out += _bspline(tx - kx) * _bspline(ty - ky) * read(i + kx, j + ky)
    return out


def rgba(image, uv, interp="Linear", ext="REPEAT", unassociate=False):
    rgb, a = lookup(image, np.asarray(uv, np.float32).reshape(-1, 2), interp, ext, unassociate)
    return np.concatenate([rgb, a[:, None]], axis=1)


def plain(pixels, **kw):
    """An image stored exactly as given (alpha as an independent channel)."""
    return from_pixels(np.asarray(pixels, np.float32), alpha="CHANNEL_PACKED", **kw)


# --- tests ----------------------------------------------------------------------

def test01_srgb_to_linear_known_values():
    x = np.array([0.0, 0.5, 1.0, 0.04, 0.04045, 0.2, -0.3], np.float32)
    y = srgb_to_linear(x)
    assert y.dtype == np.float32
    expected = [0.0, 0.214041, 1.0, 0.04 / 12.92, ((0.04045 + 0.055) / 1.055) ** 2.4,
                ((0.2 + 0.055) / 1.055) ** 2.4, 0.0]
    np.testing.assert_allclose(y, expected, rtol=2e-6, atol=1e-7)
    # The two pieces meet (to the precision of the standard's constants).
    lo, hi = srgb_to_linear(np.array([0.04045 - 1e-6, 0.04045], np.float32))
    assert abs(hi - lo) < 1e-6


def test02_closest_reads_texels_bottom_row_first():
    pix = np.arange(4 * 2 * 4, dtype=np.float32).reshape(2, 4, 4)   # row 0 = bottom
    im = plain(pix)
    centres = [((i + 0.5) / 4, (j + 0.5) / 2) for j in range(2) for i in range(4)]
    got = rgba(im, centres, "Closest")
    np.testing.assert_array_equal(got, pix.reshape(-1, 4))
    # Left edge of a texel belongs to it; v = 0.25 is the bottom row.
    np.testing.assert_array_equal(rgba(im, [(0.25, 0.25)], "Closest")[0], pix[0, 1])
    np.testing.assert_array_equal(rgba(im, [(0.25, 0.75)], "Closest")[0], pix[1, 1])


def test03_linear_exact_at_centres_and_midpoints():
    pix = np.zeros((1, 4, 4), np.float32)
    pix[0, :, 0] = [0.0, 1.0, 2.0, 4.0]
    pix[0, :, 3] = 1.0
    im = plain(pix)
    got = rgba(im, [(0.125, 0.5), (0.375, 0.5), (0.25, 0.5), (0.5, 0.5), (0.0, 0.5), (0.3125, 0.5)])
    np.testing.assert_allclose(got[:, 0], [0.0, 1.0, 0.5, 1.5, 2.0, 0.75], atol=1e-6)
    # u = 0 with REPEAT averages the last and first texels; EXTEND holds the first.
    assert rgba(im, [(0.0, 0.5)], "Linear", "EXTEND")[0, 0] == pytest.approx(0.0)


def test04_cubic_bspline_smooths_a_single_texel():
    pix = np.zeros((5, 5, 4), np.float32)
    pix[2, 2] = 1.0
    im = plain(pix)
    c = (2.5 / 5, 2.5 / 5)
    pts = [c, (3.5 / 5, 2.5 / 5), (3.5 / 5, 3.5 / 5), (4.5 / 5, 2.5 / 5)]
    got = rgba(im, pts, "Cubic", "CLIP")[:, 0]
    np.testing.assert_allclose(got, [4 / 9, 1 / 9, 1 / 36, 0.0], atol=1e-7)
    # Smart is Cubic.
    np.testing.assert_array_equal(rgba(im, pts, "Smart", "CLIP"), rgba(im, pts, "Cubic", "CLIP"))


@pytest.mark.parametrize("ext", ["REPEAT", "EXTEND", "MIRROR"])
@pytest.mark.parametrize("interp", INTERPS)
def test05_constant_image_stays_constant(rng, interp, ext):
    im = plain(np.full((3, 7, 4), 0.625, np.float32))
    uv = rng.uniform(-3, 4, (500, 2))
    np.testing.assert_allclose(rgba(im, uv, interp, ext), 0.625, atol=1e-6)


@pytest.mark.parametrize("ext", EXTS)
@pytest.mark.parametrize("interp", INTERPS)
def test06_matches_scalar_reference(rng, interp, ext):
    pix = rng.uniform(0, 1, (5, 7, 4)).astype(np.float32)
    im = plain(pix)
    uv = rng.uniform(-1.5, 2.5, (400, 2)).astype(np.float32)
    uv[:20] = rng.integers(-10, 20, (20, 2)) / np.array([7, 5])   # on texel edges
    got = rgba(im, uv, interp, ext)
    ref = np.array([ref_sample(pix.astype(np.float64), float(u), float(v), interp, ext)
                    for u, v in uv])
    np.testing.assert_allclose(got, ref, atol=2e-6)


@pytest.mark.parametrize("interp", INTERPS)
def test07_byte_image_matches_reference(rng, interp):
    pix = rng.integers(0, 256, (4, 6, 4)).astype(np.uint8)
    im = from_pixels(pix, alpha="CHANNEL_PACKED")
    assert im.pixels.dtype == np.uint8 and im.nbytes == 4 * 6 * 4
    uv = rng.uniform(-0.5, 1.5, (300, 2)).astype(np.float32)
    got = rgba(im, uv, interp, "MIRROR")
    ref = np.array([ref_sample(pix / 255.0, float(u), float(v), interp, "MIRROR") for u, v in uv])
    np.testing.assert_allclose(got, ref, atol=2e-6)


def test08_extension_modes_at_and_beyond_borders():
    pix = np.zeros((1, 4, 4), np.float32)
    pix[0, :, 0] = [1.0, 2.0, 3.0, 4.0]
    pix[0, :, 3] = 1.0
    im = plain(pix)
    r = lambda u, interp, ext: rgba(im, [(u, 0.5)], interp, ext)[0]  # noqa: E731
    # CLIP: Closest is zero outside [0, 1); Linear fades over the half texel.
    assert r(1.0, "Closest", "CLIP")[0] == 0 and r(-0.01, "Closest", "CLIP")[3] == 0
    assert r(0.999, "Closest", "CLIP")[0] == 4.0
    np.testing.assert_allclose(r(0.0, "Linear", "CLIP"), [0.5, 0, 0, 0.5], atol=1e-6)
    np.testing.assert_allclose(r(-0.125, "Linear", "CLIP"), 0.0, atol=1e-7)
    assert r(-0.2, "Cubic", "CLIP")[3] > 0            # cubic taps reach two texels out
    np.testing.assert_allclose(r(-0.5, "Cubic", "CLIP"), 0.0, atol=1e-7)
    # EXTEND holds the edge texel far away.
    assert r(7.3, "Linear", "EXTEND")[0] == pytest.approx(4.0)
    assert r(-5.0, "Cubic", "EXTEND")[0] == pytest.approx(1.0)
    # MIRROR repeats the edge texel, then runs backwards.
    assert [r(u, "Closest", "MIRROR")[0] for u in (1.1, 1.3, 1.6, 1.9, 2.1, -0.1, -0.3)] == \
        [4.0, 3.0, 2.0, 1.0, 1.0, 1.0, 2.0]
    # REPEAT is periodic.
    np.testing.assert_allclose(r(0.3, "Cubic", "REPEAT"), r(-2.7, "Cubic", "REPEAT"), atol=1e-6)


def test09_cycles_floor_at_negative_integers():
    """x = u W = -1 exactly: Cycles takes texel -2 (fraction 1), not -1."""
    pix = np.zeros((1, 4, 4), np.float32)
    pix[0, :, 0] = [1.0, 2.0, 3.0, 4.0]
    im = plain(pix)
    assert rgba(im, [(-0.25, 0.5)], "Closest", "REPEAT")[0, 0] == 3.0
    assert rgba(im, [(-0.2, 0.5)], "Closest", "REPEAT")[0, 0] == 4.0


def test10_udim_tile_selection():
    tile = lambda c, w=2, h=2: plain(np.broadcast_to(np.array(c, np.float32), (h, w, 4)))  # noqa: E731
    ramp = np.zeros((1, 4, 4), np.float32)
    ramp[0, :, 1] = [1.0, 2.0, 3.0, 4.0]
    ramp[0, :, 3] = 1.0
    s = ImageSet({1001: tile((1, 0, 0, 1)), 1002: plain(ramp), 1011: tile((0, 0, 1, 1))}, tiled=True)
    uv = [(0.5, 0.5), (1.375, 0.5), (0.5, 1.5), (2.5, 0.5), (10.5, 0.5), (-0.5, 0.5),
          (0.5, -0.5), (-1.5, 0.5), (1.875, 0.2)]
    got = rgba(s, uv, "Closest")
    expected = [(1, 0, 0, 1), (0, 2, 0, 1), (0, 0, 1, 1), (1, 0, 1, 1), (1, 0, 1, 1),
                (1, 0, 0, 1), (1, 0, 0, 1), (1, 0, 1, 1), (0, 4, 0, 1)]
    np.testing.assert_array_equal(got, np.array(expected, np.float32))
    # A set that is not tiled reads its image everywhere.
    single = ImageSet.single(plain(ramp))
    assert rgba(single, [(2.375, 7.5)], "Closest")[0, 1] == 2.0


def test11_alpha_modes():
    straight = np.array([[[0.8, 0.4, 0.2, 0.5]]], np.float32)
    premul = straight * np.array([0.5, 0.5, 0.5, 1.0], np.float32)
    cases = {   # mode -> (pixels, premultiplied input, data, stored, colour with unassociate)
        "STRAIGHT": (straight, False, False, premul[0, 0], straight[0, 0]),
        "PREMUL": (premul, True, False, premul[0, 0], straight[0, 0]),
        "CHANNEL_PACKED": (straight, False, False, straight[0, 0], straight[0, 0]),
        "NONE": (straight, False, False, [0.8, 0.4, 0.2, 1.0], [0.8, 0.4, 0.2, 1.0]),
        "DATA": (straight, False, True, straight[0, 0], straight[0, 0]),
    }
    for mode, (pix, pre, data, stored, unassoc) in cases.items():
        im = from_pixels(pix, alpha="STRAIGHT" if mode == "DATA" else mode, data=data, premultiplied=pre)
        np.testing.assert_allclose(rgba(im, [(0.5, 0.5)], unassociate=False)[0], stored, rtol=1e-6,
                                   err_msg=mode)
        np.testing.assert_allclose(rgba(im, [(0.5, 0.5)], unassociate=True)[0], unassoc, rtol=1e-6,
                                   err_msg=mode)


def test12_filtering_is_premultiplied():
    """An opaque red texel beside a transparent green one: no green in between."""
    pix = np.array([[[1, 0, 0, 1], [0, 1, 0, 0]]], np.float32)
    im = from_pixels(pix, alpha="STRAIGHT")
    got = rgba(im, [(0.5, 0.5)], "Linear", "EXTEND", unassociate=True)[0]
    np.testing.assert_allclose(got, [1, 0, 0, 0.5], atol=1e-6)
    got = rgba(im, [(0.5, 0.5)], "Linear", "EXTEND", unassociate=False)[0]
    np.testing.assert_allclose(got, [0.5, 0, 0, 0.5], atol=1e-6)
    # Where alpha is 0 nothing is divided.
    assert rgba(im, [(0.99, 0.5)], "Closest", unassociate=True)[0].tolist() == [0, 0, 0, 0]


def test13_byte_srgb_premultiplied_in_integers_and_decoded_after_filtering():
    pix = np.array([[[200, 255, 0, 128]]], np.uint8)
    im = from_pixels(pix, alpha="STRAIGHT", srgb=True)
    assert im.pixels[0, 0].tolist() == [(200 * 128) // 255, 128, 0, 128]
    got = rgba(im, [(0.5, 0.5)], "Closest", unassociate=True)[0]
    np.testing.assert_allclose(got[:3], srgb_to_linear(np.array([100 / 128, 1.0, 0.0], np.float32)),
                               rtol=1e-6)
    assert got[3] == pytest.approx(128 / 255)
    # Linear filtering happens on the encoded values (as Cycles does for 8-bit sRGB).
    two = from_pixels(np.array([[[0, 0, 0, 255], [255, 255, 255, 255]]], np.uint8), srgb=True)
    mid = rgba(two, [(0.5, 0.5)], "Linear", "EXTEND")[0]
    np.testing.assert_allclose(mid[:3], 0.214041, rtol=1e-5)


def test14_nonfinite_texels_become_transparent_black():
    pix = np.ones((2, 2, 4), np.float64)
    pix[0, 0, 1] = np.nan
    pix[1, 1, 0] = np.inf
    pix[1, 0, 3] = 1e300                      # overflows float32
    im = from_pixels(pix, alpha="CHANNEL_PACKED")
    assert im.pixels.dtype == np.float32 and np.isfinite(im.pixels).all()
    assert im.pixels[0, 0].tolist() == [0, 0, 0, 0] and im.pixels[1, 1].tolist() == [0, 0, 0, 0]
    assert im.pixels[1, 0].tolist() == [0, 0, 0, 0] and im.pixels[0, 1].tolist() == [1, 1, 1, 1]
    # The constructor itself sanitises, without touching the caller's array.
    raw = np.full((1, 2, 4), np.nan, np.float32)
    assert np.isfinite(Image(raw).pixels).all() and np.isnan(raw).all()


def test15_outputs_finite_for_extreme_inputs():
    pix = np.array([[[3e38, 3e38, 3e38, 1e-30], [3e38, 0, 0, 1]]], np.float32)
    im = from_pixels(pix, alpha="PREMUL", premultiplied=True)
    uv = np.array([(0.25, 0.5), (0.5, 0.5), (np.nan, 0.5), (np.inf, -np.inf), (1e30, 3e38)])
    for interp in INTERPS:
        for unassociate in (False, True):
            got = rgba(im, uv, interp, "REPEAT", unassociate)
            assert np.isfinite(got).all(), (interp, unassociate)


def test16_nonfinite_uv_read_as_zero():
    pix = np.random.default_rng(1).uniform(0, 1, (3, 3, 4)).astype(np.float32)
    im = plain(pix)
    bad = rgba(im, [(np.nan, 0.0), (0.0, np.inf), (-np.inf, np.nan)], "Cubic")
    np.testing.assert_array_equal(bad, np.repeat(rgba(im, [(0.0, 0.0)], "Cubic"), 3, axis=0))


def test17_missing_and_empty_images_are_magenta():
    warnings = []
    im = from_pixels(np.zeros((0, 0, 4), np.float32), name="gone", warn=warnings.append)
    assert len(warnings) == 1 and "gone" in warnings[0]
    for s in (magenta("x"), ImageSet.single(im)):
        np.testing.assert_allclose(rgba(s, [(0.3, 0.7), (5.5, -2.0)], "Cubic"), [[1, 0, 1, 1]] * 2,
                                   atol=1e-6)
        # Cycles reads its missing-image colour at every uv, whatever the
        # extension: CLIP leaves it magenta outside [0, 1] (checked against
        # Cycles: a missing file on a quad whose uv span [-1, 2]).
        for interpolation in ("Closest", "Linear", "Cubic"):
            np.testing.assert_array_equal(rgba(s, [(1.5, 0.5), (0.0, 0.0), (-3.0, 0.5)], interpolation, "CLIP"),
                                          [[1, 0, 1, 1]] * 3)


def test18_channel_layouts():
    grey = from_pixels(np.full((1, 1), 0.25, np.float32))
    grey_alpha = from_pixels(np.array([[[0.5, 0.5]]], np.float32), alpha="CHANNEL_PACKED")
    rgb = from_pixels(np.array([[[0.1, 0.2, 0.3]]], np.float32))
    assert grey.pixels[0, 0].tolist() == [0.25, 0.25, 0.25, 1.0]
    assert grey_alpha.pixels[0, 0].tolist() == [0.5, 0.5, 0.5, 0.5]
    np.testing.assert_allclose(rgb.pixels[0, 0], [0.1, 0.2, 0.3, 1.0])


def test19_rejects_unknown_options():
    im = magenta()
    with pytest.raises(ValueError):
        lookup(im, np.zeros((1, 2), np.float32), "Bilinear")
    with pytest.raises(ValueError):
        lookup(im, np.zeros((1, 2), np.float32), "Linear", "WRAP")
    with pytest.raises(ValueError):
        from_pixels(np.zeros((1, 1, 4)), alpha="ASSOCIATED")


def test20_empty_batch_and_vector_input():
    im = magenta()
    rgb, a = lookup(im, np.zeros((0, 3), np.float32))
    assert rgb.shape == (0, 3) and a.shape == (0,)
    rgb, a = lookup(im, np.zeros((2, 3), np.float32), "Cubic")   # a Vector socket: z ignored
    assert rgb.shape == (2, 3) and rgb.dtype == np.float32 and a.dtype == np.float32


def test21_from_pixels_leaves_the_callers_array_alone():
    for pix in (np.full((2, 2, 4), 0.5, np.float32), np.full((2, 2, 4), 128, np.uint8)):
        before = pix.copy()
        for mode in ("STRAIGHT", "NONE"):
            im = from_pixels(pix, alpha=mode)
            np.testing.assert_array_equal(pix, before)
            assert not np.shares_memory(im.pixels, pix)
        owned = pix.copy()
        im = from_pixels(owned, alpha="STRAIGHT", copy=False)   # may work in place
        assert im.pixels[0, 0, 0] == (0.25 if pix.dtype == np.float32 else 64)
