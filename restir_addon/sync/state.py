"""Bookkeeping of the viewport session: counters of the work done, the
depsgraph updates as sync reads them, and the changes waiting for the render
side."""

from dataclasses import dataclass, field


from ...core.scene import Camera, Lights


@dataclass
class Work:
    """What the session did, counted (tests assert on these)."""
    full_exports: int = 0           # whole depsgraph read (first sync)
    mesh_exports: int = 0           # meshes read from Blender (a full export reads them all)
    object_walks: int = 0           # passes over the depsgraph's instances (matrices only)
    transform_updates: int = 0      # placed objects whose matrix changed
    triangle_updates: int = 0       # times triangle arrays were rewritten (whole or in part)
    accel_static_builds: int = 0    # Embree builds of the static scene (all but moving objects)
    accel_dynamic_builds: int = 0   # Embree builds of the small scene of moving objects
    material_updates: int = 0
    light_updates: int = 0
    world_updates: int = 0
    camera_updates: int = 0
    resizes: int = 0
    settings_updates: int = 0
    frames: int = 0                 # frames (or path-traced samples) rendered
    abandoned_frames: int = 0       # frames dropped mid-way for an edit, a resize or close


@dataclass
class Update:
    """One entry of depsgraph.updates, reduced to what sync needs."""
    id: object                      # the original ID
    transform: bool
    geometry: bool
    shading: bool


def as_update(item):
    """An Update from a DepsgraphUpdate or from a tuple (id, transform, geometry, shading)."""
    if isinstance(item, Update):
        return item
    if isinstance(item, tuple):
        return Update(*item)
    return Update(getattr(item.id, "original", item.id), bool(item.is_updated_transform),
                  bool(item.is_updated_geometry), bool(item.is_updated_shading))




@dataclass
class Pending:
    """Changes read by sync, waiting for the render side (merged until applied)."""
    instances: dict = None          # latest key -> Instance snapshot, if objects changed
    moved: set = field(default_factory=set)      # matrix changed
    remeshed: set = field(default_factory=set)   # mesh re-read (or new object)
    reslotted: set = field(default_factory=set)  # material slots changed
    animated: set = field(default_factory=set)   # keys of objects with animation (may move)
    layout: bool = False            # objects added or removed
    full: bool = False              # a full export: build everything afresh
    materials: tuple = None          # (Materials table, shader graphs, images)
    lights: Lights = None
    world: tuple = None              # (Environment or None,)
    volumes: list = None             # volume objects' GridMedium list
    camera: Camera = None
    size: tuple = None              # display size
    filter_width: float = None
    film_transparent: bool = None
    settings: bool = False
    generation: int = 0

    def empty(self):
        return (self.instances is None and self.materials is None and self.lights is None
                and self.world is None and self.volumes is None and self.camera is None and self.size is None
                and self.filter_width is None and self.film_transparent is None
                and not self.settings)


