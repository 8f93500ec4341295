"""Rays against the scene: Embree scenes, static and dynamic (accel.py,
dynamic_accel.py), surface hits (interaction.py), and strands and points as
triangles (strands.py). Imports core.util, core.workers, core.sampling and
core.scene."""
