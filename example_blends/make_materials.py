"""Build the materials example: textures, a normal map, glass, an
alpha-clipped leaf card and an HDRI world, as users' scenes have them.

Run from anywhere:

    .venv/bin/python example_blends/make_materials.py

Writes ``materials_showcase.blend`` next to this script (320x180, ReSTIR GI
biased, 4 bounces):

* world: Blender's own "sunset" HDRI (CC0, shipped in its datafiles) through an
  Environment Texture with a Mapping rotation, packed into the file;
* ground: a tiled image texture (generated here, UV-mapped, packed) with a
  tangent-space normal map (Non-Color) and a roughness from a Color Ramp;
* a glass sphere (Glass BSDF, IOR 1.45), a brushed metal sphere (Principled,
  metallic, roughness from a Gradient texture through Map Range);
* a leaf card: Principled with an alpha-clipped leaf mask texture, casting a
  leaf-shaped shadow;
* a Mix Shader of Diffuse and Glossy by Layer Weight on a box, coloured by a
  Color Attribute.

All images are generated from numpy arrays and packed, so the file needs no
other files.
"""

import math
import os

import numpy as np
import bpy

from blend_kit import (HERE, add_camera, add_mesh, box_geometry, look_at_rotation, new_scene,
                       save, setup_render, use_restir)


def _image(name, rgba, non_color=False):
    """A packed PNG image from an (H, W, 4) float array (row 0 at the bottom)."""
    h, w = rgba.shape[:2]
    img = bpy.data.images.new(name, w, h, alpha=True)
    img.pixels.foreach_set(np.ascontiguousarray(rgba, np.float32).ravel())
    img.file_format = "PNG"
    img.pack()
    if non_color:
        img.colorspace_settings.name = "Non-Color"
    return img


def _tiles(size=256):
    """Terracotta tiles with grout; and the matching tangent-space normal map."""
    y, x = np.mgrid[0:size, 0:size] / size
    u, v = (x * 4) % 1, (y * 4) % 1
    grout = (np.minimum(np.minimum(u, 1 - u), np.minimum(v, 1 - v)) < 0.04)
    tile_id = (np.floor(x * 4) + 4 * np.floor(y * 4)) % 5
    rgba = np.ones((size, size, 4), np.float32)
    base = np.stack([0.55 + 0.05 * tile_id, 0.25 + 0.02 * tile_id, 0.15 + 0.01 * tile_id], -1)
    rgba[..., :3] = np.where(grout[..., None], 0.35, base)
    # Normal map: grooves along the grout lines (slopes from a height field).
    height = np.where(grout, 0.0, 1.0)
    gy, gx = np.gradient(height.astype(np.float64))
    n = np.stack([-gx * 2.0, -gy * 2.0, np.ones_like(gx)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    normal = np.ones((size, size, 4), np.float32)
    normal[..., :3] = n * 0.5 + 0.5
    return rgba, normal


def _leaf(size=128):
    """A leaf mask: an almond outline with a stem; alpha 1 inside, 0 outside."""
    y, x = np.mgrid[0:size, 0:size] / (size - 1) * 2 - 1
    inside = (x / 0.55) ** 2 + (y / 0.95) ** 2 * (1 + 0.6 * y) < 1.0
    stem = (np.abs(x) < 0.03) & (y < -0.6)
    rgba = np.zeros((size, size, 4), np.float32)
    rgba[..., 0], rgba[..., 1], rgba[..., 2] = 0.15 + 0.1 * (y + 1), 0.45 + 0.1 * x, 0.08
    rgba[..., 3] = (inside | stem).astype(np.float32)
    return rgba


def _uv_sphere(radius, center, rings=24, segments=48):
    """Vertices and quad/triangle faces of a UV sphere, outward normals."""
    verts = [(0.0, 0.0, -radius)]
    for i in range(1, rings):
        theta = math.pi * i / rings
        for j in range(segments):
            phi = 2 * math.pi * j / segments
            verts.append((radius * math.sin(theta) * math.cos(phi), radius * math.sin(theta) * math.sin(phi),
                          -radius * math.cos(theta)))
    verts.append((0.0, 0.0, radius))
    faces = [[0, 1 + (j + 1) % segments, 1 + j] for j in range(segments)]
    for i in range(rings - 2):
        a, b = 1 + i * segments, 1 + (i + 1) * segments
        faces += [[a + j, a + (j + 1) % segments, b + (j + 1) % segments, b + j] for j in range(segments)]
    top = len(verts) - 1
    last = 1 + (rings - 2) * segments
    faces += [[last + j, last + (j + 1) % segments, top] for j in range(segments)]
    return np.asarray(verts) + np.asarray(center), faces


def _material(name):
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    for n in list(nt.nodes):
        if n.type != "OUTPUT_MATERIAL":
            nt.nodes.remove(n)
    return mat, nt, next(n for n in nt.nodes if n.type == "OUTPUT_MATERIAL")


def _smooth(ob):
    ob.data.polygons.foreach_set("use_smooth", [True] * len(ob.data.polygons))
    ob.data.update()


def build():
    scene = new_scene()
    scene.name = "MaterialsShowcase"
    setup_render(scene, 320, 180)
    scene.frame_start = scene.frame_end = scene.frame_current = 1

    # World: the sunset HDRI, packed.
    world = bpy.data.worlds.new("SunsetHDRI")
    scene.world = world
    wt = world.node_tree
    bg = next(n for n in wt.nodes if n.type == "BACKGROUND")
    env = wt.nodes.new("ShaderNodeTexEnvironment")
    folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
    env.image = bpy.data.images.load(os.path.join(folder, "sunset.exr"))
    env.image.pack()
    mapping = wt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(-40))
    coords = wt.nodes.new("ShaderNodeTexCoord")
    wt.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    wt.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    wt.links.new(env.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = 1.0

    # Ground: tiles + normal map + roughness ramp.
    tiles, normal = _tiles()
    mat, nt, out = _material("Tiles")
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = _image("tiles_color", tiles)
    ntex = nt.nodes.new("ShaderNodeTexImage")
    ntex.image = _image("tiles_normal", normal, non_color=True)
    nmap = nt.nodes.new("ShaderNodeNormalMap")
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.35, 0.35, 0.35, 1)
    ramp.color_ramp.elements[1].color = (0.8, 0.8, 0.8, 1)
    p = nt.nodes.new("ShaderNodeBsdfPrincipled")
    nt.links.new(tex.outputs["Color"], p.inputs["Base Color"])
    nt.links.new(ntex.outputs["Color"], nmap.inputs["Color"])
    nt.links.new(nmap.outputs["Normal"], p.inputs["Normal"])
    nt.links.new(tex.outputs["Color"], ramp.inputs["Fac"])
    nt.links.new(ramp.outputs["Color"], p.inputs["Roughness"])
    nt.links.new(p.outputs["BSDF"], out.inputs["Surface"])
    ground = add_mesh("Ground", [(-4, -3, 0), (4, -3, 0), (4, 5, 0), (-4, 5, 0)], [[0, 1, 2, 3]], mat)
    uv = ground.data.uv_layers.new(name="UVMap")
    uv.data.foreach_set("uv", np.float32([0, 0, 4, 0, 4, 4, 0, 4]))

    # Glass sphere and metal sphere.
    glass, gt, gout = _material("Glass")
    g = gt.nodes.new("ShaderNodeBsdfGlass")
    g.inputs["IOR"].default_value = 1.45
    g.inputs["Roughness"].default_value = 0.02
    gt.links.new(g.outputs[0], gout.inputs["Surface"])
    _smooth(add_mesh("GlassSphere", *_uv_sphere(0.6, (-1.2, 0.6, 0.6)), glass))
    metal, mt, mout = _material("BrushedMetal")
    grad = mt.nodes.new("ShaderNodeTexGradient")
    mrange = mt.nodes.new("ShaderNodeMapRange")
    mrange.inputs["To Min"].default_value, mrange.inputs["To Max"].default_value = 0.15, 0.45
    mp = mt.nodes.new("ShaderNodeBsdfPrincipled")
    mp.inputs["Base Color"].default_value = (0.95, 0.75, 0.45, 1)
    mp.inputs["Metallic"].default_value = 1.0
    mt.links.new(grad.outputs["Fac"], mrange.inputs["Value"])
    mt.links.new(mrange.outputs["Result"], mp.inputs["Roughness"])
    mt.links.new(mp.outputs[0], mout.inputs["Surface"])
    _smooth(add_mesh("MetalSphere", *_uv_sphere(0.5, (1.3, 1.2, 0.5)), metal))

    # Leaf card with an alpha-clipped mask.
    leaf, lt, lout = _material("Leaf")
    ltex = lt.nodes.new("ShaderNodeTexImage")
    ltex.image = _image("leaf_mask", _leaf())
    ltex.interpolation = "Closest"
    lp = lt.nodes.new("ShaderNodeBsdfPrincipled")
    lt.links.new(ltex.outputs["Color"], lp.inputs["Base Color"])
    lt.links.new(ltex.outputs["Alpha"], lp.inputs["Alpha"])
    lt.links.new(lp.outputs[0], lout.inputs["Surface"])
    card = add_mesh("LeafCard", [(-0.5, 0, 0), (0.5, 0, 0), (0.5, 0, 1.4), (-0.5, 0, 1.4)], [[0, 1, 2, 3]],
                    leaf, location=(0.1, 0.3, 0.05))
    card.rotation_euler = (0.0, 0.0, math.radians(25))
    card.data.uv_layers.new(name="UVMap").data.foreach_set("uv", np.float32([0, 0, 1, 0, 1, 1, 0, 1]))

    # A box: Mix of Diffuse (Color Attribute) and Glossy by Layer Weight.
    boxm, bt, bout = _material("PaintedBox")
    attr = bt.nodes.new("ShaderNodeVertexColor")
    attr.layer_name = "Paint"
    d = bt.nodes.new("ShaderNodeBsdfDiffuse")
    gl = bt.nodes.new("ShaderNodeBsdfGlossy")
    gl.inputs["Roughness"].default_value = 0.2
    lw = bt.nodes.new("ShaderNodeLayerWeight")
    mix = bt.nodes.new("ShaderNodeMixShader")
    bt.links.new(attr.outputs["Color"], d.inputs["Color"])
    bt.links.new(lw.outputs["Fresnel"], mix.inputs["Fac"])
    bt.links.new(d.outputs[0], mix.inputs[1])
    bt.links.new(gl.outputs[0], mix.inputs[2])
    bt.links.new(mix.outputs[0], bout.inputs["Surface"])
    box = add_mesh("PaintedBox", *box_geometry((0.7, 0.7, 0.7), (2.3, -0.2, 0.35), rot_z_deg=20), boxm)
    paint = box.data.color_attributes.new("Paint", "FLOAT_COLOR", "POINT")
    rng = np.random.default_rng(3)
    cols = np.ones((len(paint.data), 4), np.float32)
    cols[:, :3] = rng.uniform(0.1, 0.9, (len(paint.data), 3))
    paint.data.foreach_set("color", cols.ravel())

    eye = (0.3, -5.2, 1.6)
    scene.camera = add_camera("Camera", eye, look_at_rotation(eye, (0.3, 0.8, 0.5)), 50.0)
    use_restir(scene, max_bounces=4, warmup_frames=16)
    save("materials_showcase.blend")


if __name__ == "__main__":
    assert HERE
    build()
