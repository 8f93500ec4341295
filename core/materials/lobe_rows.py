"""Optional lobes of per-hit BSDF parameters scattered into a batch's.

Most rows of a batch have no glass, sheen, velvet, single-scattering or
exact-Fresnel share; BSDFParams leaves such fields None until some row has
one. ``add_lobes`` writes the optional fields of rows' parameters into the
batch's, creating each field (its neutral value elsewhere) on first use.
"""

import numpy as np

from ..util.rows import scatter


# Fields of BSDFParams and the value rows without the lobe take.
GLASS = (("glass_r", 0.0), ("glass_t", 0.0), ("ior", 1.0), ("alpha_g", 1.0), ("p_glass", 0.0), ("eta", 1.0))
SHEEN = (("sheen", 0.0), ("sheen_rough", 0.5))
# Lobes a batch keeps once any row has them: the leading field, and its fields.
KEPT = (("sheen_free", (("sheen_free", 0.0),)),
        ("spec_ss", (("spec_ss", 0.0),)),                            # None: multiscatter
        ("velvet", (("velvet", 0.0), ("velvet_sigma", 0.5))),
        ("f_exact", (("f_exact", 0.0), ("spec_ior", 1.5))))         # None: Schlick's
COLOURS = {"glass_r", "glass_t", "sheen", "velvet", "f_exact"}


def add_lobes(params, rows, p):
    """Scatter the optional lobes of rows' parameters p into params."""
    rows = np.asarray(rows)
    if p.has_glass:
        for name, neutral in GLASS:
            _put(params, rows, name, getattr(p, name), neutral)
        params.p_spec[rows] = p.p_spec
    if p.sheen is not None:
        for name, neutral in SHEEN:
            _put(params, rows, name, getattr(p, name), neutral)
    for lead, names in KEPT:
        if lead == "sheen_free" and p.sheen is None:
            continue
        given = getattr(p, lead) is not None
        if given or getattr(params, lead) is not None:
            for name, neutral in names:
                _put(params, rows, name, getattr(p, name) if given else None, neutral)


def _put(params, rows, name, value, neutral):
    """params.<name>[rows] = value (``neutral`` where value is None), the
    field made first, ``neutral`` in every row, if params has none."""
    field = getattr(params, name)
    if field is None:
        shape = (len(params.alpha), 3) if name in COLOURS else (len(params.alpha),)
        field = np.full(shape, neutral, np.float32)
        setattr(params, name, field)
    value = neutral if value is None else value
    if field.ndim == 2:
        scatter(field, rows, value)
    else:
        field[rows] = value
