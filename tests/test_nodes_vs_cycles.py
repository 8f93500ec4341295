"""Shader node families against Cycles: the same scene rendered by both.

Each family of tests/node_families.py changes the example Cornell box so one
family of nodes decides most of the image; both engines render it twice with
independent seeds. Mean brightness must agree within 2 % and the block-wise
differences must be what the noise allows (as tests/test_vs_cycles.py; the
bugs these tests caught while they were written gave block chi 6 to 150).
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
    assert r["chi"] < 2.5
