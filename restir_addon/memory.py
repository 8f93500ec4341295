"""Memory a render will take, against what the machine has, checked before
anything large is allocated: a scene or an image too big stops with a report
naming the numbers instead of being killed by the system.

Instances are flattened: every placed copy of a mesh gets its own world-space
triangles in the combined arrays and the Embree scene (embreex offers no
instancing), so 10,000 instances of a 10k-triangle object cost what 100M
distinct triangles do.
"""

import os

# Bytes per placed triangle and vertex held at once while a scene is built:
# combined arrays (indices 12, corner normals 36, UVs 24, ids 8, face normal
# 12), their placed copies (48), Embree's index and BVH (about 80); per vertex
# the positions, their placed copy and Embree's copy (36).
BYTES_PER_TRIANGLE = 220
BYTES_PER_VERTEX = 36
# Share of the available memory the geometry may take (the rest: images,
# reservoirs, Blender itself).
BUDGET_SHARE = 0.6


# Peak memory of a ReSTIR GI animation frame on top of Blender itself, as
# bytes per pixel plus a fixed part: the state kept between frames
# (core.restir.temporal.state_bytes_per_pixel, 219 bytes), what a frame holds
# of last frame's while it builds its own, the images handed to Blender; the
# fixed part is the temporaries of the pixel ranges in flight, which do not
# grow with the image. bench/bench_memory.py --frames 3 measured 1.84 GB at
# 1920x1080 and 4.90 GB at 3840x2160: 528 bytes per pixel between the two,
# and 0.82 GB extrapolated to no pixels, Blender itself included
# (docs/memory.md). Path reuse of the glossy lobe added 81 bytes per pixel of
# a frame's temporaries (core/restir/glossy_reuse.py): 1.97 GB at 1920x1080
# in the same run, 65 bytes per pixel more (3840x2160 not run again).
RESTIR_BYTES_PER_PIXEL = 600
RESTIR_FIXED_BYTES = 768 * 1024 ** 2
# That figure is a measured peak, not a rough count as BYTES_PER_TRIANGLE is,
# so the image may take a larger share of the available memory.
IMAGE_BUDGET_SHARE = 0.85


class SceneTooLarge(Exception):
    """The placed geometry would not fit in memory; the message says why."""


def available_bytes():
    """Memory available to this process now (Linux: MemAvailable), or None."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def geometry_bytes(triangles, vertices):
    return triangles * BYTES_PER_TRIANGLE + vertices * BYTES_PER_VERTEX


def check_geometry(triangles, vertices, instances, available=None):
    """Raise SceneTooLarge if placing ``triangles`` would not fit."""
    available = available_bytes() if available is None else available
    if available is None:
        return
    need = geometry_bytes(triangles, vertices)
    if need <= BUDGET_SHARE * available:
        return
    gb = 1024.0 ** 3
    raise SceneTooLarge(
        f"The scene has {triangles:,} triangles once its {instances:,} objects and instances are "
        f"placed: about {need / gb:.1f} GB of geometry, and this machine has {available / gb:.1f} GB "
        f"available (the limit is {BUDGET_SHARE:.0%} of it). Instances are not shared in memory by "
        "this engine: reduce the number of instances or their resolution (e.g. Simplify > Max "
        "Subdivision), or render on a machine with more memory.")


def image_bytes(width, height):
    """Estimated peak memory of a ReSTIR GI render of width x height."""
    return RESTIR_FIXED_BYTES + width * height * RESTIR_BYTES_PER_PIXEL


def check_image(width, height, available=None, held=0):
    """Raise SceneTooLarge if a ReSTIR GI render of width x height would not
    fit. held: bytes of ReSTIR state this process already holds for the render
    (last frame's, part of the figure per pixel): it counts as available, so
    an animation that fitted at its first frame is not refused later."""
    available = available_bytes() if available is None else available
    if available is None:
        return
    available += held
    need = image_bytes(width, height)
    if need <= IMAGE_BUDGET_SHARE * available:
        return
    gb = 1024.0 ** 3
    raise SceneTooLarge(
        f"A {width}x{height} ReSTIR GI render needs about {need / gb:.1f} GB "
        f"({RESTIR_BYTES_PER_PIXEL} bytes per pixel and {RESTIR_FIXED_BYTES / gb:.1f} GB), and this "
        f"machine has {available / gb:.1f} GB "
        f"available (the limit is {IMAGE_BUDGET_SHARE:.0%} of it). Lower the resolution (Output "
        "Properties > Format) or render in Path Tracing mode, which works in bounded chunks.")
