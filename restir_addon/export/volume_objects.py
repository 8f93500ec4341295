"""Volume objects (OpenVDB grids) as heterogeneous media
(core/integrators/grid_media.py).

A volume object's grids are read from its file through the ``openvdb``
module that Blender's builds ship in their Python (Blender's own Python API
names the grids and their transforms but gives no voxel values). The
object's material's Volume output gives the coefficients: a Principled
Volume's Density Attribute (``density`` by default), or an Attribute node
feeding a Density, names the grid that scales them; emission fills the
grid's box, as Cycles' Principled Volume does not scale it by the density.
A Principled Volume's blackbody takes its temperature from the grid its
Temperature Attribute names (``temperature``), times its Temperature.
A volume object without a material renders with Cycles' default volume
shader, a Principled Volume of its default values.

Not read, each with a warning: grids made or changed by modifiers or
Geometry Nodes (no file holds them), grids that are not scalar, a Blender
without the ``openvdb`` module. A grid of more than MAX_VOXELS is averaged
down in blocks.
"""

import glob
import importlib
import os
import sys

import numpy as np

import bpy

from ...core.integrators.grid_media import GridMedium, blackbody_emission
from ...core.integrators.media import C, coefficients
from .node_graph import _output_node
from .node_values import uses_nodes
from .volumes import GridShader, read_grid_volume

MAX_VOXELS = 1 << 25
SLAB_VOXELS = 1 << 24       # voxels copied at a time at full resolution (64 MB)
NONE = {"sigma_a": (0.0,) * 3, "sigma_s": (0.0,) * 3, "emission": (0.0,) * 3, "g": 0.0}
# Cycles' default volume shader: a Principled Volume of its defaults.
DEFAULT = GridShader(dict(NONE, sigma_a=(0.5,) * 3, sigma_s=(0.5,) * 3), NONE, ["density"], [], [])


def openvdb_module():
    """Blender's ``openvdb`` module, or None. Blender's builds ship it in
    their Python's site-packages, which Blender as a Python module does not
    put on the path."""
    try:
        return importlib.import_module("openvdb")
    except ImportError:
        pass
    base = bpy.utils.system_resource("PYTHON") if hasattr(bpy.utils, "system_resource") else ""
    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    for site in (os.path.join(base, "lib", version, "site-packages"), os.path.join(base, "lib", "site-packages")):
        if base and glob.glob(os.path.join(site, "openvdb*")) and site not in sys.path:
            sys.path.append(site)
            try:
                return importlib.import_module("openvdb")
            except ImportError:
                return None
    return None


def _shader(obj, warn):
    material = next((s.material for s in obj.material_slots if s.material is not None), None)
    if material is None or not uses_nodes(material) or material.node_tree is None:
        return DEFAULT
    output = _output_node(material.node_tree, ("OUTPUT_MATERIAL",))
    socket = output.inputs.get("Volume") if output is not None else None
    if socket is None or not socket.is_linked:
        return None
    return read_grid_volume(socket, lambda text: warn(f"Material '{material.name}': {text}"))


class GridFiles:
    """Voxel arrays read from .vdb files, kept while the file is unchanged
    (a viewport edit or the next frame of an animation reads it once)."""

    def __init__(self):
        self._cache = {}
        self._boxes = {}            # (path, grid) -> its box and blocks, for the grids read on it
        self._warned_module = False

    def read(self, path, name, warn):
        """(dense float32 array, index of its first voxel, block) of a scalar
        grid over its active voxels' box, or None."""
        return self._read(path, name, None, warn)

    def read_on(self, path, name, like, warn):
        """Grid ``name`` on the voxels of grid ``like`` (read first): its
        dense array over the same box and blocks, (nx, ny, nz, 3) for a
        vector grid; or None."""
        return self._read(path, name, like, warn)

    def _read(self, path, name, like, warn):
        try:
            stamp = os.stat(path).st_mtime_ns
        except OSError:
            warn(f"volume file '{path}' cannot be read")
            return None
        key = (path, name, like)
        hit = self._cache.get(key)
        if hit is not None and hit[0] == stamp:
            return hit[1]
        vdb = openvdb_module()
        if vdb is None:
            if not self._warned_module:
                warn("volume objects need the 'openvdb' Python module, which Blender's own builds ship and "
                     "this Blender lacks (a Linux distribution's Blender: install its python3-openvdb package); "
                     "they are not rendered")
                self._warned_module = True
            return None
        try:
            grid = vdb.read(path, name)
        except Exception as error:      # noqa: BLE001 -- a bad file must not stop a render
            warn(f"grid '{name}' of '{path}' cannot be read ({error})")
            return None
        kinds = ("float", "double") if like is None else ("float", "double", "vec3s", "vec3d")
        if grid.valueTypeName not in kinds:
            warn(f"grid '{name}' of '{path}' holds {grid.valueTypeName} values, not a scalar density")
            return None
        width = 3 if grid.valueTypeName.startswith("vec3") else 0
        if like is not None:
            box = self._boxes.get((path, like))
            if box is None:
                return None
            lo, dims, block = box
            out = _dense(grid, lo, dims, block, width) if dims is not None else None
        else:
            lo, hi = (np.asarray(x, np.int64) for x in grid.evalActiveVoxelBoundingBox())
            dims = hi - lo + 1
            if (dims <= 0).any() or grid.activeVoxelCount() == 0:
                out, dims, block = (np.zeros((1, 1, 1), np.float32), lo * 0, 1), None, 1
            else:
                block = 1
                while int(np.prod(-(-dims // block))) > MAX_VOXELS:
                    block += 1
                if block > 1:
                    warn(f"grid '{name}' of '{path}' ({dims[0]}x{dims[1]}x{dims[2]} voxels) is averaged "
                         f"down {block}x per axis")
                out = (_dense(grid, lo, dims, block), lo, block)
            self._boxes[(path, name)] = (lo, dims, block)
        self._cache[key] = (stamp, out)
        return out


def _dense(grid, lo, dims, block, width=0):
    """The grid's voxels over the box lo .. lo + dims - 1 as a dense float32
    array ((..., 3) for a vector grid: width 3), averaged over blocks of
    ``block`` voxels a side; copied in slabs along x so a sparse grid with a
    large box never needs its whole box in memory at full resolution."""
    out_dims = tuple(int(x) for x in -(-dims // block))
    tail = (width,) if width else ()
    out = np.zeros(out_dims + tail, np.float32)
    ny, nz = out_dims[1] * block, out_dims[2] * block
    layers = block * max(1, SLAB_VOXELS // max(ny * nz * max(width, 1), 1) // block)
    for x0 in range(0, int(dims[0]), layers):
        n = min(layers, -(-(int(dims[0]) - x0) // block) * block)
        slab = np.zeros((n, ny, nz) + tail, np.float32)
        grid.copyToArray(slab, ijk=(int(lo[0]) + x0, int(lo[1]), int(lo[2])))
        slab = slab.reshape((n // block, block, ny // block, block, nz // block, block) + tail).mean(axis=(1, 3, 5))
        out[x0 // block:x0 // block + len(slab)] = slab
    return out


def volume_grids(obj, matrix_world, files, warn):
    """The GridMedium list of one volume object instance."""
    vol = obj.data
    label = f"Volume '{obj.name}'"
    shader = _shader(obj, warn)
    if shader is None:
        return []
    scaled, constant, names, blackbody, colors = shader
    if any(m.show_render for m in getattr(obj.original, "modifiers", ())):
        warn(f"{label}: modifiers are not applied (the file's grids render)")
    try:
        vol.grids.load()
    except Exception:                   # noqa: BLE001
        pass
    path = vol.grids.frame_filepath if hasattr(vol.grids, "frame_filepath") else ""
    if not path and obj.original is not None:
        path = getattr(obj.original.data.grids, "frame_filepath", "") if obj.original.data else ""
    path = bpy.path.abspath(path, library=vol.library) if path else ""
    if not path or not os.path.isfile(path):
        if len(vol.grids):
            warn(f"{label}: its grids are not in a file (made by nodes or modifiers); it is not rendered")
        else:
            warn(f"{label}: no volume file; it is not rendered")
        return []
    bgrids = {g.name: g for g in vol.grids}
    name = next((n for n in names if n in bgrids), None)
    mask = name is None
    if mask:
        # No grid drives the density: the medium fills where the first
        # scalar grid is active, as Cycles fills the volume's bounds.
        name = next((g.name for g in vol.grids if g.data_type in ("FLOAT", "DOUBLE")), None)
        if names and name is not None:
            warn(f"{label}: no grid named {', '.join(repr(n) for n in names)}; the medium fills "
                 f"where grid '{name}' is active")
        if not names:
            scaled = dict(constant, emission=(0.0,) * 3)
            constant = dict(NONE, emission=constant["emission"])
    if name is None:
        warn(f"{label}: no scalar grid; it is not rendered")
        return []
    placed = _placed(files, path, bgrids[name], matrix_world, label, warn)
    if placed is None:
        return []
    out = []
    for grid_name, kelvin, intensity, tint in blackbody:
        temperature = bgrids.get(grid_name)
        hot = _placed(files, path, temperature, matrix_world, label, warn) \
            if temperature is not None and temperature.data_type in ("FLOAT", "DOUBLE") else None
        if hot is not None:
            out.append(GridMedium(hot[0], hot[1], np.zeros(C, np.float32), np.zeros(C, np.float32),
                                  name=f"{obj.name}:{grid_name}", blackbody=(kelvin, intensity, tint)))
        else:
            # Cycles: without the grid the Temperature holds everywhere.
            em = np.asarray(constant["emission"], np.float64) + blackbody_emission(kelvin, intensity) * tint
            constant = dict(constant, emission=tuple(float(x) for x in em))
    arr, to_index = placed
    if mask:
        arr = (arr > 0).astype(np.float32)
    medium = GridMedium(arr, to_index, coefficients(scaled), coefficients(constant), name=obj.name)
    for grid_name, base, factor, absorb, g in colors[:1] if not mask else ():
        tint = _colour_voxels(files, path, bgrids.get(grid_name), bgrids[name], arr.shape, label, warn)
        if tint is not None:
            medium.color = (tint, base, factor, absorb, g)
    return [medium] + out


def _colour_voxels(files, path, colour, density, shape, label, warn):
    """A colour grid's voxels on the density grid's (nx, ny, nz, 3), or None
    (with a warning where the grid is there but cannot be used)."""
    if colour is None:
        return None
    if colour.data_type not in ("VECTOR_FLOAT", "VECTOR_DOUBLE", "FLOAT"):
        warn(f"{label}: grid '{colour.name}' is not a colour; Color is used")
        return None
    if not np.allclose(np.array(colour.matrix_object), np.array(density.matrix_object)):
        warn(f"{label}: colour grid '{colour.name}' is not on the density's voxels; Color is used")
        return None
    voxels = files.read_on(path, colour.name, density.name, warn)
    if voxels is None or voxels.shape[:3] != tuple(shape):
        return None
    return voxels if voxels.ndim == 4 else np.repeat(voxels[..., None], 3, axis=-1)


def _placed(files, path, grid, matrix_world, label, warn):
    """(voxels, world-to-index matrix) of one of a volume's grids, or None."""
    read = files.read(path, grid.name, warn)
    if read is None:
        return None
    arr, lo, block = read
    index_to_object = np.array(grid.matrix_object, np.float64)
    shift = np.eye(4)
    shift[:3, :3] *= block
    shift[:3, 3] = lo + 0.5 * (block - 1)
    to_world = np.array(matrix_world, np.float64) @ index_to_object @ shift
    try:
        return arr, np.linalg.inv(to_world)
    except np.linalg.LinAlgError:
        warn(f"{label}: its transform is singular; it is not rendered")
        return None
