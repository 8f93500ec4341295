"""The ReSTIR GI renderer: numpy + Embree, no Blender imports.

Plain data in (``Scene``), plain data out (``Film``)."""

from .integrators.base import RenderContext
from .render import RenderSettings, render_frame
from .scene import Camera, Lights, Materials, Scene, make_scene

__all__ = ["Camera", "Lights", "Materials", "RenderContext", "RenderSettings", "Scene",
           "make_scene", "render_frame"]
