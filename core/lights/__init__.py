"""Emitters and their sampling: lamps (analytic.py), emissive triangles, the
world's environment map built from its shader (world.py, environment.py), and
the light grid that picks among them by place (light_set.py, light_grid.py).
Imports the layers below it, up to core.materials."""
