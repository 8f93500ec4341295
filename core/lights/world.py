"""The world's node graph as an Environment light (core/lights/environment.py).

A graph that does not depend on the direction becomes a constant world; any
other is evaluated on whole batches of directions, for the importance map at
build time and for every ray that escapes. A sky's sun disc is sampled
apart from the map (Environment's ``sun``), as Cycles' sun guiding does.
The map's resolution follows Cycles' automatic choice: the width of the
largest image the world reads (at most MAX_RESOLUTION), else
DEFAULT_RESOLUTION.
"""

import numpy as np

from ..materials.shader.evaluate import CompiledShader
from ..materials.shader.geometry import WorldGeometry
from ..materials.shader.sky import sky_model
from .environment import Environment

DEFAULT_RESOLUTION = 1024
MAX_RESOLUTION = 4096


def world_environment(graph, images=None, warn=None):
    """An Environment for the world graph, or None for a black world."""
    if graph is None or graph.output is None:
        return None
    shader = CompiledShader(graph, images, warn)
    if shader.uniform:
        rgb = shader.closure(WorldGeometry(np.float32([[0, 0, 1]]))).get("emission", 1)[0]
        return Environment.constant_color(rgb) if (rgb > 0).any() else None

    def radiance(d):
        d = np.asarray(d, np.float32)
        return shader.closure(WorldGeometry(d)).get("emission", len(d))

    widths = [img.width for key in _image_keys(graph) for s in [(images or {}).get(key)] if s is not None
              for img in s.tiles.values()]
    resolution = min(max(widths), MAX_RESOLUTION) if widths else DEFAULT_RESOLUTION
    env = Environment(radiance, resolution=resolution, sun=_sun(graph))
    if any(n.kind == "LIGHT_PATH" for n in graph.nodes):
        # Is Camera Ray etc.: the background the camera sees differs from the light.
        def camera_radiance(d):
            d = np.asarray(d, np.float32)
            return np.nan_to_num(shader.closure(WorldGeometry(d, camera_ray=True)).get("emission", len(d)),
                                 nan=0.0, posinf=0.0, neginf=0.0).astype(np.float32)
        env.camera_radiance = camera_radiance
    return None if env.is_black else env


def _sun(graph):
    """(direction, half angle) of the first sky's sun disc, which the
    environment samples apart from its map (a disc half a degree wide is
    smaller than a texel: the map alone would find it by chance, a firefly
    each time). Only a sky read along the ray itself (no Vector linked) puts
    its sun where its parameters say."""
    for n in graph.nodes:
        if n.kind == "TEX_SKY" and "Vector" not in n.inputs:
            model = sky_model(n.props)
            if model is not None and getattr(model, "has_sun", False):
                return model.sun_direction, model.diameter / 2
    return None


def _image_keys(graph):
    return [n.props.get("image") for n in graph.nodes if n.kind in ("TEX_ENVIRONMENT", "TEX_IMAGE")]
