"""Shader node families against Cycles: the same scene rendered by both.

Each family of tests/node_families.py changes the example Cornell box so one
family of nodes decides most of the image; both engines render it twice with
independent seeds. Mean brightness must agree within 2 % and the block-wise
differences must be what the noise allows (as tests/test_vs_cycles.py; the
bugs these tests caught while they were written gave block chi 6 to 150).

The anisotropic family is held to a looser block chi: Anisotropic is
approximated by the isotropic GGX of the same mean roughness
(core/shader/nodes_shader.py), so the mean agrees but the highlights'
shape does not (block chi 3.8 at this size; see the README).
"""

import numpy as np
import pytest

from blender_util import compare_with_cycles, open_example, set_resolution
from node_families import FAMILIES

SIZE = 64
BLOCK = 8
SAMPLES = 128
BOUNCES = 8
CLAMP = 1.0        # the ceiling light is compared in test_vs_cycles.py
MAX_CHI = {"anisotropic": 5.0}     # an approximation, not noise (module notes)


@pytest.mark.parametrize("family", list(FAMILIES))
def test_node_family_matches_cycles(addon, family):
    scene = open_example("cornell_box.blend")
    set_resolution(scene, SIZE, SIZE)
    FAMILIES[family](scene)
    r = compare_with_cycles(scene, SAMPLES, BOUNCES, BLOCK, clamp=CLAMP)
    assert np.isfinite(r["ours"]).all()
    print(f"{family}: mean ours {r['ours_mean']:.4f} cycles {r['cycles_mean']:.4f} "
          f"ratio {r['ratio']:.4f} block chi {r['chi']:.2f}")
    assert abs(r["ratio"] - 1.0) < 0.02
    assert r["chi"] < MAX_CHI.get(family, 2.5)
