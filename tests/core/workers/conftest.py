"""Render contexts of one and two workers over a small Cornell box."""

import pytest

from restir_gi.core import RenderContext
from support.scenes import cornell_box


@pytest.fixture(scope="module")
def contexts():
    scene = cornell_box("area", 96, 96)
    one = RenderContext.build(scene, threads=1)
    two = RenderContext.build(scene, threads=2)
    assert two.workers.processes and len(two.workers.ranges(96 * 96)) == 2
    yield one, two
    one.close()
    two.close()
