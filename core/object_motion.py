"""Objects' motion blur in Path Tracing: the shutter cut into time slices.

Embree (through embreex) has no motion blur of its own, so the shutter is
cut into slices: each slice renders its share of the samples with the moving
objects placed where they are at the slice's middle time (their triangles,
corner normals and face normals moved rigidly by the object's matrix then
against its matrix at the frame) and the camera there too, in a scene and an
acceleration structure of its own; the slices' films are summed. Up to
MAX_SLICES slices of at least two samples each.

Deforming objects (armatures, shape keys, animated modifiers: Cycles'
deformation blur) bring their triangles' corners in world space at the
shutter's steps instead; a slice puts them where linear interpolation
between the two steps around its time does (Cycles interpolates its motion
steps linearly too), on vertices of their own; their corner normals are
interpolated alike, and their face normals follow the triangles.
"""

import copy
import dataclasses
from dataclasses import dataclass

import numpy as np
from .camera.film import Film
from .camera.motion import rigid_at
from .geometry.accel import Accel
from .integrators import transparency
from .integrators.base import RenderContext
from .lights.light_set import LightSet
from .util.vectors import normalize

MAX_SLICES = 32


@dataclass
class ShutterMotion:
    """Moving objects over the shutter: their object ids (M,), world matrices
    (M, K, 4, 4) at K evenly spaced shutter times, and (M, 4, 4) at the
    frame (where the scene's arrays put them)."""
    object_ids: np.ndarray
    matrices: np.ndarray
    at_frame: np.ndarray
    # Deforming objects: {object id: (K, T_i, 2, 3, 3) world-space corner
    # positions and corner normals of its triangles (in the scene's order) at
    # the K shutter steps}.
    corners: dict = dataclasses.field(default_factory=dict)

    @staticmethod
    def of(scene, by_key, deformed=None):
        """ShutterMotion of the scene's objects whose matrices over the shutter
        (by_key: {object key: (K, 4, 4)}) differ from their frame's, and of
        those whose triangles deform (deformed: {object key: (K, T, 2, 3, 3)}
        world-space corner positions and normals, taken where the triangle
        count matches the scene's); None if nothing moves."""
        keys = list(getattr(scene, "object_keys", None) or ())
        frame = np.asarray(getattr(scene, "object_matrices", np.zeros((0, 4, 4))), np.float64)
        counts = np.bincount(np.asarray(scene.object_ids, np.int64), minlength=len(keys)) \
            if deformed else None
        ids, mats, corners = [], [], {}
        for i, key in enumerate(keys):      # (the scene's objects, not its rays)
            c = (deformed or {}).get(key)
            if c is not None and c.ndim == 5 and c.shape[1] == counts[i] and np.isfinite(c).all() \
                    and not np.allclose(c[:, :, 0], c[:1, :, 0], atol=1e-7):
                corners[i] = np.asarray(c, np.float32)
                continue
            m = by_key.get(key)
            if m is None or i >= len(frame):
                continue
            m = np.asarray(m, np.float64)
            if np.isfinite(m).all() and not np.allclose(m, frame[i][None], atol=1e-7):
                ids.append(i)
                mats.append(m)
        if not ids and not corners:
            return None
        ids = np.asarray(ids, np.int64)
        return ShutterMotion(ids, np.stack(mats) if mats else np.zeros((0, 2, 4, 4)),
                             frame[ids] if len(ids) else np.zeros((0, 4, 4)), corners)

    def corners_at(self, object_id, time):
        """(positions (T, 3, 3), unit normals (T, 3, 3)) of a deforming
        object's triangle corners at shutter time ``time``."""
        c = self.corners[object_id]
        x = float(np.clip(time, 0.0, 1.0)) * (len(c) - 1)
        k = min(int(x), len(c) - 2)
        f = x - k
        both = (1.0 - f) * c[k] + f * c[k + 1]
        n = both[:, 1]
        length = np.linalg.norm(n, axis=2, keepdims=True)
        n = np.where(length > 1e-30, n / np.maximum(length, 1e-30), c[k, :, 1])
        return both[:, 0], n

    def at(self, time):
        """(M, 4, 4) matrices taking each moving object from the frame to
        shutter time ``time`` in [0, 1]."""
        out = np.empty((len(self.object_ids), 4, 4))
        for j in range(len(self.object_ids)):      # (the moving objects)
            r, t = rigid_at(self.matrices[j], np.array([time]))
            m = np.eye(4)
            # rotation and translation interpolated; the axes' lengths (scale) the frame's
            m[:3, :3] = r[0] * np.linalg.norm(self.at_frame[j][:3, :3], axis=0)[None, :]
            m[:3, 3] = t[0]
            inv = np.linalg.pinv(self.at_frame[j])
            out[j] = m @ inv
        return out


def scene_at(scene, motion, time):
    """A shallow copy of the scene with the moving objects and the camera at
    shutter time ``time``."""
    out = copy.copy(scene)
    moves = motion.at(time)
    tri_obj = np.asarray(scene.object_ids)
    index = np.full(max(int(tri_obj.max(initial=-1)) + 1, 1), -1, np.int64)
    index[motion.object_ids[motion.object_ids < len(index)]] = np.nonzero(motion.object_ids < len(index))[0]
    tri_move = index[np.clip(tri_obj, 0, len(index) - 1)]
    moving = np.nonzero(tri_move >= 0)[0]
    vertices = np.array(scene.vertices, np.float64)
    tris = np.asarray(scene.triangles)[moving]
    vert_move = np.full(len(vertices), -1, np.int64)
    vert_move[tris.ravel()] = np.repeat(tri_move[moving], 3)
    rows = np.nonzero(vert_move >= 0)[0]
    m = moves[vert_move[rows]]
    vertices[rows] = np.einsum("nij,nj->ni", m[:, :3, :3], vertices[rows]) + m[:, :3, 3]
    out.vertices = vertices.astype(np.float32)
    lin = moves[tri_move[moving]][:, :3, :3]
    normal_m = np.linalg.inv(lin).transpose(0, 2, 1)
    normals = np.array(scene.normals, np.float32)
    nn = np.einsum("nij,nkj->nki", normal_m, normals[moving].astype(np.float64))
    normals[moving] = (nn / np.maximum(np.linalg.norm(nn, axis=2, keepdims=True), 1e-30)).astype(np.float32)
    out.normals = normals
    if scene.face_normals is not None:
        faces = np.array(scene.face_normals, np.float32)
        fn = np.einsum("nij,nj->ni", normal_m, faces[moving].astype(np.float64))
        faces[moving] = (fn / np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-30)).astype(np.float32)
        out.face_normals = faces
    if motion.corners:
        _place_deformed(out, motion, time, tri_obj)
    out.known_bounds = None
    camera = scene.camera
    if getattr(camera, "motion", None) is not None:
        r, t = rigid_at(camera.motion, np.array([time]))
        to_world = np.eye(4, dtype=np.float32)
        to_world[:3, :3], to_world[:3, 3] = r[0], t[0]
        camera = dataclasses.replace(camera, to_world=to_world, motion=None)
    out.camera = camera
    out.shutter_motion = None
    return out


def _place_deformed(out, motion, time, tri_obj):
    """The deforming objects' triangles of ``out`` at ``time``, on new vertices."""
    vertices, triangles = [out.vertices], np.array(out.triangles)
    normals = np.array(out.normals, np.float32)
    faces = None if out.face_normals is None else np.array(out.face_normals, np.float32)
    base = len(out.vertices)
    for oid in motion.corners:
        rows = np.nonzero(tri_obj == oid)[0]
        c, cn = motion.corners_at(oid, time)
        c = c.astype(np.float32)
        if len(c) != len(rows):
            continue
        normals[rows] = cn
        vertices.append(c.reshape(-1, 3))
        triangles[rows] = base + np.arange(3 * len(rows)).reshape(-1, 3)
        base += 3 * len(rows)
        if faces is not None:
            faces[rows] = normalize(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]))
    out.vertices = np.concatenate(vertices).astype(np.float32)
    out.triangles = triangles.astype(np.int32)
    out.normals = normals
    if faces is not None:
        out.face_normals = faces


def render_blurred(render_frame, ctx, settings, frame, on_sample=None, should_stop=None):
    """render_frame (core/render.py's, handed over) with the scene's
    ShutterMotion: the samples split over time slices (see the module notes);
    a Film of all of them."""
    scene = ctx.scene
    motion = scene.shutter_motion
    # At least two samples a slice: with one, each slice's only sample is its
    # sequences' first point, and the images came out further from Cycles'
    # than their noise says (block chi 3.5 against 1.75 with two).
    slices = max(1, min(int(settings.samples) // 2, MAX_SLICES))
    counts = np.full(slices, settings.samples // slices)
    counts[:settings.samples % slices] += 1
    film = Film(scene.width, scene.height)
    # Jittered strata: each slice's time uniform within it, by the seed and frame.
    jitter = np.random.default_rng([int(settings.seed) & 0xFFFFFFFF, int(frame) & 0xFFFFFFFF]).random(slices)
    for k in range(slices):
        if should_stop is not None and should_stop():
            break
        s = scene_at(scene, motion, (k + jitter[k]) / slices)
        accel = Accel.from_scene(s)
        sub_ctx = RenderContext(s, transparency.wrap(accel, s), LightSet(s), ctx.eps, ctx.workers)
        before = film.count
        try:
            def merged(f, seconds):
                if on_sample is not None:
                    on_sample(_merge(film, f), seconds)
            sub = render_frame(sub_ctx, dataclasses.replace(settings, samples=int(counts[k]),
                                                           seed=settings.seed + 7919 * (k + 1)),
                               frame, on_sample=merged, should_stop=should_stop)
        finally:
            accel.close()
        film = _merge(film, sub)
        if film.count == before:
            break
    return film


def _merge(a, b):
    """The film of the samples of both."""
    out = Film(a.width, a.height)
    out.count = a.count + b.count
    out.sum = a.sum + b.sum
    out.sum_lum2 = a.sum_lum2 + b.sum_lum2
    out.aov_sum = {k: a.aov_sum.get(k, 0) + b.aov_sum.get(k, 0) for k in set(a.aov_sum) | set(b.aov_sum)}
    return out
