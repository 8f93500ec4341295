"""Blender's depsgraph read into core scenes and kept between frames, only what
changed read again: shared by final renders (frame_scene.py) and the viewport
(scene_sync.py). Imports core and restir_addon.export."""
