"""What tests share: scenes, Blender helpers, statistics. Tests import from
here, never from each other."""
