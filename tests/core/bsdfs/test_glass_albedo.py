"""The rough glass lobe's albedo tables (core/bsdfs/glass_albedo.py): the
table against the mean weight of the lobe's own samples, and Cycles'
multiple-scattering compensation as a white furnace (white rough glass
passes on all it receives, entering and leaving), darker for a tint."""

import numpy as np
import pytest

from restir_gi.core.bsdfs import bsdf
from restir_gi.core.bsdfs.glass import glass_sample
from restir_gi.core.bsdfs.glass_albedo import glass_albedo

N = 300_000


def mean_weight(p, cos_wo, rng, channel=0):
    """Mean of f |cos| / pdf of params p's samples toward wo (zero where lost), and its standard error."""
    n = len(p.alpha)
    wo = np.tile(np.float32([np.sqrt(1 - cos_wo ** 2), 0.0, cos_wo]), (n, 1))
    wi, f, pdf = bsdf.sample(p, wo, rng.random(n, dtype=np.float32), rng.random((n, 2), dtype=np.float32))
    ok = pdf > 0
    w = np.where(ok, f[:, channel] * np.abs(wi[:, 2]) / np.where(ok, pdf, 1), 0.0)
    return w.mean(), w.std() / np.sqrt(n)


@pytest.mark.parametrize("rough, cos_wo, eta", [(0.5, 0.8, 1.45), (0.5, 0.8, 1 / 1.45), (0.8, 0.3, 1.45),
                                                (0.3, 0.5, 1 / 1.33), (0.9, 0.9, 2.0)])
def test01_table_is_the_lobes_albedo(rough, cos_wo, eta, rng):
    n = N
    wo = np.tile(np.float32([np.sqrt(1 - cos_wo ** 2), 0.0, cos_wo]), (n, 1))
    wi, f, pdf = glass_sample(wo, np.full(n, rough ** 2, np.float32), np.full(n, eta, np.float32),
                              np.ones((n, 3), np.float32), rng.random(n, dtype=np.float32),
                              rng.random((n, 2), dtype=np.float32), radiance=False)
    ok = pdf > 0
    w = np.where(ok, f[:, 0] * np.abs(wi[:, 2]) / np.where(ok, pdf, 1), 0.0)
    got = glass_albedo(np.float32([rough]), np.float32([cos_wo]), np.float32([eta]))[0]
    assert got == pytest.approx(w.mean(), abs=4 * w.std() / np.sqrt(n) + 4e-3)
    assert got < 1.0 or rough < 0.1


def glass_params(n, color, rough, eta):
    """A glass lobe reflecting white and refracting ``color``, as ShadingFrame makes it."""
    c = np.float32(color)
    p = bsdf.lobe_params(np.zeros((n, 3), np.float32), np.zeros((n, 3), np.float32), np.full(n, 0.5, np.float32),
                         np.zeros((n, 3), np.float32),
                         glass=(np.ones((n, 3), np.float32), np.tile(c, (n, 1)), np.full(n, 1.45, np.float32),
                                np.full(n, rough, np.float32)))
    p.eta = np.full(n, eta, np.float32)
    return p


@pytest.mark.parametrize("eta", [1.45, 1 / 1.45])
@pytest.mark.parametrize("rough", [0.5, 0.9])
def test02_white_rough_glass_passes_on_all_it_receives(eta, rough, rng):
    for cos_wo in (0.9, 0.5):
        wo = np.float32([np.sqrt(1 - cos_wo ** 2), 0.0, cos_wo])
        p = bsdf.at_view(glass_params(N, (1, 1, 1), rough, eta), np.tile(wo, (N, 1)))
        est, err = mean_weight(p, cos_wo, rng)
        # Within the tables' accuracy; single scattering alone keeps 0.72-0.99.
        assert est == pytest.approx(1.0, abs=4 * err + 0.01), (cos_wo, est)


def test03_a_tint_darkens_the_light_put_back(rng):
    """Kulla and Conty's multiple-bounce Fresnel: light that bounced between
    microfacets took the tint more than once, so a tinted channel gets back
    less than a white one (Cycles' darkening)."""
    cos_wo, eta, rough = 0.7, 1.45, 0.8
    wo = np.tile(np.float32([np.sqrt(1 - cos_wo ** 2), 0.0, cos_wo]), (N, 1))
    white = bsdf.at_view(glass_params(N, (1, 1, 1), rough, eta), wo)
    tinted = bsdf.at_view(glass_params(N, (0.5, 0.5, 0.5), rough, eta), wo)
    e = glass_albedo(np.float32([rough]), np.float32([cos_wo]), np.float32([eta]))[0]
    k_white = white.glass_r[0, 0]
    k_tinted = tinted.glass_r[0, 0]
    assert k_white == pytest.approx(1 / e, rel=1e-5)
    assert 1.0 < k_tinted < k_white
