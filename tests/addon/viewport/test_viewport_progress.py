"""Progressive refinement of the rendered viewport (restir_addon/viewport/progress.py):
the stages of a still view (moving, refining, sampling, done), the
resolution steps that keep what the coarser frames learnt, the sample limit,
convergence, and the denoiser's start sample."""

import dataclasses
import importlib

import numpy as np
import pytest

from support.viewport_util import build_scene, new_session


def _nudged(camera, i):
    return dataclasses.replace(camera, lens=camera.lens * (1.0 + 0.002 * (i + 1)))


def test01_stages_in_order(vp, addon):
    """Progress alone: moving after a change, refining on a still view
    (4, 2, 1 after STEP_FRAMES frames each), sampling at full resolution,
    done at the limit; the header names each."""
    vpp = addon.restir_addon.viewport.progress
    n = 2 * vpp.STEP_FRAMES + 4           # the sample limit
    p = vpp.Progress(limit=n)
    stages, divisors, texts = [], [], []
    for _ in range(n + 2):
        stages.append(p.stage)
        texts.append(p.text())
        if p.done:
            break
        d = p.next_divisor(4, fixed=False)
        p.stepped(d)
        divisors.append(d)
        p.frame_done(None)
    step = vpp.STEP_FRAMES
    assert divisors == [4] * step + [2] * step + [1] * (n - 2 * step)
    assert stages[0] == vpp.MOVING
    # (the stage after a frame: the header shown while the next one renders)
    assert stages[1:2 * step + 1] == [vpp.REFINING] * (2 * step)
    assert stages[2 * step + 1:n] == [vpp.SAMPLING] * (n - 1 - 2 * step) and stages[n] == vpp.DONE
    assert texts[0].startswith("Moving") and "1/4 res" in texts[1] and "1/2 res" in texts[step + 1]
    assert texts[2 * step + 1] == f"Sample {2 * step + 2}/{n}" and texts[n] == "Done"
    # A change starts over: moving, at the budget's divisor again.
    p.changed()
    assert p.stage == vpp.MOVING and not p.done and p.next_divisor(2, fixed=False) == 2
    # A fixed scale never steps.
    p.stepped(2)
    for _ in range(2 * step):
        p.frame_done(None)
    assert p.next_divisor(2, fixed=True) == 2


def test02_limit_zero_and_convergence(addon):
    """Limit 0 refines until the image stops changing: CONVERGED_RUN frames
    in a row under CONVERGED_CHANGE, after CONVERGED_MIN_SAMPLES; a
    change above it restarts the run."""
    vpp = addon.restir_addon.viewport.progress
    p = vpp.Progress(limit=0)
    p.stepped(1)
    small = vpp.CONVERGED_CHANGE / 2
    for i in range(vpp.CONVERGED_MIN_SAMPLES - 1):
        p.frame_done(small)
        assert not p.done
    p.frame_done(small)
    assert p.done and p.stage == vpp.DONE and p.text().startswith("Done (converged")
    p.changed()
    for i in range(vpp.CONVERGED_MIN_SAMPLES + 10):
        p.frame_done(small if i % vpp.CONVERGED_RUN else 10 * vpp.CONVERGED_CHANGE)
    assert not p.done
    a = np.ones((4, 4, 4), np.float32)
    assert vpp.relative_change(a, a) == 0.0
    assert abs(vpp.relative_change(a, a * 1.01) - 0.01) < 1e-6
    assert vpp.relative_change(a, np.ones((2, 2, 4))) is None


def test03_session_refines_a_still_view_to_full_resolution(vp, addon):
    """The session: frames at the budget's resolution while the view moves,
    then 1/4, 1/2, full, then samples to the limit and stops."""
    build_scene()
    step = addon.restir_addon.viewport.progress.STEP_FRAMES
    limit = 2 * step + 4
    session = new_session(vp, mode="RESTIR_BIASED", scale="AUTO", samples=limit, frame_budget=1e-6)
    session.resize(96, 64)
    assert session.render_step()
    camera = session.view
    sizes, texts = [], []
    for i in range(3):                      # moving: each frame follows a view change
        session.set_view(_nudged(camera, i))
        assert session.render_step()
        sizes.append(session.render_size)
    assert sizes == [(24, 16)] * 3
    sizes = []
    while session.render_step():
        sizes.append(session.render_size)
        texts.append(session.status())
    # The last moving frame counts as sample 1.
    assert sizes == [(24, 16)] * (step - 1) + [(48, 32)] * step + [(96, 64)] * (limit - 2 * step)
    assert texts[0].startswith("Refining 1/4 res") and texts[step].startswith("Refining 1/2 res") \
        and texts[2 * step + 1].startswith("Sample"), texts
    assert session.converged and session.status().startswith("Done")
    assert session.progress.samples == limit
    session.close()


def _mean_frames(session, frames):
    out = []
    for _ in range(frames):
        assert session.render_step()
        out.append(session.frame[..., :3].copy())
    return out


@pytest.mark.slow
def test04_resolution_step_keeps_the_image(vp, addon):
    """A step from 1/2 to full resolution carries the running means: the
    image keeps its mean, and right after the step it is nearer a converged
    image than a start from nothing at full resolution is."""
    resize = importlib.import_module("restir_gi.core.restir.resize")
    build_scene()
    kw = dict(mode="RESTIR_BIASED", samples=0, max_bounces=2)
    reference = new_session(vp, scale="FULL", **kw)
    reference.resize(96, 64)
    ref = np.mean(_mean_frames(reference, 48)[-16:], axis=0)
    reference.close()

    coarse = new_session(vp, scale="HALF", **kw)
    coarse.resize(96, 64)
    before = _mean_frames(coarse, 12)[-1]
    history = coarse.restir.history
    carried = resize.resize_history(history, 96, 64)
    # Nearest neighbour at exactly twice the size: the same mean, exactly.
    acc0, acc1 = history.accumulation, carried.accumulation
    np.testing.assert_allclose(acc1.indirect.mean(axis=0, dtype=np.float64), acc0.indirect.mean(axis=0, dtype=np.float64), rtol=1e-5)
    np.testing.assert_allclose(acc1.direct.mean(axis=0, dtype=np.float64), acc0.direct.mean(axis=0, dtype=np.float64), rtol=1e-5)
    assert acc1.count.max() <= resize.CARRY_FRAMES
    assert carried.signature[:2] == (96, 64) and history.signature[:2] == (48, 32)
    # Through the session: the AUTO scale's step from 1/2 to full.
    coarse.scale = "AUTO"
    coarse.progress.at_divisor = 10 ** 6        # still long enough: the next frame steps
    after = _mean_frames(coarse, 1)[0]
    assert coarse.render_size == (96, 64)
    assert coarse.restir.frames == 13           # went on, not reset
    assert abs(after.mean() / before.mean() - 1) < 0.05, (after.mean(), before.mean())

    cold = new_session(vp, scale="FULL", **kw)
    cold.resize(96, 64)
    first = _mean_frames(cold, 1)[0]
    cold.close()
    coarse.close()
    err_carried = float(np.mean((after - ref) ** 2))
    err_cold = float(np.mean((first - ref) ** 2))
    assert err_carried < 0.7 * err_cold, (err_carried, err_cold)


def test06_step_blends_the_last_coarse_image(vp, addon):
    """Right after a resolution step the image shown is the finer frame
    blended with the coarse image shown before it (upscaled bilinearly),
    which counts as min(samples, BLEND_FRAMES) frames; its share falls with
    every finer frame and it is dropped under BLEND_MIN, and at any change."""
    progress = addon.restir_addon.viewport.progress
    resize = importlib.import_module("restir_gi.core.restir.resize")
    build_scene()
    session = new_session(vp, mode="RESTIR_BIASED", scale="HALF", samples=0, max_bounces=2)
    session.resize(96, 64)
    for _ in range(5):
        assert session.render_step()
    coarse = session.frame.copy()
    session.scale = "AUTO"
    session.progress.at_divisor = 10 ** 6           # still long enough: the next frame steps
    assert session.render_step() and session.render_size == (96, 64)
    image, weight = session._carried
    assert weight == min(5, progress.BLEND_FRAMES)
    np.testing.assert_allclose(image, resize.upscale_bilinear(coarse, 96, 64))
    share = weight / (weight + 1)
    shown = session.frame
    # What the finer frame alone was: shown = share * image + (1 - share) * fine.
    fine = (shown - share * image) / (1 - share)
    assert np.all(np.isfinite(fine))
    assert np.mean((shown - image) ** 2) < np.mean((fine - image) ** 2)
    before = shown
    for k in (2, 3):                                # the coarse image's share falls: 5/7, 5/8
        assert session.render_step() and session._carried is not None
        assert session.progress.at_divisor == k
        assert np.mean((session.frame - image) ** 2) > 0 and not np.array_equal(session.frame, before)
        before = session.frame
    session.progress.at_divisor = int(weight / progress.BLEND_MIN)   # share under BLEND_MIN: dropped
    assert session.render_step() and session._carried is None
    # A change drops it at once.
    session.progress.at_divisor = 0
    session._carried = (image, weight)
    session.set_view(_nudged(session.view, 1))
    assert session.render_step()
    assert session._carried is None
    session.close()


def test05_denoise_start_sample(vp):
    """Frames before the start sample are shown as accumulated, from it on
    denoised; frames that follow a view change (orbiting) count as sample 1,
    so with the default start they are denoised."""
    build_scene()
    frames = {}
    for start in (1, 3, 10 ** 6):
        session = new_session(vp, mode="RESTIR_BIASED", denoise_start=start, max_bounces=2)
        session.resize(64, 48)
        shown = _mean_frames(session, 4)
        session.set_view(_nudged(session.view, 0))
        shown += _mean_frames(session, 1)
        frames[start] = shown
        session.close()
    d, s3, raw = frames[1], frames[3], frames[10 ** 6]
    for i in range(5):
        assert not np.array_equal(d[i], raw[i]), i       # the denoiser changed the image
    for i in (0, 1):
        np.testing.assert_array_equal(s3[i], raw[i])
    for i in (2, 3):
        np.testing.assert_array_equal(s3[i], d[i])
    np.testing.assert_array_equal(s3[4], raw[4])         # after a change: sample 1 again
