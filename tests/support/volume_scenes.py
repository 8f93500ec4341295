"""Volume object scenes for tests/oracle/test_volume_objects.py,
bench/bench_volumes.py and the contact sheet: OpenVDB files written with the
``openvdb`` module Blender ships (restir_addon/export/volume_objects.py finds
it), volume objects and their materials, the stage they stand on."""

import math

import numpy as np

N = 40


def lumpy_ball(n=N):
    """(n, n, n) float32 density: a ball falling off from 3 at its centre,
    modulated by waves along x and y."""
    x = (np.arange(n) - (n - 1) / 2) / (n / 2)
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    r = np.sqrt(X ** 2 + Y ** 2 + Z ** 2)
    return (3.0 * np.clip(1 - r, 0, None) ** 1.5 * (1 + 0.5 * np.sin(6 * X) * np.cos(5 * Y))).astype(np.float32)


def colour_waves(n=N):
    """(n, n, n, 3) float32 colours: red rising along x, green falling,
    blue waving along z."""
    x = np.linspace(0.0, 1.0, n)
    X, _, Z = np.meshgrid(x, x, x, indexing="ij")
    return np.stack([X, 1.0 - X, 0.5 + 0.5 * np.sin(6 * Z)], axis=-1).astype(np.float32)


def write_vdb(path, grids, voxel=2.0 / N):
    """Write {name: array} as one .vdb file: (n, n, n) arrays as float grids,
    (n, n, n, 3) ones as vector grids, voxel (0, 0, 0) at the origin."""
    from restir_gi.restir_addon.export.volume_objects import openvdb_module
    vdb = openvdb_module()
    assert vdb is not None, "Blender's builds (and the bpy module) ship the openvdb module"
    out = []
    for name, arr in grids.items():
        vector = arr.ndim == 4
        g = vdb.Vec3SGrid() if vector else vdb.FloatGrid()
        g.name = name
        g.copyFromArray(arr, ijk=(0, 0, 0), tolerance=(0.0, 0.0, 0.0) if vector else 0.0)
        g.transform = vdb.createLinearTransform(voxelSize=voxel)
        out.append(g)
    vdb.write(str(path), grids=out)
    return str(path)


def stage(width=64, height=48):
    import bpy
    from support.addon_util import add_mesh, camera, fresh, rect, world
    from support.blender_util import diffuse_material
    scene = fresh(width, height)
    world((0.2, 0.25, 0.3))
    add_mesh("Floor", *rect(-4, 4, -4, 4), mat=diffuse_material("Floor", (0.6, 0.6, 0.6)))
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 3.0
    ob = bpy.data.objects.new("Sun", sun)
    ob.rotation_euler = (0.6, 0.3, 0.5)
    scene.collection.objects.link(ob)
    camera(location=(1.0, -4.0, 2.0), rotation=(math.radians(75), 0, 0), lens=35)
    return scene


def volume_object(path, name="Smoke", material=None):
    import bpy
    vol = bpy.data.volumes.new(name)
    vol.filepath = path
    ob = bpy.data.objects.new(name, vol)
    ob.location = (0.0, 0.0, 0.2)
    bpy.context.scene.collection.objects.link(ob)
    if material is not None:
        vol.materials.append(material)
    return ob


def smoke_material(case):
    """A volume material: the Principled Volume of the case (with a
    blackbody for "fire", a colour grid for "color"), or a Volume Scatter whose Density an Attribute
    node feeds ("attribute_scatter")."""
    import bpy
    mat = bpy.data.materials.new(case)
    tree = mat.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    out = tree.nodes["Material Output"]
    if case == "attribute_scatter":
        node = tree.nodes.new("ShaderNodeVolumeScatter")
        node.inputs["Color"].default_value = (0.6, 0.8, 0.9, 1)
        node.inputs["Anisotropy"].default_value = 0.4
        attr = tree.nodes.new("ShaderNodeAttribute")
        attr.attribute_name = "density"
        tree.links.new(attr.outputs["Fac"], node.inputs["Density"])
    else:
        node = tree.nodes.new("ShaderNodeVolumePrincipled")
        node.inputs["Color"].default_value = (0.8, 0.6, 0.4, 1)
        node.inputs["Density"].default_value = 2.0
        if case == "emission":
            node.inputs["Emission Strength"].default_value = 0.5
            node.inputs["Emission Color"].default_value = (1.0, 0.5, 0.2, 1)
        if case == "color":
            node.inputs["Color Attribute"].default_value = "color"
            node.inputs["Color"].default_value = (0.9, 0.9, 0.9, 1)
            node.inputs["Absorption Color"].default_value = (0.2, 0.3, 0.1, 1)
        if case in ("fire", "fire_without_grid"):
            node.inputs["Blackbody Intensity"].default_value = 1.0
            node.inputs["Temperature"].default_value = 1500.0
            node.inputs["Density"].default_value = 0.3         # thin smoke: the glow shows
            node.inputs["Blackbody Tint"].default_value = (1.0, 0.9, 0.8, 1)
    tree.links.new(node.outputs[0], out.inputs["Volume"])
    return mat, node
