"""Reference optics in scalar Python, for checking the vectorised code."""

import math


def fresnel_ref(theta_i, eta):
    """Unpolarised Fresnel from the angle forms: R_s = sin^2(ti - tt) / sin^2(ti + tt),
    R_p = tan^2(ti - tt) / tan^2(ti + tt)."""
    s = math.sin(theta_i) / eta
    if s >= 1:
        return 1.0
    if theta_i == 0:
        return ((eta - 1) / (eta + 1)) ** 2
    tt = math.asin(s)
    rs = (math.sin(theta_i - tt) / math.sin(theta_i + tt)) ** 2
    rp = (math.tan(theta_i - tt) / math.tan(theta_i + tt)) ** 2
    return 0.5 * (rs + rp)
