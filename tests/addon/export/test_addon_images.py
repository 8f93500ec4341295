"""Reading Blender images into core ImageSets (restir_addon/export/images.py).

Files are written independently of Blender where it matters (a PNG encoded
here, an EXR through OpenEXR) so row order and colour handling are checked
against known bytes, not against Blender's own writer."""

import os
import struct
import zlib

import numpy as np
import pytest

from restir_gi.core.materials.texture import lookup, srgb_to_linear


def write_png(path, rows_top_first, alpha=True):
    """An 8-bit RGB(A) PNG from uint8 rows listed top row first (the file order)."""
    rows = np.asarray(rows_top_first, np.uint8)
    h, w, c = rows.shape

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    raw = b"".join(b"\x00" + rows[y].tobytes() for y in range(h))
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 6 if c == 4 else 2, 0, 0, 0)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw))
                + chunk(b"IEND", b""))


def texel_centres(w, h):
    """uv of every texel centre, bottom row first."""
    j, i = np.mgrid[0:h, 0:w]
    return np.stack([(i.ravel() + 0.5) / w, (j.ravel() + 0.5) / h], axis=1).astype(np.float32)


def read_back(image_set, w, h, unassociate=False):
    rgb, a = lookup(image_set, texel_centres(w, h), "Closest", "REPEAT", unassociate)
    return np.concatenate([rgb, a[:, None]], axis=1).reshape(h, w, 4)


@pytest.fixture
def bpy_env(addon, tmp_path):
    """bpy, a cache with its warnings, a temporary folder; images made by the
    test are removed afterwards, and no temporary image may be left behind."""
    import bpy
    from restir_gi.restir_addon.export.images import ImageCache
    before = set(bpy.data.images)
    warnings = []

    class Env:
        pass
    env = Env()
    env.bpy, env.dir, env.warnings = bpy, tmp_path, warnings
    env.cache = lambda **kw: ImageCache(warnings.append, **kw)
    env.made = lambda: set(bpy.data.images) - before
    yield env
    for im in set(bpy.data.images) - before:
        bpy.data.images.remove(im)


@pytest.fixture
def png_rows():
    """2 x 3 RGBA rows, top row first: top opaque red/green, bottom blue/partial."""
    return [[[255, 0, 0, 255], [0, 255, 0, 255]],
            [[10, 20, 30, 255], [40, 50, 60, 255]],
            [[0, 0, 255, 255], [200, 100, 50, 128]]]


def test01_png_srgb_rows_bottom_first_and_linearised(bpy_env, png_rows):
    path = str(bpy_env.dir / "a.png")
    write_png(path, png_rows)
    img = bpy_env.bpy.data.images.load(path)
    n_images = len(bpy_env.bpy.data.images)
    cache = bpy_env.cache()
    s = cache.get(cache.key(img))
    assert len(bpy_env.bpy.data.images) == n_images          # no temporaries left
    stored = s.tiles[1001].pixels
    assert stored.dtype == np.uint8 and stored.shape == (3, 2, 4)
    bottom_first = np.asarray(png_rows, np.float64)[::-1]
    # Straight bytes are premultiplied in integers: (200 * 128) // 255 = 100.
    assert stored[0, 1].tolist() == [100, 50, 25, 128]
    got = read_back(s, 2, 3, unassociate=False)
    expected = srgb_to_linear((bottom_first[..., :3] * bottom_first[..., 3:] // 255) / 255)
    np.testing.assert_allclose(got[..., :3], expected, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(got[..., 3], bottom_first[..., 3] / 255, rtol=1e-6)
    np.testing.assert_allclose(got[0, 0, :3], [0, 0, 1], atol=1e-6)   # bottom-left is blue
    assert bpy_env.warnings == []


def test02_non_color_is_raw(bpy_env, png_rows):
    path = str(bpy_env.dir / "n.png")
    write_png(path, png_rows)
    img = bpy_env.bpy.data.images.load(path)
    img.colorspace_settings.name = "Non-Color"
    cache = bpy_env.cache()
    s = cache.get(cache.key(img))
    got = read_back(s, 2, 3, unassociate=True)
    np.testing.assert_allclose(got, np.asarray(png_rows, np.float64)[::-1] / 255, rtol=1e-6)


def test03_alpha_modes_of_a_byte_image(bpy_env, png_rows):
    """Colour comes back straight wherever the mode stores premultiplied texels
    (the integer premultiply loses up to a byte, which dividing by alpha = 0.5
    doubles: the same loss as Cycles'), alpha as stored.
    The reference is Blender's own straight buffer: for a file marked PREMUL
    Blender un-premultiplies the bytes on load."""
    path = str(bpy_env.dir / "m.png")
    write_png(path, png_rows)
    for mode in ("STRAIGHT", "PREMUL", "CHANNEL_PACKED", "NONE"):
        img = bpy_env.bpy.data.images.load(path, check_existing=False)
        img.colorspace_settings.name = "Non-Color" if mode == "CHANNEL_PACKED" else "sRGB"
        img.alpha_mode = mode
        raw = np.empty(24, np.float32)
        img.pixels.foreach_get(raw)
        texel = raw.reshape(3, 2, 4)[0, 1]                    # bottom-right, alpha 128
        cache = bpy_env.cache()
        got = read_back(cache.get(cache.key(img)), 2, 3, unassociate=True)[0, 1]
        want = texel[:3] if mode == "CHANNEL_PACKED" else srgb_to_linear(texel[:3])
        np.testing.assert_allclose(got[:3], want, atol=0.02, err_msg=mode)
        assert got[3] == pytest.approx(1.0 if mode == "NONE" else 128 / 255), mode
        # Without un-premultiplying, Color is the stored (premultiplied) value.
        stored = read_back(cache.get(cache.key(img)), 2, 3)[0, 1, :3]
        if mode in ("STRAIGHT", "PREMUL"):
            assert stored[0] < 0.6 * got[0], mode
        else:
            np.testing.assert_array_equal(stored, got[:3], err_msg=mode)


def test04_float_exr_kept_linear_and_premultiplied(bpy_env):
    import OpenEXR
    path = str(bpy_env.dir / "f.exr")
    top_first = np.array([[[0.5, 2.0, 8.0, 1.0], [16.0, 0.0, 0.25, 1.0]],
                          [[0.25, 0.125, 0.0, 0.5], [0.0, 0.0, 0.0, 0.0]]], np.float32)
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                      {"RGBA": top_first}) as f:
        f.write(path)
    img = bpy_env.bpy.data.images.load(path)
    cache = bpy_env.cache()
    s = cache.get(cache.key(img))
    stored = s.tiles[1001].pixels
    assert stored.dtype == np.float32
    np.testing.assert_array_equal(stored, top_first[::-1])
    got = read_back(s, 2, 2, unassociate=True)
    np.testing.assert_allclose(got[0, 0], [0.5, 0.25, 0.0, 0.5], rtol=1e-6)
    np.testing.assert_allclose(got[1, 1], [16.0, 0.0, 0.25, 1.0], rtol=1e-6)


def test05_generated_byte_and_float_images(bpy_env):
    bpy = bpy_env.bpy
    g = bpy.data.images.new("gen_byte", 4, 2)
    g.generated_color = (0.5, 0.25, 1.0, 1.0)
    f = bpy.data.images.new("gen_float", 3, 2, float_buffer=True)
    values = np.linspace(0, 3, 24, dtype=np.float32).reshape(2, 3, 4)
    values[..., 3] = 1.0
    f.pixels.foreach_set(values.ravel())
    cache = bpy_env.cache()
    sb, sf = cache.get(cache.key(g)), cache.get(cache.key(f))
    raw = np.empty(32, np.float32)
    g.pixels.foreach_get(raw)
    np.testing.assert_allclose(read_back(sb, 4, 2)[..., :3],
                               srgb_to_linear(raw.reshape(2, 4, 4)[..., :3]), rtol=1e-5)
    np.testing.assert_allclose(read_back(sf, 3, 2), values, rtol=1e-6)


def test06_missing_file_is_magenta_with_warning(bpy_env):
    bpy = bpy_env.bpy
    img = bpy.data.images.new("lost", 4, 4)
    img.source = "FILE"
    img.filepath = str(bpy_env.dir / "not_there.png")
    cache = bpy_env.cache()
    s = cache.get(cache.key(img))
    np.testing.assert_array_equal(read_back(s, 1, 1), [[[1, 0, 1, 1]]])
    assert len(bpy_env.warnings) == 1
    assert "lost" in bpy_env.warnings[0] and "not_there.png" in bpy_env.warnings[0]


def test07_empty_image_and_no_image_are_magenta(bpy_env):
    bpy = bpy_env.bpy
    img = bpy.data.images.new("empty", 4, 4)
    img.source = "FILE"                       # no file path: no pixels at all
    cache = bpy_env.cache()
    for key in (cache.key(img), cache.key(None)):
        np.testing.assert_array_equal(read_back(cache.get(key), 1, 1), [[[1, 0, 1, 1]]])
    assert len(bpy_env.warnings) == 2 and "empty" in bpy_env.warnings[0]


def test08_packed_image_read_after_its_file_is_gone(bpy_env, png_rows):
    path = str(bpy_env.dir / "p.png")
    write_png(path, png_rows)
    img = bpy_env.bpy.data.images.load(path)
    img.pack()
    os.unlink(path)
    img.buffers_free()
    cache = bpy_env.cache()
    got = read_back(cache.get(cache.key(img)), 2, 3)
    np.testing.assert_allclose(got[0, 0, :3], [0, 0, 1], atol=1e-6)
    np.testing.assert_allclose(got[2, 0, :3], [1, 0, 0], atol=1e-6)
    assert bpy_env.warnings == []


def test09_one_read_per_image(bpy_env):
    img = bpy_env.bpy.data.images.new("shared", 2, 2)
    cache = bpy_env.cache()
    k1, k2 = cache.key(img), cache.key(img)
    assert k1 == k2 and isinstance(k1, str)
    assert cache.get(k1) is cache.get(k2) and list(cache.images) == [k1]


def _udim_from_files(bpy_env, colours_by_tile):
    for number, (rgb, size) in colours_by_tile.items():
        rows = np.broadcast_to(np.array(rgb + [255], np.uint8), (size[1], size[0], 4))
        write_png(str(bpy_env.dir / f"t.{number}.png"), rows)
    img = bpy_env.bpy.data.images.load(str(bpy_env.dir / "t.1001.png"))
    img.source = "TILED"
    img.colorspace_settings.name = "Non-Color"
    return img


def test10_udim_tiles_from_files_and_generated(bpy_env):
    bpy = bpy_env.bpy
    tiles = {1001: ([255, 0, 0], (4, 2)), 1002: ([0, 255, 0], (8, 4)), 1012: ([0, 0, 255], (2, 2))}
    img = _udim_from_files(bpy_env, tiles)
    assert [t.number for t in img.tiles] == [1001, 1002, 1012]
    gen = bpy.data.images.new("udim_gen", 4, 2, tiled=True)
    gen.colorspace_settings.name = "Non-Color"
    gen.generated_color = (1, 0, 0, 1)
    with bpy.context.temp_override(edit_image=gen):
        bpy.ops.image.tile_add(number=1002, count=1, fill=True, color=(0, 1, 0, 1),
                               width=8, height=4, float=False, alpha=True)
        bpy.ops.image.tile_add(number=1012, count=1, fill=True, color=(0, 0, 1, 1),
                               width=2, height=2, float=False, alpha=True)
    n_images = len(bpy.data.images)
    cache = bpy_env.cache()
    uv = np.array([(0.5, 0.5), (1.5, 0.5), (1.5, 1.5), (2.5, 0.5)], np.float32)
    for image in (img, gen):
        s = cache.get(cache.key(image))
        assert s.tiled and sorted(s.tiles) == [1001, 1002, 1012]
        assert s.tiles[1002].pixels.shape == (4, 8, 4)
        rgb, a = lookup(s, uv, "Closest")
        np.testing.assert_allclose(rgb, [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1]], atol=1e-6)
    assert len(bpy.data.images) == n_images
    assert os.path.exists(bpy_env.dir / "t.1002.png")        # files left alone


def test11_large_images_are_halved_until_they_fit(bpy_env):
    bpy = bpy_env.bpy
    img = bpy.data.images.new("big", 64, 20, float_buffer=True)
    img.generated_color = (0.25, 0.5, 0.75, 1.0)
    n_images = len(bpy.data.images)
    cache = bpy_env.cache(max_size=16)
    s = cache.get(cache.key(img))
    assert s.tiles[1001].pixels.shape == (5, 16, 4)
    assert tuple(img.size) == (64, 20) and len(bpy.data.images) == n_images
    assert len(bpy_env.warnings) == 1 and "64 x 20" in bpy_env.warnings[0] \
        and "16 x 5" in bpy_env.warnings[0]
    full = np.empty(64 * 20 * 4, np.float32)
    img.pixels.foreach_get(full)
    rgb, _ = lookup(s, np.array([(0.5, 0.5)], np.float32), "Closest")
    np.testing.assert_allclose(rgb[0], full[:3], atol=1e-5)     # a uniform image stays uniform


def test12_image_sequence_reads_the_scene_frame(bpy_env, png_rows):
    from restir_gi.restir_addon.export.images import sequence_frame
    bpy = bpy_env.bpy
    for frame, value in ((1, 50), (2, 150)):
        write_png(str(bpy_env.dir / f"seq_{frame:04d}.png"),
                  np.full((1, 1, 4), [value, value, value, 255], np.uint8))
    img = bpy.data.images.load(str(bpy_env.dir / "seq_0001.png"))
    img.source = "SEQUENCE"
    img.colorspace_settings.name = "Non-Color"
    mat = bpy.data.materials.new("seq_mat")
    node = mat.node_tree.nodes.new("ShaderNodeTexImage")
    node.image = img
    user = node.image_user
    user.frame_duration, user.frame_start, user.frame_offset = 2, 10, 0
    assert [sequence_frame(user, f) for f in (9, 10, 11, 12)] == [0, 1, 2, 2]
    user.use_cyclic = True
    assert [sequence_frame(user, f) for f in (9, 10, 11, 12)] == [2, 1, 2, 1]
    cache = bpy_env.cache()
    k10, k11 = cache.key(img, user, 10), cache.key(img, user, 11)
    assert k10 != k11
    assert read_back(cache.get(k10), 1, 1)[0, 0, 0] == pytest.approx(50 / 255)
    assert read_back(cache.get(k11), 1, 1)[0, 0, 0] == pytest.approx(150 / 255)
    bpy.data.materials.remove(mat)


def test13_other_colour_spaces_warn(bpy_env, png_rows):
    path = str(bpy_env.dir / "c.png")
    write_png(path, png_rows)
    texel = np.array([10, 20, 30]) / 255                 # middle row, left
    for space, decode in (("AgX Base sRGB", True), ("ACEScg", False)):
        bpy_env.warnings.clear()
        img = bpy_env.bpy.data.images.load(path, check_existing=False)
        img.colorspace_settings.name = space
        cache = bpy_env.cache()
        got = read_back(cache.get(cache.key(img)), 2, 3)[1, 0, :3]
        want = srgb_to_linear(texel.astype(np.float32)) if decode else texel
        np.testing.assert_allclose(got, want, rtol=1e-5)
        assert len(bpy_env.warnings) == 1 and space in bpy_env.warnings[0]


@pytest.mark.parametrize("persistent", [False, True], ids=["compare", "persistent"])
def test14_image_sequences_follow_the_frame_in_renders(bpy_env, tmp_path, persistent):
    """An Image Texture on a sequence shows each frame's file in an animation
    render (with and without Persistent Data) and in a still of a frame: the
    exporter hands the node's image user and the scene frame to the cache."""
    from support.addon_util import add_mesh, camera, fresh, rect, world
    from restir_gi.core.camera.film import read_exr
    bpy = bpy_env.bpy
    values = (40, 120, 200)
    for frame, value in enumerate(values, 1):
        write_png(str(bpy_env.dir / f"seq_{frame:04d}.png"),
                  np.full((1, 1, 4), [value, value, value, 255], np.uint8))
    scene = fresh(8, 8, samples=1)
    scene.render.use_persistent_data = persistent
    camera(location=(0, 0, 5), type="ORTHO", ortho_scale=1.0)
    world((0, 0, 0))
    img = bpy.data.images.load(str(bpy_env.dir / "seq_0001.png"))
    img.source = "SEQUENCE"
    img.colorspace_settings.name = "Non-Color"
    mat = bpy.data.materials.new("seq_glow")
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.image_user.frame_duration = 3
    bsdf = tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0, 0, 0, 1)
    bsdf.inputs["Emission Strength"].default_value = 1.0
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Emission Color"])
    add_mesh("Card", *rect(-2, 2, -2, 2)).data.materials.append(mat)
    scene.frame_start, scene.frame_end = 1, 3
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(tmp_path / "seq_####")
    bpy.ops.render.render(animation=True)
    got = [float(read_exr(tmp_path / f"seq_{f:04d}.exr")[..., :3].mean()) for f in (1, 2, 3)]
    np.testing.assert_allclose(got, np.array(values) / 255.0, rtol=0.02)
    scene.frame_set(2)
    scene.render.filepath = str(tmp_path / "still.exr")
    bpy.ops.render.render(write_still=True)
    assert float(read_exr(tmp_path / "still.exr")[..., :3].mean()) == pytest.approx(values[1] / 255.0, rel=0.02)
    bpy.data.materials.remove(mat)


def test15_no_datablock_is_removed_while_rendering(bpy_env):
    """Removing a datablock during an animation render with Persistent Data
    crashes Blender 5.2 in the next frame's depsgraph update: temporary images
    read during a final render are kept, their pixels freed, until sweep()
    runs once no render does; outside renders they go at once."""
    from restir_gi.restir_addon.export import images
    bpy = bpy_env.bpy
    for frame, value in ((1, 50), (2, 150)):
        write_png(str(bpy_env.dir / f"seq_{frame:04d}.png"),
                  np.full((1, 1, 4), [value, value, value, 255], np.uint8))
    img = bpy.data.images.load(str(bpy_env.dir / "seq_0001.png"))
    img.source = "SEQUENCE"
    img.colorspace_settings.name = "Non-Color"
    udim = _udim_from_files(bpy_env, {1001: ([255, 0, 0], (2, 2)), 1002: ([0, 255, 0], (2, 2))})
    mat = bpy.data.materials.new("seq_mat")
    node = mat.node_tree.nodes.new("ShaderNodeTexImage")
    node.image = img
    node.image_user.frame_duration = 2
    assert bpy.app.timers.is_registered(images.sweep)                # the engine's, main thread
    n_images = len(bpy.data.images)
    cache = bpy_env.cache()
    with images.rendering():
        _, k2 = cache.key(img, node.image_user, 1), cache.key(img, node.image_user, 2)
        cache.key(udim)
        kept = [im for im in bpy.data.images if im.name.startswith(images.TEMPORARY)]
        assert len(kept) == 3 and len(bpy.data.images) == n_images + 3
        assert all(not im.has_data for im in kept)                   # pixels freed
        images.sweep()                                               # still rendering: kept
        assert len(bpy.data.images) == n_images + 3
    assert read_back(cache.get(k2), 1, 1)[0, 0, 0] == pytest.approx(150 / 255)
    images.sweep()
    assert len(bpy.data.images) == n_images
    cache.key(img, node.image_user, 3)                               # outside a render: at once
    assert len(bpy.data.images) == n_images
    bpy.data.materials.remove(mat)


def test16_large_images_average_boxes_of_texels(bpy_env, rng):
    """The halving averages each box of texels (a box filter, as Blender's
    Image.scale for whole ratios) from the pixels as they are, unsaved paint
    included, without a temporary copy."""
    from restir_gi.restir_addon.export.images import shrink
    bpy = bpy_env.bpy
    px = rng.random((20, 64, 4)).astype(np.float32)
    img = bpy.data.images.new("painted", 64, 20, float_buffer=True)
    img.colorspace_settings.name = "Non-Color"
    img.pixels.foreach_set(px.ravel())
    n_images = len(bpy.data.images)
    cache = bpy_env.cache(max_size=16)
    stored = cache.get(cache.key(img)).tiles[1001].pixels
    np.testing.assert_allclose(stored, px.reshape(5, 4, 16, 4, 4).mean(axis=(1, 3)), atol=1e-6)
    assert len(bpy.data.images) == n_images
    odd = shrink(np.arange(5, dtype=np.float32).reshape(1, 5, 1), 2, 1)
    np.testing.assert_allclose(odd.ravel(), [0.5, 3.0])            # boxes of 2 and 3 texels
