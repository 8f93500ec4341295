"""Media whose density a texture drives (a Noise Texture into a Principled
Volume's Density, in a closed mesh): Cycles evaluates the volume shader at
every step of its march; here the density's nodes (the material's
``volume_field`` graph, which the exporter translates from the Density
input) are evaluated once per scene on a lattice of RESOLUTION cells along
the longest side of each object's bounds, inside its mesh (the parity of
its faces crossed toward +x), and become a voxel grid
(core/integrators/grid_media.py). The grid's trilinear density then stands
for the texture: detail finer than a cell is smoothed, and the mesh's
surface is blurred over a cell.

Inputs the texture reads at a point: its position, object space and
Generated coordinates (the object's bounds in object space mapped to
[0, 1]^3, as a mesh's automatic texture space); no UV, normal or attribute.
"""

import numpy as np

from ..materials.shader.evaluate import CompiledShader, as_float, convert
from ..materials.shader.geometry import VolumeGeometry
from .grid_media import GridMedium

RESOLUTION = 64
CHUNK = 1 << 16
# Parity rays leave slightly off the axes, so they do not run along edges.
PARITY_DIRECTION = np.array([1.0, 0.0013, 0.0021], np.float32) / np.float32(np.sqrt(1 + 0.0013 ** 2 + 0.0021 ** 2))


def graph_fields(shaders):
    """{material id: density graph} of the graphs whose medium's density a
    texture drives."""
    return {i: g.volume_field for i, g in enumerate(shaders or ())
            if g is not None and getattr(g, "volume_field", None) is not None}


def density_of(scene, graph, points, object_id, box):
    """The density graph's output (N,) at world points inside one object."""
    shader = CompiledShader(graph, getattr(scene, "images", None))
    link = graph.output
    out = np.zeros(len(points), np.float32)
    if link is None:
        return out
    for start in range(0, len(points), CHUNK):
        geom = VolumeGeometry(scene, points[start:start + CHUNK], object_id, box)
        values = shader.outputs(geom)
        v = values[link.node].get(link.socket) if link.node < len(values) else None
        if v is not None:
            v = as_float(convert(v, link.from_type, link.to_type))
            out[start:start + CHUNK] = np.broadcast_to(np.asarray(v, np.float32).reshape(-1), (len(geom.position),))
    return np.maximum(np.nan_to_num(out, nan=0.0, posinf=0.0, neginf=0.0), 0.0)


def field_grids(scene, media, fields, rows):
    """GridMedium of each object with a textured medium: ``media`` is the
    Media whose boundaries hold the objects' faces, ``fields`` the density
    graphs by material, ``rows`` the coefficient rows per unit of density
    by material."""
    out = []
    if not fields or len(media.tri) == 0:
        return out
    mids = np.asarray(scene.material_ids)[media.tri]
    matrices = getattr(scene, "object_matrices", None)
    for mid, graph in fields.items():
        for oid in np.unique(media.obj[mids == mid]):
            mine = (mids == mid) & (media.obj == oid)
            m = np.asarray(matrices[oid], np.float64) if matrices is not None and oid < len(matrices) \
                else np.eye(4)
            try:
                inv = np.linalg.inv(m)
            except np.linalg.LinAlgError:
                continue
            verts = np.asarray(scene.vertices, np.float64)[np.asarray(scene.triangles)[media.tri[mine]]].reshape(-1, 3)
            local = verts @ inv[:3, :3].T + inv[:3, 3]
            lo, hi = local.min(axis=0), local.max(axis=0)
            extent = hi - lo
            voxel = max(float(extent.max()), 1e-6) / RESOLUTION
            dims = np.clip(np.ceil(extent / voxel - 1e-6), 1, RESOLUTION).astype(np.int64)
            cell = np.where(extent > 0, extent / dims, voxel)
            axes = [lo[k] + (np.arange(dims[k]) + 0.5) * cell[k] for k in range(3)]
            grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
            points = (grid @ m[:3, :3].T + m[:3, 3]).astype(np.float32)
            dens = density_of(scene, graph, points, oid, (lo, hi))
            dens *= _inside(media, points, mine)
            index_to_object = np.eye(4)
            index_to_object[:3, :3] = np.diag(cell)
            index_to_object[:3, 3] = lo + 0.5 * cell
            to_index = np.linalg.inv(m @ index_to_object)
            out.append(GridMedium(dens.reshape(tuple(dims)).astype(np.float32), to_index, rows[mid],
                                  np.zeros_like(rows[mid]), name=f"material {mid}, object {oid}"))
    return out


def _inside(media, points, mine):
    """1 where a point is inside the closed mesh of the boundary triangles
    ``mine`` (a mask over media.tri): an odd number of them crossed toward
    PARITY_DIRECTION; else 0."""
    inside = np.zeros(len(points), np.float32)
    for start in range(0, len(points), CHUNK):
        p = points[start:start + CHUNK]
        _, b = media.crossings(p, np.broadcast_to(PARITY_DIRECTION, p.shape))
        hits = (b >= 0) & mine[np.maximum(b, 0)]
        inside[start:start + CHUNK] = hits.sum(axis=1) % 2
    return inside
