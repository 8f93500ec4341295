"""Voxel arrays read from .vdb files (restir_addon/export/volume_objects.py's
GridFiles): exact where the grid fits, averaged down in blocks where it does
not, read once while the file is unchanged."""

import os

import numpy as np

from support.volume_scenes import write_vdb


def _random_grid(shape, seed=0):
    rng = np.random.default_rng(seed)
    return (rng.random(shape) + 0.1).astype(np.float32)


def test_a_grid_reads_exactly(addon, tmp_path):
    from restir_gi.restir_addon.export.volume_objects import GridFiles
    dens = _random_grid((7, 5, 9))
    path = write_vdb(tmp_path / "g.vdb", {"density": dens})
    warnings = []
    arr, lo, block = GridFiles().read(path, "density", warnings.append)
    assert block == 1 and tuple(lo) == (0, 0, 0) and warnings == []
    np.testing.assert_array_equal(arr, dens)


def test_a_large_grid_is_averaged_down_in_blocks(addon, tmp_path, monkeypatch):
    """With room for fewer voxels than the grid has, the array is the
    grid's mean over blocks (the last block padded with the background),
    copied slab by slab; one warning says so."""
    from restir_gi.restir_addon.export import volume_objects
    dens = _random_grid((13, 10, 7), 1)
    path = write_vdb(tmp_path / "g.vdb", {"density": dens})
    monkeypatch.setattr(volume_objects, "MAX_VOXELS", 100)
    monkeypatch.setattr(volume_objects, "SLAB_VOXELS", 300)        # three layers at a time
    warnings = []
    arr, lo, block = volume_objects.GridFiles().read(path, "density", warnings.append)
    assert block == 3 and len(warnings) == 1 and "averaged down 3x" in warnings[0]
    padded = np.pad(dens, [(0, 2), (0, 2), (0, 2)])
    expect = padded.reshape(5, 3, 4, 3, 3, 3).mean(axis=(1, 3, 5))
    np.testing.assert_allclose(arr, expect, rtol=1e-6)


def test_a_file_is_read_again_only_when_it_changes(addon, tmp_path):
    from restir_gi.restir_addon.export.volume_objects import GridFiles
    files = GridFiles()
    path = write_vdb(tmp_path / "g.vdb", {"density": _random_grid((4, 4, 4))})
    first = files.read(path, "density", print)
    assert files.read(path, "density", print) is first
    write_vdb(path, {"density": _random_grid((4, 4, 4), 2)})
    stat = os.stat(path)
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns + 10 ** 9))
    second = files.read(path, "density", print)
    assert second is not first and not np.array_equal(second[0], first[0])
