"""Blender materials to core materials: one shader graph per material.

Every material becomes the plain graph of its node tree (node_graph.py); the
core runs it on hits (core/shader/). The constant table row of a material is
a neutral placeholder the graph overrides; only row 0, the default for faces
without a material, is used as is (Cycles' default surface: grey diffuse).
"""

from .images import ImageCache
from .node_graph import material_graph

NEUTRAL = {"name": "neutral", "base_color": (0.8, 0.8, 0.8), "roughness": 0.5, "specular": 0.5}


class MaterialTable:
    """Material ids keyed by the original material, id 0 the default; the
    graphs, their images (an ImageCache) and the corner data they read."""

    def __init__(self, warn, images=None):
        self.warn = warn
        self.images = images if images is not None else ImageCache(warn)
        self.rows = [dict(NEUTRAL)]
        self.graphs = [None]
        self.index = {}

    def id_of(self, mat):
        if mat is None:
            return 0
        key = mat.original.as_pointer()
        if key not in self.index:
            self.index[key] = len(self.rows)
            self.rows.append(dict(NEUTRAL, name=mat.name))
            self.graphs.append(self._graph(mat))
        return self.index[key]

    def _graph(self, mat):
        graph = material_graph(mat, self.images)
        for text in graph.warnings:
            self.warn(f"Material '{mat.name}': {text}")
        graph.warnings = []
        return graph

    def needs(self, ids):
        """The corner data keys the graphs of material ids read."""
        out = set()
        for i in ids:
            g = self.graphs[i] if 0 <= i < len(self.graphs) else None
            if g is not None:
                out |= set(g.needs)
        return out

    def refresh(self, mat_original, depsgraph):
        """Re-read one material; True if its graph changed."""
        i = self.index.get(mat_original.as_pointer())
        if i is None:
            return False
        graph = self._graph(mat_original.evaluated_get(depsgraph))
        if repr(graph) == repr(self.graphs[i]):
            return False
        self.graphs[i] = graph
        return True

    def snapshot(self):
        """(Materials table, graphs, images) as they are now, for the render side."""
        return self.table(), list(self.graphs), dict(self.images.images)

    def table(self):
        from ...core import Materials   # noqa: PLC0415
        return Materials.from_list(self.rows)
