"""Blender's cameras: primary rays and projection back to pixels (projection.py,
panorama.py), the pixel filter, and the film with its image files (film.py).
Imports core.util, core.sampling and core.scene."""
