"""OpenVDB files for the volume object tests and the contact sheet, written
with the ``openvdb`` module Blender ships (restir_addon/export/volume_objects.py
finds it)."""

import numpy as np

N = 40


def lumpy_ball(n=N):
    """(n, n, n) float32 density: a ball falling off from 3 at its centre,
    modulated by waves along x and y."""
    x = (np.arange(n) - (n - 1) / 2) / (n / 2)
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    r = np.sqrt(X ** 2 + Y ** 2 + Z ** 2)
    return (3.0 * np.clip(1 - r, 0, None) ** 1.5 * (1 + 0.5 * np.sin(6 * X) * np.cos(5 * Y))).astype(np.float32)


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
