"""Temporal resampling: last frame's reservoirs reused through reprojection.

Each visible point is carried to where it was last frame (the object's previous
transform, then the previous camera), the pixel there is accepted only if its
surface was similar (normal and depth tests), and that pixel's reservoir is
merged with this frame's new sample, its history capped at M_cap.
"""

from dataclasses import dataclass

import numpy as np

from ..camera.projection import project
from .reservoirs import NARROW_MIN_PIXELS, StoredReservoirs, bytes_per_row
from .reservoirs import finalize, merge
from ..util.vectors import dot
from ..util.rows import gather
from .accumulation import COLUMNS
from .denoise import MOMENTS
from .shift import J_MAX, J_MIN, jacobian, shift_weight, target_at
from .similarity import DEPTH_REL_MAX, NORMAL_COS_MIN


@dataclass
class FrameHistory:
    """What the next frame needs of this one (full-image arrays, one row per pixel)."""
    width: int
    height: int
    camera: object
    p: np.ndarray           # (P, 3) visible points
    n: np.ndarray           # (P, 3) shading normals
    ng: np.ndarray          # (P, 3) geometric normals
    depth: np.ndarray       # (P,) view depth
    valid: np.ndarray       # (P,) bool
    object_id: np.ndarray   # (P,) int32
    object_keys: list       # object key of each object id
    object_matrices: np.ndarray  # (O, 4, 4)
    signature: tuple        # resolution and scene sizes the reservoirs refer to
    temporal: StoredReservoirs
    spatial: StoredReservoirs   # (the temporal ones without spatial reuse)
    noise_hold: np.ndarray = None   # (P,) int8 frames left of "direct light noisy" (adaptive_direct)
    visibility: np.ndarray = None   # (P,) int8 spatial samples' visibility states (shading.py)
    sky_share: np.ndarray = None    # (P,) float16 the sky rays' share of the light around each pixel
                                    # (sky.pixel_shares)
    accumulation: object = None     # running means of the shaded frames (accumulation.py)
    # Where each reservoir's sample was drawn from, as carried by
    # carry_with_objects (None: the visible points p).
    temporal_owner: np.ndarray = None
    spatial_owner: np.ndarray = None
    # Each pixel's first initial sample's weight, and the frame number and
    # stream index its random numbers came from (gradients.py draws it again).
    sample_value: np.ndarray = None
    frame: int = None
    index: int = None
    # Each pixel's light probe (light_probes.py), in frames where objects moved.
    light_probe: np.ndarray = None

    def owners(self, spatial=False):
        """(P, 3) the points each pixel's temporal (or spatial) reservoir's
        sample reconnects from, for the shift's Jacobian."""
        o = self.spatial_owner if spatial else self.temporal_owner
        return self.p if o is None else o


# Per pixel of the G-buffer history: p, n, ng (3 x float32 x 3), depth
# (float32), valid (bool), object id (int32), the first initial sample's
# weight (float32); noise hold and visibility (int8); in frames where objects
# moved and frames are accumulated, the light probe (float32).
_GBUFFER_BYTES = 3 * 3 * 4 + 4 + 1 + 4 + 4
_FLAG_BYTES = 1 + 1
_PROBE_BYTES = 4


def state_bytes_per_pixel(accumulating=True, pixels=NARROW_MIN_PIXELS, denoise=False, moving=True):
    """Bytes per pixel of what a frame of ``pixels`` pixels keeps for the
    next (FrameHistory): the temporal and spatial reservoirs (narrowed from
    NARROW_MIN_PIXELS on: reservoirs.py), the G-buffer history, two
    flags and, when frames are accumulated, the running means, with the
    denoiser's moments when it is on, and where objects move (``moving``:
    the most a frame keeps) the light probes (docs/memory.md)."""
    return (2 * bytes_per_row(pixels, kept=True) + _GBUFFER_BYTES + _FLAG_BYTES
            + ((COLUMNS + (MOMENTS if denoise else 0)) * 4 + (_PROBE_BYTES if moving else 0)
               if accumulating else 0))


def _object_motions(scene, history):
    """For every current object that also was in the last frame and moved:
    {current object id: (last frame's object id, 4x4 current -> last frame)}.
    All objects' matrices are compared in one pass (a scene of 20,000
    instances spent 1.5 s a frame comparing them one by one)."""
    keys, mats = scene.object_keys, scene.object_matrices
    if not keys or not history.object_keys:
        return {}
    prev_index = {k: i for i, k in enumerate(history.object_keys)}
    j = np.array([prev_index.get(k, -1) for k in keys], np.int64)
    both = np.nonzero(j >= 0)[0]
    if len(both) == 0:
        return {}
    cur = np.asarray(mats, np.float64).reshape(-1, 4, 4)[both]
    prev = np.asarray(history.object_matrices, np.float64).reshape(-1, 4, 4)[j[both]]
    # np.allclose's test (rtol 1e-5 of the previous value, atol 1e-7), per object.
    still = (np.abs(cur - prev) <= 1e-7 + 1e-5 * np.abs(prev)).all(axis=(1, 2))
    go = np.nonzero(~still)[0]
    if len(go) == 0:
        return {}
    invertible = np.abs(np.linalg.det(cur[go])) > 1e-300
    go = go[invertible]
    to_prev = prev[go] @ np.linalg.inv(cur[go]) if len(go) else np.zeros((0, 4, 4))
    return {int(both[g]): (int(j[both[g]]), m) for g, m in zip(go, to_prev)}


@dataclass
class ObjectMotion:
    """How the objects moved since last frame, found once per frame."""
    to_previous: np.ndarray     # (O, 4, 4) per current object id: current -> last frame
                                # (identity where an object is new or did not move)
    moved_now: np.ndarray       # (O,) bool over current object ids
    moved_before: np.ndarray    # (O_prev,) bool over last frame's object ids
    to_current: np.ndarray = None   # (O_prev, 4, 4) per last frame's object id: last frame -> current

    @classmethod
    def between(cls, scene, history):
        """The motion from last frame to this one, or None if nothing moved."""
        moved = _object_motions(scene, history) if history is not None else {}
        if not moved:
            return None
        out = cls(np.tile(np.eye(4, dtype=np.float64), (len(scene.object_keys), 1, 1)),
                  np.zeros(len(scene.object_keys), bool), np.zeros(len(history.object_keys), bool),
                  np.tile(np.eye(4, dtype=np.float64), (len(history.object_keys), 1, 1)))
        for i, (j, to_prev) in moved.items():
            out.to_previous[i] = to_prev
            out.to_current[j] = np.linalg.inv(to_prev)
            out.moved_now[i], out.moved_before[j] = True, True
        return out

    def of(self, object_id):
        """Per-row 4x4 matrices for rows on the given (current) object ids."""
        return self.to_previous[np.maximum(object_id, 0)]

    def carry_forward(self, object_id, valid, points=(), normals=()):
        """Rows of last frame (object ids ``object_id`` (N,), ``valid`` (N,))
        that lie on objects that moved since, and their ``points`` and
        ``normals`` arrays' rows carried to where those objects are now (in
        place). Returns the rows (K,)."""
        on = valid & (object_id >= 0)
        on[on] = self.moved_before[np.clip(object_id[on], 0, len(self.moved_before) - 1)]
        rows = np.flatnonzero(on)
        if len(rows):
            _move_rows(self.to_current[object_id[rows]], rows, points=points, normals=normals)
        return rows


def _move_rows(m, rows, points=(), directions=(), normals=()):
    """Apply the (K, 4, 4) matrices m, one per row index in ``rows``, to
    those rows of point, direction and normal arrays, in place."""
    lin = m[:, :3, :3]
    for a in points:
        a[rows] = (np.einsum("kij,kj->ki", lin, a[rows].astype(np.float64)) + m[:, :3, 3]).astype(np.float32)
    for a in directions:
        _turn_rows(a, rows, lin)
    if normals:
        normal_m = np.transpose(np.linalg.inv(lin), (0, 2, 1))
        for a in normals:
            _turn_rows(a, rows, normal_m)


def _turn_rows(a, rows, mat):
    """Rows of unit vectors a, turned by the (K, 3, 3) mat and renormalised, in place."""
    v = np.einsum("kij,kj->ki", mat, a[rows].astype(np.float64))
    a[rows] = (v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-30)).astype(np.float32)


def carry_with_objects(scene, history):
    """Move last frame's state with the objects that moved since: the sample
    points (with their normals and directions) lying on moved objects, so
    reuse reconnects to where those surfaces are now, and with each of them
    the point it was drawn from (history.owners), so the shift's Jacobian
    sees the geometry the sample was drawn in, carried rigidly. A sample on
    a static surface keeps its owner where it was, whether or not the owner's
    own object moved: the Jacobian of the shift from there to this frame's
    visible point is the true one. (Moving owners with their own objects
    made every sample of a moving box look as if drawn from where the box is
    now: the quick-start example's sliding box, lit by the sunlit floor in
    front of it, got a sixth of its indirect light.) In place; returns the
    number of samples moved."""
    moved = _object_motions(scene, history)
    if not moved or scene.triangle_count == 0:
        return 0
    sets = [history.temporal]
    if history.spatial is not history.temporal \
            and not np.shares_memory(history.spatial.x2, history.temporal.x2):
        sets.append(history.spatial)
    # Each object's last frame -> current matrix, read per sample by the
    # object its triangle belongs to (all moved objects in one pass).
    ids = np.fromiter(moved, np.int64, len(moved))
    to_cur = np.linalg.inv(np.stack([moved[i][1] for i in ids]))
    slot = np.full(len(scene.object_keys), -1, np.int64)
    slot[ids] = np.arange(len(ids))
    count = 0
    owners = []
    for res in sets:
        owner = history.p.copy()
        oid = np.take(scene.object_ids, np.maximum(res.prim2, 0))
        which = np.where(res.prim2 >= 0, slot[oid], -1)
        on = np.nonzero(which >= 0)[0]
        if len(on):
            m = to_cur[which[on]]
            moving = res.take(on)
            every = np.arange(len(on))
            _move_rows(m, every, points=(moving.x2,), directions=(moving.wo2,), normals=(moving.ng2, moving.n2))
            res.put(on, moving)
            _move_rows(m, on, points=(owner,))
            count += len(on)
        owners.append(owner)
    history.temporal_owner = owners[0]
    history.spatial_owner = owners[-1]
    return count


def reproject(scene, gb, history, motion=False):
    """Previous-frame pixel of every pixel (-1 where history is rejected).
    motion: ObjectMotion.between(scene, history) if the caller has it."""
    n = len(gb.valid)
    prev_pix = np.full(n, -1, np.int64)
    if history is None or (history.width, history.height) != (gb.width, gb.height):
        return prev_pix
    idx = gb.index
    p = gb.surf.p.astype(np.float64)
    nrm = gb.surf.ns.astype(np.float64)
    if motion is False:
        motion = ObjectMotion.between(scene, history)
    if motion is not None:
        motion = motion.of(gb.object_id[idx])
        p = np.einsum("nij,nj->ni", motion[:, :3, :3], p) + motion[:, :3, 3]
        nrm = np.einsum("nij,nj->ni", motion[:, :3, :3], nrm)
        nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-30)
    film, depth = project(history.camera, gb.width, gb.height, p)
    x = np.floor(film[:, 0]).astype(np.int64)
    y = np.floor(film[:, 1]).astype(np.int64)
    inside = (x >= 0) & (x < gb.width) & (y >= 0) & (y < gb.height) & (depth > 0)
    q = np.where(inside, y * gb.width + x, 0)
    ok = inside & history.valid[q]
    ok &= dot(nrm.astype(np.float32), history.n[q]) >= NORMAL_COS_MIN
    ok &= np.abs(history.depth[q] - depth) <= DEPTH_REL_MAX * np.maximum(depth, 1e-6)
    prev_pix[idx] = np.where(ok, q, -1)
    return prev_pix


def temporal_resample(initial, gb, history, prev_pix, u, M_cap, max_age, biased):
    """This frame's temporal reservoirs: the reprojected history merged with the
    new samples, finalised with 1/M (biased) or, unbiased, weighted by the
    balance heuristic between the two (generalized RIS, Lin et al. 2022)."""
    ok = prev_pix >= 0
    if history is None or not ok.any():
        return initial.copy()
    # (initial is already finalised by the caller)
    q = np.where(ok, prev_pix, 0)
    prev = history.temporal.take(q)
    prev.M = np.minimum(prev.M, M_cap).astype(np.float32)
    prev.age += 1
    ok &= prev.age <= max_age
    p, ng, ns = gb.p, gb.ng, gb.n
    owner = gather(history.owners(), q)
    w_prev = np.where(ok, shift_weight(prev, owner, p, ng, ns, biased), 0.0)
    m_prev = np.where(ok, prev.M, 0.0).astype(np.float32)
    if biased:
        res = _merged(prev, w_prev, m_prev, initial, initial.w_sum, u)
        return finalize(res, target_at(res, p, ng, ns))
    # Unbiased: each candidate's weight carries its balance-heuristic share
    # m(y) = M p_A(y) / sum_i M_i p_A,i(y) (area measure at the sample point:
    # target_at at each visible point, over the shift's Jacobian), and W =
    # w_sum / p_hat(y). The history counts for a sample only where last
    # frame's visible point could have held it (in front of it, the shift
    # accepted); visibility is left out, as it was with 1/Z: with it the
    # carried weights compounded into fireflies. Against 1/Z, a new sample
    # the history cannot hold no longer carries the whole history's weight
    # (M up to the cap) alone: that made W of a dim sample hundreds of times
    # its pixel's mean (fireflies held 16 frames by the running means).
    ng_h, ns_h = gather(history.ng, q), gather(history.n, q)
    share_prev = _history_share(prev, owner, ng_h, ns_h, p, ng, ns, m_prev, initial.M)
    share_new = 1.0 - _history_share(initial, owner, ng_h, ns_h, p, ng, ns, m_prev, initial.M)
    with np.errstate(invalid="ignore", divide="ignore"):
        w_prev = np.where(m_prev > 0, w_prev * share_prev / np.where(m_prev > 0, m_prev, 1.0), 0.0)
    # The new reservoir's weight is share p_hat W with W = w_sum / (M p_hat)
    # (it was finalised with 1/M): w_sum share / M. Without the 1 / M, a
    # frame of several initial samples (settings.samples) counted them M
    # times over (indirect light 0.87 against 0.53 with two).
    w_new = initial.w_sum * share_new / np.maximum(initial.M, np.float32(1))
    res = _merged(prev, w_prev, m_prev, initial, w_new, u)
    return finalize(res, target_at(res, p, ng, ns), np.ones(len(res.M), np.float32))


def _merged(prev, w_prev, m_prev, initial, w_new, u):
    """The history's reservoirs (weights w_prev, counts m_prev) with each
    row's new sample streamed in (weight w_new)."""
    res = prev
    res.w_sum = w_prev.astype(np.float32)
    res.M = m_prev.copy()
    res.prim2 = np.where(w_prev > 0, res.prim2, -1)
    merge(res, initial, w_new, initial.M, u)
    # A reservoir without a contributing sample holds nothing that can go
    # stale: its age must not run out, or its count of dark candidates (M)
    # would be dropped and the next bright sample over-weighted.
    res.age[res.w_sum <= 0] = 0
    return res


def _history_share(res, owner, ng_h, ns_h, p, ng, ns, m_prev, m_new):
    """Balance heuristic share of the history (counts m_prev, visible points
    owner) in each row's sample of res, against the new samples (counts
    m_new) at this frame's visible points p: M_h p_h / (M_h p_h + M_c p_c J)
    with p_* the target in solid angle at each point and J the shift's
    Jacobian from owner to p (zero where the history cannot hold the sample)."""
    p_h = target_at(res, owner, ng_h, ns_h)
    p_c = target_at(res, p, ng, ns)
    j = jacobian(owner, p, res.x2, res.ng2)
    p_h = np.where((j >= J_MIN) & (j <= J_MAX), p_h, 0.0)
    a = m_prev * p_h
    den = a + m_new * p_c * j
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(den > 0, a / np.where(den > 0, den, 1.0), 0.0)
    return share.astype(np.float32)
