"""Scenes for the renderer's features beyond shader nodes (issue 40: panoramic
cameras, point clouds, hair, volumes), built by script on the example Cornell
box: the feature rows of bench/contact_sheet.py, ours beside Cycles. Each
builder takes the opened Cornell box scene and changes it so the feature
decides most of the image; the tests of each feature (tests/test_panorama.py,
...) compare their own, smaller scenes with Cycles.
"""

import math


def _pano(scene, **props):
    cam = scene.camera
    cam.location = (0.0, -0.6, 1.0)
    cam.rotation_euler = (math.radians(90), 0.0, 0.0)
    cam.data.type = "PANO"
    cam.data.clip_start = 0.01
    for key, value in props.items():
        setattr(cam.data, key, value)


def panorama_equirectangular(scene):
    """An equirectangular camera inside the box, looking at the back wall."""
    _pano(scene, panorama_type="EQUIRECTANGULAR")


def panorama_fisheye(scene):
    """An equisolid fisheye (180 degrees) inside the box, looking at the back wall."""
    _pano(scene, panorama_type="FISHEYE_EQUISOLID", fisheye_fov=math.pi, fisheye_lens=8.0)


FEATURES = {"panorama_equirectangular": panorama_equirectangular, "panorama_fisheye": panorama_fisheye}
