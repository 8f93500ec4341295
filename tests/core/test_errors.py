"""Errors inside a frame say where they happened (core/util/errors.py): the
frame's stage and the material or object, as notes on the exception that the
add-on's report shows."""

import pickle

import pytest

from restir_gi.core.util.errors import context, describe, noted, notes


def test01_innermost_context_of_each_kind_is_noted():
    with pytest.raises(ValueError) as info:
        with context("stage", "outer"), context("material", "'Glass'"), context("stage", "spatial reuse"):
            raise ValueError("bad")
    exc = info.value
    assert noted(exc, "stage") == "spatial reuse"
    assert notes(exc) == {"stage": "spatial reuse", "material": "'Glass'"}
    assert describe(exc) == "ValueError: bad (stage: spatial reuse; material: 'Glass')"


def test02_notes_survive_pickling():
    """The twin process hands its errors to the parent pickled."""
    with pytest.raises(KeyError) as info:
        with context("stage", "G-buffer"):
            raise KeyError("x")
    back = pickle.loads(pickle.dumps(info.value))
    assert noted(back, "stage") == "G-buffer"


def test03_plain_errors_describe_themselves():
    assert describe(RuntimeError("boom")) == "RuntimeError: boom"
    assert describe(ZeroDivisionError()) == "ZeroDivisionError"


def test04_a_failing_material_graph_names_its_material(monkeypatch):
    from restir_gi.core.materials.shader import CompiledShader
    from restir_gi.core.materials.shader.graph import Link, Node, ShaderGraph
    shader = CompiledShader(ShaderGraph(nodes=[Node("BSDF_DIFFUSE", {"Color": (0.5, 0.5, 0.5)})],
                                        output=Link(0, "BSDF"), name="Brick"))

    def broken(geom, stop=None):
        raise IndexError("out of range")
    monkeypatch.setattr(shader, "outputs", broken)
    with pytest.raises(IndexError) as info:
        shader.closure(None)
    assert noted(info.value, "material") == "'Brick'"


def test05_a_failing_stage_is_named_in_the_frame(monkeypatch):
    """An exception inside a ReSTIR frame's pass names its stage, through the
    workers (threads here)."""
    import restir_gi.core.restir.frame as frame
    from restir_gi.core import RenderContext
    from restir_gi.core.restir import ReSTIRGI, ReSTIRSettings
    from support.scenes import cornell_box

    def broken(*args, **kwargs):
        raise FloatingPointError("no")
    monkeypatch.setattr(frame, "spatial_resample", broken)
    ctx = RenderContext.build(cornell_box("area", 8, 8))
    try:
        with pytest.raises(FloatingPointError) as info:
            ReSTIRGI().render_frame(ctx, ReSTIRSettings(), 0)
    finally:
        ctx.close()
    assert noted(info.value, "stage") == "spatial reuse"
