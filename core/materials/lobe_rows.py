"""Optional lobes of per-hit BSDF parameters scattered into a batch's.

Most rows of a batch have no glass, sheen, velvet, single-scattering or
exact-Fresnel share; BSDFParams leaves such fields None until some row has
one. ``add_lobes`` writes the optional fields of rows' parameters into the
batch's, creating each field (its neutral value elsewhere) on first use.
"""

import numpy as np

from ..util.rows import scatter


def add_lobes(params, rows, p):
    """Scatter the optional lobes of rows' parameters p into params."""
    if p.has_glass:
        _add_glass(params, rows, p)
    if p.sheen is not None:
        _add_sheen(params, rows, p)
    if p.spec_ss is not None or params.spec_ss is not None:
        _add_single_scatter(params, rows, p)
    if p.velvet is not None or params.velvet is not None:
        _add_velvet(params, rows, p)
    if p.f_exact is not None or params.f_exact is not None:
        _add_exact(params, rows, p)


def _add_glass(params, rows, p):
    """Scatter the glass lobe of rows' parameters p into params, creating the
    glass fields (zero elsewhere) on first use."""
    n = len(params.alpha)
    if not params.has_glass:
        params.glass_r = np.zeros((n, 3), np.float32)
        params.glass_t = np.zeros((n, 3), np.float32)
        params.ior = np.ones(n, np.float32)
        params.alpha_g = np.ones(n, np.float32)
        params.p_glass = np.zeros(n, np.float32)
        params.eta = np.ones(n, np.float32)
    scatter(params.glass_r, rows, p.glass_r)
    scatter(params.glass_t, rows, p.glass_t)
    for name in ("ior", "alpha_g", "p_glass", "eta", "p_spec"):
        getattr(params, name)[rows] = getattr(p, name)



def _add_sheen(params, rows, p):
    """Scatter the sheen of rows' parameters p into params, creating the
    sheen fields (no sheen elsewhere) on first use."""
    if params.sheen is None:
        params.sheen = np.zeros((len(params.alpha), 3), np.float32)
        params.sheen_rough = np.full(len(params.alpha), 0.5, np.float32)
    scatter(params.sheen, np.asarray(rows), p.sheen)
    params.sheen_rough[rows] = p.sheen_rough
    if p.sheen_free is not None or params.sheen_free is not None:
        if params.sheen_free is None:
            params.sheen_free = np.zeros(len(params.alpha), np.float32)
        params.sheen_free[rows] = 0.0 if p.sheen_free is None else p.sheen_free



def _add_velvet(params, rows, p):
    """Scatter the velvet lobe of rows' parameters p (None: none) into
    params, creating its fields (no velvet elsewhere) on first use."""
    if params.velvet is None:
        params.velvet = np.zeros((len(params.alpha), 3), np.float32)
        params.velvet_sigma = np.full(len(params.alpha), 0.5, np.float32)
    rows = np.asarray(rows)
    scatter(params.velvet, rows, 0.0 if p.velvet is None else p.velvet)
    params.velvet_sigma[rows] = 0.5 if p.velvet is None else p.velvet_sigma



def _add_single_scatter(params, rows, p):
    """Scatter the single-scattering share of rows' GGX lobes (p.spec_ss;
    None: multiscatter) into params, creating the field (zero elsewhere)
    on first use."""
    if params.spec_ss is None:
        params.spec_ss = np.zeros(len(params.alpha), np.float32)
    params.spec_ss[rows] = 0.0 if p.spec_ss is None else p.spec_ss



def _add_exact(params, rows, p):
    """Scatter the exact-Fresnel share of rows' GGX lobes (p.f_exact; None:
    Schlick's) into params, creating the fields (zero elsewhere) on first use."""
    if params.f_exact is None:
        params.f_exact = np.zeros((len(params.alpha), 3), np.float32)
        params.spec_ior = np.full(len(params.alpha), 1.5, np.float32)
    rows = np.asarray(rows)
    scatter(params.f_exact, rows, 0.0 if p.f_exact is None else p.f_exact)
    params.spec_ior[rows] = 1.5 if p.f_exact is None else p.spec_ior
