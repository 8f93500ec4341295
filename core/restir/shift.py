"""Reconnection shift: reusing another pixel's sample x2 at this pixel's visible point.

The sample keeps its point x2 and radiance; only the direction from the
receiver changes, so its solid-angle density changes by the Jacobian

    J = |cos phi_r| / |cos phi_q| * |x1_q - x2|^2 / |x1_r - x2|^2

(cos phi: angle at x2 between its normal and the direction to each visible point).
"""

import numpy as np

from ..integrators.base import shadow_rays
from .reservoirs import target
from ..util.rows import gather, scale
from ..util.vectors import dot

J_MIN, J_MAX = 0.1, 10.0          # beyond these a shift is rejected
J_CLAMP = (1.0 / 3.0, 3.0)        # biased mode clamps what is accepted


def jacobian(x1_from, x1_to, x2, ng2):
    """Solid-angle Jacobian of moving the sample x2 from visible point x1_from to x1_to."""
    a = x1_from - x2
    b = x1_to - x2
    da2 = dot(a, a)
    db2 = dot(b, b)
    cos_a = np.abs(dot(a, ng2)) / np.sqrt(np.maximum(da2, 1e-30))
    cos_b = np.abs(dot(b, ng2)) / np.sqrt(np.maximum(db2, 1e-30))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        j = (cos_b / cos_a) * (da2 / db2)
    return np.where(np.isfinite(j), j, 0.0).astype(np.float32)


def target_at(res, x1, ng1, ns1):
    """Target function p_hat of each reservoir's sample at receivers (x1, ng1, ns1):
    luminance of its radiance times the cosine at the receiver, zero where x2 is
    behind the receiver's surface or the receiver behind x2's."""
    to_x2 = res.x2 - x1
    dist = np.sqrt(np.maximum(dot(to_x2, to_x2), 1e-30))
    cos = dot(to_x2, ns1) / dist
    facing = (dot(to_x2, ng1) > 0) & (dot(-to_x2, res.ng2) > 0) & res.has_sample & (cos > 0)
    return np.where(facing, target(res.lo) * cos, 0.0).astype(np.float32)


def shift_weight(res, x1_owner, x1_receiver, ng_receiver, ns_receiver, biased):
    """Resampling weight p_hat_r(y) * W * M * J of reusing reservoirs at receivers."""
    lum_wm = np.where(res.has_sample, target(res.lo) * res.W * res.M, 0.0).astype(np.float32)
    return shift_weight_of(res.x2, res.ng2, lum_wm, x1_owner, x1_receiver, ng_receiver,
                           ns_receiver, biased)


def shift_weight_of(x2, ng2, lum_wm, x1_owner, x1_receiver, ng_receiver, ns_receiver, biased):
    """shift_weight from the sample points x2, their normals ng2 and each
    reservoir's luminance(Lo) W M (0 without a sample): target_at and jacobian
    in one pass over the shared terms."""
    p_r, j = shift_target(x2, ng2, lum_wm, x1_owner, x1_receiver, ng_receiver, ns_receiver)
    if biased:
        j = np.clip(j, *J_CLAMP)
    with np.errstate(invalid="ignore", over="ignore"):
        w = p_r * j
    return w.astype(np.float32)


def shift_target(x2, ng2, lum, x1_owner, x1_receiver, ng_receiver, ns_receiver):
    """Samples x2 (normals ng2, luminance(Lo) ``lum``) found from x1_owner, at
    receivers: (lum times the cosine at the receiver, zero where they do not
    face each other or the shift is rejected; the Jacobian J of the shift)."""
    b = x1_receiver - x2                      # from the sample to the receiver
    a = x1_owner - x2                         # from the sample to its owner
    db2 = np.maximum(dot(b, b), 1e-30)
    da2 = np.maximum(dot(a, a), 1e-30)
    inv_db = 1.0 / np.sqrt(db2)
    b_n2 = dot(b, ng2)                        # > 0: the receiver is in front of x2
    cos_r = -dot(b, ns_receiver) * inv_db     # cosine at the receiver
    facing = (dot(b, ng_receiver) < 0) & (b_n2 > 0) & (cos_r > 0)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        j = (b_n2 * inv_db) / (np.abs(dot(a, ng2)) / np.sqrt(da2)) * (da2 / db2)
    ok = facing & (j >= J_MIN) & (j <= J_MAX)
    with np.errstate(invalid="ignore", over="ignore"):
        p_r = np.where(ok, lum * cos_r, 0.0)
    return p_r, np.where(ok, j, 0.0)


def visible(ctx, x1, ng1, ns1, res, where=None):
    """True where x1 sees its row's sample point (and each faces the other);
    only rows where ``where`` is True are traced (the others are False)."""
    n = len(x1)
    out = np.zeros(n, bool)
    rows = None if where is None else np.nonzero(where)[0]
    if rows is not None:
        x1, ng1, ns1, res = gather(x1, rows), gather(ng1, rows), gather(ns1, rows), res.view(rows)
    ok = np.nonzero(target_at(res, x1, ng1, ns1) > 0)[0]
    if len(ok):
        x1_r = gather(x1, ok)
        to = gather(res.x2, ok) - x1_r
        dist = np.sqrt(np.maximum(dot(to, to), 1e-30))
        wi = scale(to, 1.0 / dist).astype(np.float32)
        blocked = ctx.accel.occluded(*shadow_rays(ctx, x1_r, gather(ng1, ok), wi, dist))
        out[ok if rows is None else rows[ok]] = ~blocked
    return out
