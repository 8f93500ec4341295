"""The example Cornell box changed by script: new materials, assigned to its
objects by name; smooth spheres in place of its two boxes; an image texture
written to a file. The node families (node_families.py) and the light path
tests build on these."""

import os
import tempfile

import numpy as np


def _tree(mat):
    tree = mat.node_tree
    for n in list(tree.nodes):
        if n.type != "OUTPUT_MATERIAL":
            tree.nodes.remove(n)
    out = next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")
    return tree, out


def new_material(name):
    """A material whose tree holds its Material Output alone: (material, tree, output)."""
    import bpy
    mat = bpy.data.materials.new(name)
    return mat, *_tree(mat)


def assign(obj_names, mat):
    """mat as the only material of the named objects (given a UV map where they have none)."""
    import bpy
    for name in obj_names:
        ob = bpy.data.objects[name]
        ob.data.materials.clear()
        ob.data.materials.append(mat)
        if not ob.data.uv_layers:
            ob.data.uv_layers.new(name="UVMap")


def png(name, size=32):
    """A colourful 8-bit sRGB PNG written to a temporary folder and loaded
    from there as a file image."""
    import bpy
    y, x = np.mgrid[0:size, 0:size] / size
    rgba = np.ones((size, size, 4), np.float32)
    rgba[..., 0] = 0.15 + 0.8 * (((x * 4).astype(int) + (y * 4).astype(int)) % 2)
    rgba[..., 1] = 0.2 + 0.7 * y
    rgba[..., 2] = 0.9 - 0.7 * x
    img = bpy.data.images.new(name, size, size)
    img.pixels.foreach_set(rgba.ravel())
    path = os.path.join(tempfile.mkdtemp(prefix="restir-tex-"), f"{name}.png")
    img.filepath_raw = path
    img.file_format = "PNG"
    img.save()
    bpy.data.images.remove(img)
    return bpy.data.images.load(path)


def spheres(specs):
    """Smooth UV spheres in place of the two boxes: (radius, (x, y), material)."""
    import bpy
    for name in ("TallBox", "ShortBox"):
        bpy.data.objects.remove(bpy.data.objects[name])
    for radius, (x, y), mat in specs:
        bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=radius,
                                             location=(x, y, radius + 0.002))
        ob = bpy.context.object
        ob.data.shade_smooth()
        ob.data.materials.append(mat)


def principled(name, **inputs):
    """A material of a Principled BSDF, inputs set by name ("Base Color": ...)."""
    mat, tree, out = new_material(name)
    p = tree.nodes.new("ShaderNodeBsdfPrincipled")
    for key, value in inputs.items():
        p.inputs[key].default_value = value
    tree.links.new(p.outputs[0], out.inputs["Surface"])
    return mat

