"""Camera motion over the shutter (motion blur): the camera's matrices at
evenly spaced times across the shutter (Cycles' motion steps: start, centre
and end by default), and each ray's own camera, interpolated between them
as Cycles does: translation linearly, rotation by quaternion slerp, scale
linearly (the axes' lengths; rays only use the unit axes).
"""

import numpy as np


def _quaternions(r):
    """(K, 4) unit quaternions (w, x, y, z) of rotation matrices r (K, 3, 3)."""
    q = np.empty((len(r), 4))
    tr = np.trace(r, axis1=1, axis2=2)
    for i, m in enumerate(r):        # the few matrices of the shutter's steps
        if tr[i] > 0:
            s = np.sqrt(tr[i] + 1.0) * 2
            q[i] = (0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s)
        else:
            k = int(np.argmax(np.diag(m)))
            a, b = (k + 1) % 3, (k + 2) % 3
            s = np.sqrt(max(1.0 + m[k, k] - m[a, a] - m[b, b], 1e-30)) * 2
            v = np.zeros(3)
            v[k] = 0.25 * s
            v[a] = (m[a, k] + m[k, a]) / s
            v[b] = (m[b, k] + m[k, b]) / s
            q[i] = ((m[b, a] - m[a, b]) / s, *v)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    for i in range(1, len(q)):       # the short way round from one step to the next
        if np.dot(q[i], q[i - 1]) < 0:
            q[i] = -q[i]
    return q


def _rotation(q):
    """(N, 3, 3) rotation matrices of unit quaternions q (N, 4)."""
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1)], axis=1)


def _slerp(a, b, t):
    cos = np.clip((a * b).sum(axis=1), -1.0, 1.0)
    angle = np.arccos(cos)
    sin = np.sin(angle)
    small = sin < 1e-6
    wa = np.where(small, 1.0 - t, np.sin((1.0 - t) * angle) / np.where(small, 1.0, sin))
    wb = np.where(small, t, np.sin(t * angle) / np.where(small, 1.0, sin))
    q = wa[:, None] * a + wb[:, None] * b
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def rigid_at(matrices, time):
    """(rotation (N, 3, 3), translation (N, 3)) of the camera at shutter
    times ``time`` (N,) in [0, 1], from its matrices (K, 4, 4) at K evenly
    spaced times."""
    m = np.asarray(matrices, np.float64)
    axes = m[:, :3, :3] / np.maximum(np.linalg.norm(m[:, :3, :3], axis=1, keepdims=True), 1e-30)
    # Re-orthonormalise (a sheared matrix is not a rotation).
    u, _, vt = np.linalg.svd(axes)
    rot = u @ vt
    q = _quaternions(rot)
    k = len(m)
    x = np.clip(np.asarray(time, np.float64), 0.0, 1.0) * (k - 1)
    i = np.minimum(x.astype(np.int64), k - 2) if k > 1 else np.zeros(len(x), np.int64)
    f = x - i if k > 1 else np.zeros(len(x))
    j = np.minimum(i + 1, k - 1)
    r = _rotation(_slerp(q[i], q[j], f))
    t = m[i, :3, 3] * (1.0 - f)[:, None] + m[j, :3, 3] * f[:, None]
    return r, t
