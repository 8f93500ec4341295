"""The flat scene the renderer consumes: plain numpy arrays, world space.

The Blender layer (or a test) fills these; nothing here knows about Blender.
Units and conventions follow Cycles so the same .blend renders with the same
brightness: light power in watts, sun strength as irradiance (W/m^2), emission
strength and world strength as radiance.
"""

import hashlib
from dataclasses import dataclass, field, fields

import numpy as np

# Light types.
LIGHT_POINT = 0
LIGHT_SPOT = 1
LIGHT_SUN = 2
LIGHT_AREA = 3

# Area light shapes.
SHAPE_SQUARE = 0
SHAPE_RECTANGLE = 1
SHAPE_DISK = 2
SHAPE_ELLIPSE = 3


@dataclass
class Materials:
    """Material table; triangles index it by material id (row 0 is the default)."""
    base_color: np.ndarray      # (M, 3) float32
    metallic: np.ndarray        # (M,) float32
    roughness: np.ndarray       # (M,) float32
    specular: np.ndarray        # (M,) float32, Principled "Specular IOR Level" (0.5 = IOR's own)
    ior: np.ndarray             # (M,) float32
    emission: np.ndarray        # (M, 3) float32 radiance = colour x strength
    names: list = field(default_factory=list)

    @staticmethod
    def from_list(rows):
        """rows: dicts with any of base_color, metallic, roughness, specular, ior, emission, name."""
        rows = list(rows) or [{}]

        def col(key, default, width=None):
            vals = [r.get(key, default) for r in rows]
            arr = np.asarray(vals, dtype=np.float32)
            return arr.reshape(len(rows), width) if width else arr.reshape(len(rows))

        return Materials(
            base_color=col("base_color", (0.8, 0.8, 0.8), 3),
            metallic=col("metallic", 0.0),
            roughness=col("roughness", 0.5),
            specular=col("specular", 0.0),
            ior=col("ior", 1.5),
            emission=col("emission", (0.0, 0.0, 0.0), 3),
            names=[r.get("name", f"material_{i}") for i, r in enumerate(rows)],
        )

    def __len__(self):
        return len(self.metallic)


@dataclass
class Lights:
    """Analytic lights, one row each (emissive triangles are found from materials)."""
    kind: np.ndarray            # (L,) int32, LIGHT_*
    position: np.ndarray        # (L, 3) float32
    direction: np.ndarray       # (L, 3) float32, unit, where the light points (local -Z)
    axis_u: np.ndarray          # (L, 3) float32, unit, local +X (area lights)
    axis_v: np.ndarray          # (L, 3) float32, unit, local +Y (area lights)
    power: np.ndarray           # (L, 3) float32, W for point/spot/area, W/m^2 for sun
    radius: np.ndarray          # (L,) float32, point/spot sphere radius
    spot_size: np.ndarray       # (L,) float32, full cone angle in radians
    spot_blend: np.ndarray      # (L,) float32
    angle: np.ndarray           # (L,) float32, sun angular diameter in radians
    shape: np.ndarray           # (L,) int32, SHAPE_*
    size_u: np.ndarray          # (L,) float32, area extent along axis_u
    size_v: np.ndarray          # (L,) float32, area extent along axis_v
    soft_falloff: np.ndarray    # (L,) bool, point/spot act as a disk facing the receiver
    camera_visible: np.ndarray  # (L,) bool, camera rays see the light (Blender's default: no)
    names: list = field(default_factory=list)
    # (L, 3) bool: hidden from diffuse, glossy, transmission rays (None: from none)
    hidden_kinds: np.ndarray = None
    # (L,) bool: the light's samples are not tested for occlusion (Cast Shadow
    # off); None: every light casts shadows
    shadowless: np.ndarray = None
    # Light Falloff in the light's node tree (Cycles' svm light falloff):
    # radiance times d^falloff (0 quadratic, the physical falloff; 1 linear;
    # 2 constant) and, where falloff_smooth s > 0, times d^2 / (s + d^2), d
    # the distance from the shading point to the light sample. Suns: none.
    falloff: np.ndarray = None          # (L,) float32
    falloff_smooth: np.ndarray = None   # (L,) float32

    @staticmethod
    def empty():
        return Lights.from_list([])

    @staticmethod
    def from_list(rows):
        """rows: dicts with kind and whichever fields apply; the rest default."""
        rows = list(rows)
        n = len(rows)

        def col(key, default, dtype=np.float32, width=None):
            vals = [r.get(key, default) for r in rows]
            shape = (n, width) if width else (n,)
            return np.asarray(vals, dtype=dtype).reshape(shape)

        return Lights(
            kind=col("kind", LIGHT_POINT, np.int32),
            position=col("position", (0, 0, 0), width=3),
            direction=col("direction", (0, 0, -1), width=3),
            axis_u=col("axis_u", (1, 0, 0), width=3),
            axis_v=col("axis_v", (0, 1, 0), width=3),
            power=col("power", (0, 0, 0), width=3),
            radius=col("radius", 0.0),
            spot_size=col("spot_size", np.pi / 4),
            spot_blend=col("spot_blend", 0.15),
            angle=col("angle", 0.0),
            shape=col("shape", SHAPE_SQUARE, np.int32),
            size_u=col("size_u", 1.0),
            size_v=col("size_v", 1.0),
            soft_falloff=col("soft_falloff", True, bool),
            camera_visible=col("camera_visible", False, bool),
            names=[r.get("name", f"light_{i}") for i, r in enumerate(rows)],
            hidden_kinds=col("hidden_kinds", (False, False, False), bool, width=3),
            shadowless=col("shadowless", False, bool),
            falloff=col("falloff", 0.0),
            falloff_smooth=col("falloff_smooth", 0.0),
        )

    def __len__(self):
        return len(self.kind)


@dataclass
class Camera:
    """Blender camera model: looks down local -Z with +Y up, sensor in mm."""
    to_world: np.ndarray = field(default_factory=lambda: np.eye(4, dtype=np.float32))
    projection: str = "PERSP"   # or "ORTHO", "PANO"
    lens: float = 50.0          # focal length, mm
    sensor_width: float = 36.0
    sensor_height: float = 24.0
    sensor_fit: str = "AUTO"    # AUTO, HORIZONTAL, VERTICAL
    ortho_scale: float = 6.0
    shift_x: float = 0.0
    shift_y: float = 0.0
    clip_start: float = 0.1
    clip_end: float = 1000.0
    # Depth of field (a thin lens, as Cycles): aperture radius in scene units
    # (0: a pinhole), the distance along the view axis that is in focus, and
    # the aperture's shape: blades (0, or 3 and more for a polygon), their
    # rotation (radians) and the anamorphic ratio (x is divided by it).
    aperture_size: float = 0.0
    focus_distance: float = 10.0
    aperture_blades: int = 0
    aperture_rotation: float = 0.0
    aperture_ratio: float = 1.0
    # Panoramic cameras (projection "PANO", core/camera/panorama.py): Cycles'
    # panorama type, the equirectangular latitude and longitude ranges
    # (radians), the fisheyes' field of view (radians) and equisolid lens
    # (mm); pano_region: (x0, y0, W, H), where a render region's film lies in
    # the full image (None: the film is the full image).
    panorama_type: str = "EQUIRECTANGULAR"
    latitude_min: float = -np.pi / 2
    latitude_max: float = np.pi / 2
    longitude_min: float = -np.pi
    longitude_max: float = np.pi
    fisheye_fov: float = np.pi
    fisheye_lens: float = 10.5
    fisheye_polynomial_k0: float = 0.0      # lens polynomial fisheye: theta = -(k0 + k1 r + ... + k4 r^4)
    fisheye_polynomial_k1: float = -0.02
    fisheye_polynomial_k2: float = 0.0
    fisheye_polynomial_k3: float = 0.0
    fisheye_polynomial_k4: float = 0.0
    central_cylindrical_range_u_min: float = -np.pi
    central_cylindrical_range_u_max: float = np.pi
    central_cylindrical_range_v_min: float = -1.0
    central_cylindrical_range_v_max: float = 1.0
    central_cylindrical_radius: float = 1.0
    pano_region: tuple = None
    # Motion blur (core/camera/motion.py): the camera's matrices (K, 4, 4) at K
    # evenly spaced times over the shutter, None without blur; to_world stays
    # the frame's (depth, reprojection).
    motion: np.ndarray = None


@dataclass
class Scene:
    """Triangles in world space plus materials, lights, world and camera."""
    vertices: np.ndarray        # (V, 3) float32
    triangles: np.ndarray       # (T, 3) int32 indices into vertices
    normals: np.ndarray         # (T, 3, 3) float32 shading normal per corner
    uvs: np.ndarray             # (T, 3, 2) float32
    material_ids: np.ndarray    # (T,) int32 into materials
    object_ids: np.ndarray      # (T,) int32, which exported object a triangle came from
    materials: Materials
    lights: Lights
    camera: Camera
    world_color: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))  # radiance
    # The world as a light (core/lights/environment.py's Environment: an HDRI, a sky);
    # None: a constant world of radiance world_color (LightSet builds it).
    environment: object = None
    # The world's Volume output (Cycles' world volume): a homogeneous medium
    # filling the space outside the objects' media, as a volume dict of
    # core/integrators/media.py (sigma_a, sigma_s, emission, g); None: none.
    world_volume: dict = None
    # Volume objects' voxel grids as heterogeneous media
    # (core/integrators/grid_media.py's GridMedium each).
    volume_grids: list = field(default_factory=list)
    width: int = 64
    height: int = 64
    filter_width: float = 1.5   # pixel filter width in pixels (Blackman-Harris, as Cycles)
    warnings: list = field(default_factory=list)
    # Placed objects: a key stable across frames and the world matrix of each
    # object id, so temporal reuse can follow moving objects.
    object_keys: list = field(default_factory=list)
    object_matrices: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4), np.float32))
    face_normals: np.ndarray = None   # (T, 3) unit geometric normals (make_scene fills them)
    # (geometry, lighting) change counters, from a builder that knows what it
    # changed (the viewport): the keys below are then these instead of digests.
    versions: tuple = None
    # Shader node graphs (core/materials/shader/graph.py), one per material id or None
    # where the Materials row says all; images they read by key
    # (core/materials/texture.py); corner data they read beyond scene.uvs, by the
    # graphs' ``needs`` keys (core/materials/shader/geometry.py); per-object values of
    # the Object Info node ("Color" (O, 3), "Random" (O,), "Alpha" (O,)).
    shaders: list = field(default_factory=list)
    images: dict = field(default_factory=dict)
    corner_data: dict = field(default_factory=dict)
    object_info: dict = field(default_factory=dict)
    # Blender's ray visibility per object id: (O, 3) bool for camera rays,
    # shadow rays and every other ray (Diffuse); None: visible to all.
    ray_visibility: np.ndarray = None
    # Per object id, a holdout for the camera (Object or collection Holdout):
    # camera rays see a hole, other rays the object (None: no such object).
    object_holdout: np.ndarray = None
    # Film > Transparent: the world seen directly is left out and the image
    # gets an alpha of the pixels' coverage by geometry.
    film_transparent: bool = False
    # Shadow rays of smooth-shaded triangles start from the smooth surface
    # near the terminator (core/integrators/terminator.py): Cycles' Geometry
    # Offset, its default for every object (0: off).
    shadow_terminator: float = 0.1
    # (lo, hi) of the vertices, from a builder that keeps them per object
    # (the add-on); None: computed on first use and kept while ``vertices``
    # is the same array, as a frame asks several times (ray offsets, the
    # lights, the world's distance) and a pass over 1M vertices takes some
    # 5 ms. Vertices edited in place belong in a new Scene.
    known_bounds: tuple = None

    @property
    def triangle_count(self):
        return len(self.triangles)

    def bounds(self):
        if self.known_bounds is None:
            cached = self.__dict__.get("_bounds_of")
            if cached is None or cached[0] is not self.vertices:
                cached = self._bounds_of = (self.vertices, *column_bounds(self.vertices))
            lo, hi = cached[1:]
        else:
            lo, hi = self.known_bounds
        return lo.copy(), hi.copy()

    def extent(self):
        """Diagonal of the bounding box (at least 1e-3), used for ray offsets."""
        lo, hi = self.bounds()
        return max(float(np.linalg.norm(hi - lo)), 1e-3)

    def geometry_key(self):
        """A digest of the triangles and where they are: equal keys mean every
        ray hits what it hit before (visibility is unchanged)."""
        if self.versions is not None:
            return b"geometry version %d" % self.versions[0]
        return _digest([self.vertices, self.triangles])

    def lighting_key(self, geometry_key=None, shading_key=None):
        """A digest of everything that decides the light leaving a surface point
        (geometry, materials, lights, world), but not the camera or the image:
        equal keys mean a path traced again with the same seed gives the same
        radiance. geometry_key, shading_key: this scene's, if the caller has them."""
        if self.versions is not None:
            return b"lighting version %d.%d" % tuple(self.versions)
        return _digest([self.normals, self.material_ids], (geometry_key or self.geometry_key())
                       + (shading_key or self.shading_key()))

    def shading_key(self):
        """A digest of the lights, the materials and the world alone: a change
        relights every surface, whatever the geometry did in the same frame."""
        if self.versions is not None:
            return b"shading version %d" % self.versions[1]
        arrays = [self.world_color]
        arrays += [getattr(self.materials, f.name) for f in fields(Materials) if f.name != "names"]
        arrays += [getattr(self.lights, f.name) for f in fields(Lights) if f.name != "names"]
        if self.shaders:
            # Graphs are small plain data: their text names every constant.
            shapes = sorted((k, getattr(v, "shape", None)) for k, v in self.images.items())
            arrays.append(np.frombuffer(repr((self.shaders, shapes)).encode(), np.uint8))
        world = self.environment.digest() if self.environment is not None else b""
        if self.world_volume is not None:
            world += repr(sorted(self.world_volume.items())).encode()
        for g in self.volume_grids or ():
            world += g.digest()
        return _digest(arrays, world)


def _digest(arrays, prefix=b""):
    """SHA-1 of the arrays' types, shapes and bytes: a change detector, not a
    security measure (SHA-NI makes it fast)."""
    h = hashlib.sha1(prefix)
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.data)
    return h.digest()


def column_bounds(points):
    """(lo, hi) of (N, 3) points, zeros when empty. One 1-D reduction per
    column: numpy's axis-0 min over a (N, 3) array is some 40x slower."""
    if len(points) == 0:
        return np.zeros(3, np.float32), np.zeros(3, np.float32)
    lo = np.array([points[:, k].min() for k in range(3)], points.dtype)
    hi = np.array([points[:, k].max() for k in range(3)], points.dtype)
    return lo, hi


def make_scene(vertices, triangles, material_ids=None, materials=None, lights=None,
               camera=None, world_color=(0, 0, 0), normals=None, uvs=None,
               object_ids=None, width=64, height=64, filter_width=1.5, corner_data=None):
    """Build a Scene from minimal arrays, computing flat normals where none are given,
    and removing degenerate or non-finite triangles (with a warning)."""
    v = np.ascontiguousarray(vertices, dtype=np.float32).reshape(-1, 3)
    t = np.ascontiguousarray(triangles, dtype=np.int32).reshape(-1, 3)
    n_tri = len(t)
    mids = np.zeros(n_tri, np.int32) if material_ids is None else np.asarray(material_ids, np.int32)
    oids = np.zeros(n_tri, np.int32) if object_ids is None else np.asarray(object_ids, np.int32)
    mats = materials if materials is not None else Materials.from_list([{}])
    warnings = []

    keep = np.ones(n_tri, bool)
    if n_tri:
        in_range = (t >= 0).all(axis=1) & (t < len(v)).all(axis=1)
        keep &= in_range
        tc = np.where(in_range[:, None], t, 0)
        p = v[tc]
        finite = np.isfinite(p).all(axis=(1, 2))
        cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        with np.errstate(invalid="ignore", over="ignore"):
            area2 = np.einsum("ij,ij->i", cross, cross)
        n_bad = int((in_range & ~finite).sum())
        n_degenerate = int((in_range & finite & ~((area2 > 0) & np.isfinite(area2))).sum())
        keep &= finite & (area2 > 0) & np.isfinite(area2)
        if n_bad:
            warnings.append(f"Skipped {n_bad} triangle(s) with non-finite vertex coordinates")
        if n_degenerate:
            warnings.append(f"Skipped {n_degenerate} degenerate (zero-area) triangle(s)")
        if int((~in_range).sum()):
            warnings.append(f"Skipped {int((~in_range).sum())} triangle(s) with invalid vertex indices")
    # Vertices no kept triangle uses may still be non-finite: they must not
    # reach the scene bounds (and every ray offset derived from them).
    v = np.where(np.isfinite(v), v, 0.0).astype(np.float32)
    mids = np.where((mids >= 0) & (mids < len(mats)), mids, 0).astype(np.int32)

    t, mids, oids = t[keep], mids[keep], oids[keep]
    p = v[t] if len(t) else np.zeros((0, 3, 3), np.float32)
    ng = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]) if len(t) else np.zeros((0, 3), np.float32)
    ng = (ng / np.maximum(np.linalg.norm(ng, axis=1, keepdims=True), 1e-30)).astype(np.float32)
    if normals is None:
        ns = np.repeat(ng[:, None, :], 3, axis=1)
    else:
        ns = np.asarray(normals, np.float32).reshape(-1, 3, 3)[keep]
        ns = np.where(np.isfinite(ns), ns, 0.0)
    if uvs is None:
        uv = np.zeros((len(t), 3, 2), np.float32)
    else:
        uv = np.asarray(uvs, np.float32).reshape(-1, 3, 2)[keep]

    return Scene(
        vertices=v, triangles=np.ascontiguousarray(t), normals=np.ascontiguousarray(ns, np.float32),
        uvs=np.ascontiguousarray(uv, np.float32), material_ids=mids, object_ids=oids,
        materials=mats, lights=lights if lights is not None else Lights.empty(),
        camera=camera if camera is not None else Camera(),
        world_color=np.asarray(world_color, np.float32).reshape(3),
        width=int(width), height=int(height), filter_width=float(filter_width), warnings=warnings,
        face_normals=ng,
        corner_data={k: np.ascontiguousarray(np.asarray(c, np.float32)[keep])
                     for k, c in (corner_data or {}).items()})
