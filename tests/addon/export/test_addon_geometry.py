"""Export of Blender objects to core.Scene's triangles: meshes in world
space, mirrored objects, modifiers, instancing (collections, vertices,
geometry nodes), curves and text, render visibility and per-object ray
visibility, each checked against values computed here from the numbers the
scene was built with (never against the exporter's own functions). Lights:
test_addon_lights.py; the camera: test_addon_camera.py; materials:
test_addon_materials.py.

Every test starts from an empty factory file and builds its scene from numpy
arrays, so nothing depends on the startup file or on other tests.
"""

import math

import numpy as np
import pytest

from support.export_util import (QUAD, TRI, add_mesh, apply, area, export, export_for_render, fresh, material, row,
                                 trs, tri_counts, tri_points)


def test_mesh_triangles_in_world_space(addon):
    fresh()
    verts = np.concatenate([QUAD[0], TRI[0] + [2, 0, 0]])
    loc, rot, scl = (1.0, -2.0, 3.0), (0.3, -0.4, 1.1), (2.0, 0.5, 1.5)
    add_mesh("obj", verts, [[0, 1, 2, 3], [4, 5, 6]], location=loc, rotation=rot, scale=scl)
    s = export(addon)
    m = trs(loc, rot, scl)
    expected = apply(m, verts)

    assert s.triangle_count == 3
    np.testing.assert_allclose(s.vertices, expected, atol=1e-5)
    # The quad splits into two triangles over its own four corners, the triangle stays.
    tri_sets = sorted(sorted(t) for t in s.triangles.tolist())
    assert tri_sets[-1] == [4, 5, 6]
    assert all(set(t) <= {0, 1, 2, 3} for t in tri_sets[:2])
    p = tri_points(s)
    quad_area = np.linalg.norm(np.cross(expected[1] - expected[0], expected[3] - expected[0]))
    np.testing.assert_allclose(area(p).sum(), quad_area + area(expected[None, 4:7])[0], rtol=1e-5)
    # Shading normals are world-space unit normals of the (flat) faces.
    ng = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    ng /= np.linalg.norm(ng, axis=1, keepdims=True)
    for corner in range(3):
        np.testing.assert_allclose(np.einsum("ij,ij->i", s.normals[:, corner], ng), 1.0, atol=1e-5)


BOX = (np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], np.float64),
       [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]])


def _outward(s, name, centre):
    """Per triangle of an object: its winding normal and its corner normals
    against the direction from the object's centre to the triangle's."""
    p = tri_points(s, name)
    ng = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    out = p.mean(axis=1) - centre
    ids = [i for i, n in enumerate(s.object_names) if n == name]
    ns = s.normals[np.isin(s.object_ids, ids)]
    return np.einsum("ij,ij->i", ng, out), np.einsum("tcj,tj->tc", ns, out)


@pytest.mark.parametrize("path", ["export", "render"])
def test_mirrored_objects_keep_their_faces_outward(addon, monkeypatch, path):
    """Under a negative scale (one axis or three) the placed triangles wind
    the other way; their corners are taken 0, 2, 1 so that winding normal
    and corner normals both point out of the box (as Cycles does), in the
    one-shot export and in the render's kept scene. Otherwise smooth
    mirrored meshes shaded faceted and mirrored glass refracted inside out."""
    fresh()
    centres = {"plain": (0, 0, 0), "mirror_x": (4, 0, 0), "mirror_xyz": (8, 0, 0)}
    scales = {"plain": (1, 1, 1), "mirror_x": (-1, 2, 1), "mirror_xyz": (-1, -1, -1)}
    for name, c in centres.items():
        add_mesh(name, *BOX, location=c, scale=scales[name])
    s = export(addon) if path == "export" else export_for_render(addon, monkeypatch)
    for name, c in centres.items():
        winding, corners = _outward(s, name, np.asarray(c, np.float32))
        assert len(winding) == 12, name
        assert (winding > 0).all(), name
        assert (corners > 0).all(), name
        if s.face_normals is not None:
            fn = s.face_normals[np.isin(s.object_ids, [i for i, n in enumerate(s.object_names) if n == name])]
            p = tri_points(s, name)
            assert (np.einsum("ij,ij->i", fn, p.mean(axis=1) - np.float32(c)) > 0).all(), name


def test_flat_non_planar_faces_shade_by_each_triangle(addon):
    """A mesh of flat faces only shades each triangle by its own normal, as
    Cycles does (a non-planar quad shows its crease); once a face is smooth
    the corner normals are Blender's (the flat quad's the polygon's)."""
    fresh()
    ob = add_mesh("bent", [(-1, -1, 0), (1, -1, 0), (1, 1, 1.5), (-1, 1, 0)], [[0, 1, 2, 3]])
    s = export(addon)
    p = tri_points(s)
    ng = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    ng /= np.linalg.norm(ng, axis=1, keepdims=True)
    assert np.einsum("ij,ij->i", ng[0:1], ng[1:2])[0] < 0.95      # the quad is bent
    for corner in range(3):
        np.testing.assert_allclose(np.einsum("ij,ij->i", s.normals[:, corner], ng), 1.0, atol=1e-5)
    ob.data.polygons[0].use_smooth = True
    ob.data.update()
    s = export(addon)
    assert np.abs(np.einsum("ij,ij->i", s.normals[:, 0], ng) - 1.0).max() > 1e-3


def test_modifiers_are_applied(addon):
    fresh()
    arr = add_mesh("array", *QUAD)
    mod = arr.modifiers.new("Array", "ARRAY")
    mod.count = 3
    mod.relative_offset_displace = (1.0, 0.0, 0.0)
    sub = add_mesh("subsurf", *QUAD, location=(0, 5, 0))
    mod = sub.modifiers.new("Subsurf", "SUBSURF")
    mod.levels = mod.render_levels = 2
    s = export(addon)
    counts = tri_counts(s)
    assert counts == {"array": 2 * 3, "subsurf": 2 * 16}
    p = tri_points(s, "array")
    np.testing.assert_allclose(p.reshape(-1, 3).min(axis=0), [0, 0, 0], atol=1e-6)
    np.testing.assert_allclose(p.reshape(-1, 3).max(axis=0), [3, 1, 0], atol=1e-6)
    np.testing.assert_allclose(area(p).sum(), 3.0, rtol=1e-5)


def _count_reads(addon, monkeypatch):
    """Wrap the exporter's mesh reader: the list collects the pointer of each mesh read."""
    export_mod = addon.restir_addon.export
    reads = []
    real = export_mod.read_mesh

    def counting(me):
        reads.append(me.as_pointer())
        return real(me)

    monkeypatch.setattr(export_mod, "read_mesh", counting)
    return reads


def test_collection_instances_share_geometry(addon, monkeypatch):
    import bpy
    fresh()
    src = bpy.data.collections.new("Source")          # not linked to the scene: only instanced
    add_mesh("piece", *TRI, collection=src)
    placements = [((5, 0, 0), (0, 0, 0), (1, 1, 1)), ((0, 5, 0), (0, 0, 0.5), (2, 2, 2)),
                  ((0, 0, 5), (0.7, 0, 0), (1, 3, 1))]
    for i, (loc, rot, scl) in enumerate(placements):
        empty = bpy.data.objects.new(f"inst{i}", None)
        empty.instance_type = "COLLECTION"
        empty.instance_collection = src
        empty.location, empty.rotation_euler, empty.scale = loc, rot, scl
        bpy.context.scene.collection.objects.link(empty)
    reads = _count_reads(addon, monkeypatch)
    s = export(addon)

    assert s.triangle_count == len(placements)
    assert len(reads) == 1, "instances must share one geometry read"
    got = sorted(map(tuple, np.round(tri_points(s).reshape(-1, 3, 3)[:, 0], 5)))
    want = sorted(tuple(np.round(apply(trs(*pl), TRI[0][:1])[0], 5)) for pl in placements)
    np.testing.assert_allclose(got, want, atol=1e-4)
    areas = np.sort(area(tri_points(s)))
    base = area(TRI[0][None])[0]
    np.testing.assert_allclose(areas, np.sort([base, 4 * base, 3 * base]), rtol=1e-5)


def test_dupli_verts_instances(addon, monkeypatch):
    fresh()
    spots = np.array([[0, 0, 0], [3, 0, 0], [0, 4, 0], [1, 1, 2]], float)
    parent = add_mesh("points", spots, [])          # vertices only: no triangles of its own
    child = add_mesh("piece", *TRI)
    child.parent = parent
    parent.instance_type = "VERTS"
    reads = _count_reads(addon, monkeypatch)
    s = export_for_render(addon, monkeypatch)

    assert s.triangle_count == len(spots)   # one copy per vertex, the child itself not rendered
    assert len(set(reads)) == len(reads), "the same mesh was read twice"
    corners = tri_points(s)[:, 0]
    np.testing.assert_allclose(sorted(map(tuple, corners)), sorted(map(tuple, spots)), atol=1e-5)


def test_geometry_nodes_instances(addon, monkeypatch):
    import bpy
    fresh()
    spots = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [0, 0, 2], [2, 2, 2]], float)
    src = add_mesh("piece", *QUAD, location=(0, 0, -10))
    pts = add_mesh("points", spots, [])
    tree = bpy.data.node_groups.new("Scatter", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    gin, gout = tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")
    inst = tree.nodes.new("GeometryNodeInstanceOnPoints")
    info = tree.nodes.new("GeometryNodeObjectInfo")
    info.inputs["Object"].default_value = src
    tree.links.new(gin.outputs[0], inst.inputs["Points"])
    tree.links.new(info.outputs["Geometry"], inst.inputs["Instance"])
    tree.links.new(inst.outputs[0], gout.inputs[0])
    pts.modifiers.new("Scatter", "NODES").node_group = tree
    src.data.materials.append(material("red", Base_Color=(1, 0, 0, 1)))
    reads = _count_reads(addon, monkeypatch)
    s = export(addon)

    assert s.triangle_count == 2 + 2 * len(spots)     # the source itself plus the copies
    assert len(set(reads)) == len(reads), "the instances must share one geometry read"
    # Instances keep the material of the instanced geometry.
    assert (s.material_ids == row(s, "red")["id"]).all()
    copies = tri_points(s)[tri_points(s)[:, :, 2].max(axis=1) > -5]
    assert len(copies) == 2 * len(spots)
    mins = {tuple(np.round(c, 5)) for c in copies.reshape(-1, 2, 3, 3).min(axis=(1, 2))}
    assert mins == {tuple(p) for p in spots}


def test_curves_and_text_become_triangles(addon):
    import bpy
    scene = fresh()
    text = bpy.data.curves.new("text", "FONT")
    text.body = "Hi"
    text.materials.append(material("ink", "ShaderNodeBsdfDiffuse", Color=(0.1, 0.2, 0.9, 1)))
    scene.collection.objects.link(bpy.data.objects.new("text", text))
    curve = bpy.data.curves.new("tube", "CURVE")
    curve.dimensions = "3D"
    curve.bevel_depth = 0.1
    spline = curve.splines.new("POLY")
    spline.points.add(1)
    spline.points[0].co = (0, 0, 0, 1)
    spline.points[1].co = (2, 0, 0, 1)
    scene.collection.objects.link(bpy.data.objects.new("tube", curve))
    meta = bpy.data.metaballs.new("blob")
    meta.elements.new().radius = 1.0
    scene.collection.objects.link(bpy.data.objects.new("blob", meta))
    s = export(addon)

    counts = tri_counts(s)
    assert counts["text"] > 10 and counts["tube"] > 8 and counts["blob"] > 8
    # Each surface exactly once: no triangle exported twice on top of itself.
    keyed = {tuple(sorted(map(tuple, t))) for t in np.round(tri_points(s), 5).tolist()}
    assert len(keyed) == s.triangle_count, "triangles exported twice"
    tube = tri_points(s, "tube").reshape(-1, 3)
    np.testing.assert_allclose(tube.min(axis=0), [0, -0.1, -0.1], atol=1e-4)
    np.testing.assert_allclose(tube.max(axis=0), [2, 0.1, 0.1], atol=1e-4)
    # Side of a tube of radius 0.1 and length 2 (a polygon a little inside the circle).
    lateral = 2 * math.pi * 0.1 * 2
    assert 0.95 * lateral < area(tri_points(s, "tube")).sum() <= lateral
    ink = s.material_ids[s.object_ids == s.object_names.index("text")]
    assert (ink == row(s, "ink")["id"]).all()
    txt = tri_points(s, "text").reshape(-1, 3)
    np.testing.assert_allclose(txt[:, 2], 0.0, atol=1e-6)     # flat text in its z = 0 plane
    assert 0.5 < np.ptp(txt[:, 0]) < 3 and 0.3 < np.ptp(txt[:, 1]) < 1.5


def test_render_visibility_and_render_levels(addon, monkeypatch):
    fresh()
    add_mesh("shown", *QUAD)
    add_mesh("hidden", *QUAD, location=(3, 0, 0)).hide_render = True
    add_mesh("viewport_hidden", *QUAD, location=(-3, 0, 0)).hide_viewport = True
    sub = add_mesh("subsurf", *QUAD, location=(0, 3, 0))
    mod = sub.modifiers.new("Subsurf", "SUBSURF")
    mod.levels, mod.render_levels = 0, 1
    s = export_for_render(addon, monkeypatch)

    counts = tri_counts(s)
    assert "hidden" not in counts
    assert counts == {"shown": 2, "viewport_hidden": 2, "subsurf": 8}


def test_ray_visibility_per_object(addon):
    """Blender's Camera / Shadow / Diffuse / Glossy / Transmission ray
    visibility reach the scene per object (core/integrators/transparency.py hides the object from those rays)."""
    fresh()
    add_mesh("seen", *QUAD)
    b = add_mesh("unseen", *QUAD, location=(2, 0, 0))
    b.visible_camera = False
    b.visible_shadow = False
    b.visible_glossy = False
    s = export(addon)
    assert s.ray_visibility is not None
    rows = {name: s.ray_visibility[s.object_names.index(name)].tolist() for name in ("seen", "unseen")}
    assert rows == {"seen": [True] * 5, "unseen": [False, False, True, False, True]}
    b.visible_camera = b.visible_shadow = b.visible_glossy = True
    assert export(addon).ray_visibility is None      # all visible: nothing to hide


def test_a_mesh_in_edit_mode_renders_its_edits(addon, monkeypatch):
    """A mesh in Edit Mode (a user rendering while editing, or a file saved
    so) renders as edited: its object's data shows the mesh as it was when
    the mode began until Blender leaves it, as the untouched mesh shows."""
    import bmesh
    import bpy
    fresh()
    obj = add_mesh("edited", *QUAD)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    bpy.ops.object.mode_set(mode="EDIT")
    try:
        bm = bmesh.from_edit_mesh(obj.data)
        for v in bm.verts:
            v.co.z += 2.0
        bm.faces.new([bm.verts.new((5, 0, 0)), bm.verts.new((6, 0, 0)), bm.verts.new((5, 1, 0))])
        bmesh.update_edit_mesh(obj.data)
        assert len(obj.data.polygons) == 1         # the data as it was
        for s in (export(addon), export_for_render(addon, monkeypatch)):
            assert tri_counts(s) == {"edited": 3}
            z = tri_points(s, "edited")[..., 2]
            assert sorted(np.unique(np.round(z, 5)).tolist()) == [0.0, 2.0]
    finally:
        bpy.ops.object.mode_set(mode="OBJECT")
