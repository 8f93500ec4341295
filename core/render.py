"""Rendering one frame: settings in, a Film out, with progress and cancel hooks."""

import time
from dataclasses import dataclass

from .camera import PixelFilter
from .film import Film
from .integrators.path import camera_pass


@dataclass
class RenderSettings:
    mode: str = "PATH"
    samples: int = 16
    max_bounces: int = 4
    seed: int = 0


def render_frame(ctx, settings, frame=0, on_sample=None, should_stop=None):
    """Path-trace ``settings.samples`` passes of the whole image into a Film.

    on_sample(film, seconds) is called after every pass; should_stop() is polled
    between passes, so a cancel takes at most one pass. Returns the Film (with
    the passes done so far if stopped early).
    """
    scene = ctx.scene
    film = Film(scene.width, scene.height)
    pixel_filter = PixelFilter(scene.filter_width)
    start = time.perf_counter()
    for s in range(settings.samples):
        if should_stop is not None and should_stop():
            break
        res = camera_pass(ctx, scene.width, scene.height, settings.seed, frame, s,
                          settings.max_bounces, pixel_filter)
        film.add(res.color, depth=res.depth, normal=res.normal, albedo=res.albedo)
        if on_sample is not None:
            on_sample(film, time.perf_counter() - start)
    return film
