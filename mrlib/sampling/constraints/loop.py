"""Seamless loops: motion whose end joins its start.

``method="circular"`` (default): every level of the generator runs on a circle, with
wrap-around padding in the convolutions and wrap-around upsampling between levels
(``MultiResGenerator.run_batch(circular=True)``), so the features are periodic by
construction: the frame after the last is the first. The root travels on (a walk loop
moves forward each cycle, as root motion in a game engine): ``meta["loop_offset"]`` is
the ground displacement of one cycle.

A cycle has no first frame of its own, so ``start="calm"`` (default) begins it where
the body moves least: the wrap from the last frame to the first is then the cycle's
smallest joint step, the place where a cut into or out of the loop shows least (and the
seam cannot stand out from the loop's other steps). ``start="sample"`` keeps the
generator's frame 0 as the first.

``method="crossfade"``: the usual fix, a sample ``CROSSFADE_S`` seconds longer whose extra
tail is faded into its head (the features, so the root velocity too). Measured against
the circular loop in ``docs/results.md``.
"""

from __future__ import annotations

import numpy as np
import torch

from mrlib.errors import MotionValueError, check_number
from mrlib.representation.motion import Motion
from mrlib.sampling.arguments import checked

__all__ = ["generate_loop", "loop_seam", "tile_loop", "roll_loop", "CROSSFADE_S"]

CROSSFADE_S = 0.5  # method="crossfade": seconds of the tail faded into the head


def _loop_motion(model, x: torch.Tensor, label: str, name: str) -> Motion:
    """Features ``(C, T)`` of one cycle -> Motion with the wrap-around step in meta."""
    from mrlib.representation.features import ROOT_SLICE, features_to_motion

    m = features_to_motion(
        x.T, model.fps, betas=model.betas, normalizer=model.normalizer, label=label, name=name
    )
    root = model.normalizer.denormalize(x.T)[:, ROOT_SLICE].double().numpy()
    # the step from the last frame into the next cycle's first is frame 0's velocity
    wrap = np.array([root[0, 0], 0.0, root[0, 2]]) / model.fps
    offset = m.trans[-1] - m.trans[0] + wrap
    offset[1] = 0.0
    m.meta["loop_offset"] = offset.round(6).tolist()
    return m


@checked()
def tile_loop(motion: Motion, cycles: int) -> Motion:
    """``cycles`` copies of a loop one after the other, each moved on by
    ``meta["loop_offset"]``."""
    if "loop_offset" not in motion.meta:
        raise MotionValueError("not a loop (no meta['loop_offset']); make one with generate_loop")
    off = np.asarray(motion.meta["loop_offset"], np.float64)
    k = np.repeat(np.arange(cycles), motion.num_frames)[:, None]
    return motion.replace(
        poses=np.tile(motion.poses, (cycles, 1, 1)),
        trans=np.tile(motion.trans, (cycles, 1)) + k * off,
        contacts=None if motion.contacts is None else np.tile(motion.contacts, (cycles, 1)),
        meta=dict(motion.meta),
    )


@checked(start=lambda n, v: check_number(n, v, integer=True))
def roll_loop(motion: Motion, start: int) -> Motion:
    """The same loop begun at its frame ``start`` (the frames before it move to the end,
    one cycle on)."""
    T = motion.num_frames
    s = int(start) % T
    if s == 0:
        return motion
    two = tile_loop(motion, 2)
    out = two.slice(s, s + T)
    return out.replace(trans=out.trans - out.trans[0] + motion.trans[0], meta=dict(motion.meta))


def _joint_steps(motion: Motion, body, frames: int) -> np.ndarray:
    """Mean joint displacement (metres) from frame k to k + 1 over the first ``frames``
    frames of the loop played twice: ``(frames - 1,)``, step ``T - 1`` the wrap."""
    from mrlib.representation.body import resolve_body

    J = resolve_body(body, shared=True).motion_joints(tile_loop(motion, 2).slice(0, frames))
    return np.linalg.norm(np.diff(J, axis=0), axis=-1).mean(-1)


def _calm_start(motion: Motion, body) -> int:
    """The frame after the cycle's smallest joint step (wrap-around included)."""
    T = motion.num_frames
    return (int(np.argmin(_joint_steps(motion, body, T + 1))) + 1) % T


def _raised_loop(m: Motion, fps: float) -> Motion:
    """A loop resampled to about ``fps`` by cubic splines through three cycles, so the
    frames near the seam see across it: ``round(T * fps / m.fps)`` frames evenly over the
    cycle (its duration kept; the rate is ``fps`` to within one frame per cycle)."""
    T = m.num_frames
    n = max(2, round(T * float(fps) / m.fps))
    t = T + np.arange(n) * (T / n)  # the middle cycle of three, in input frames
    mid = tile_loop(m, 3).at_frames(t, smooth=True)
    off = np.asarray(m.meta["loop_offset"], np.float64)
    meta = {**m.meta, "source_fps": float(m.meta.get("source_fps", m.fps))}
    return mid.replace(trans=mid.trans - off, fps=float(fps), meta=meta)


def _clean_loop(m: Motion, body, jitter: float | None = None) -> Motion:
    """Foot clean-up of a loop: on three cycles, keeping the middle one, so the
    clean-up sees across the seam. Planting the feet moves the root, so a cleaned cycle
    travels its own distance: ``loop_offset`` becomes the middle cycle's (from its first
    frame to the third cycle's), else the wrap would step by the difference."""
    from mrlib.sampling.cleanup import JITTER_SIGMA, cleanup_foot_contacts

    T = m.num_frames
    c = cleanup_foot_contacts(tile_loop(m, 3), body, jitter=jitter or JITTER_SIGMA)
    mid = c.slice(T, 2 * T)
    off = c.trans[2 * T] - c.trans[T]
    off[1] = 0.0
    return mid.replace(
        trans=mid.trans - np.asarray(m.meta["loop_offset"]),
        meta=dict(c.meta, loop_offset=off.round(6).tolist()),
    )


@checked()
def generate_loop(
    model,
    condition=None,
    length: int | None = None,
    *,
    seed: int | None = None,
    method: str = "circular",
    start: str = "calm",
    sampler=None,
    body=None,
) -> Motion:
    """A loop of ``length`` frames (default: the condition's training clip) under a
    condition (a label or a ``mrlib.Condition``; None: the first label; method and
    ``start``: module docstring). ``sampler``: a ``mrlib.Sampler`` (fine noise, guidance;
    ``fps``: the cycle drawn at the model's rate, resampled by cubic splines across the
    seam to that rate, its duration kept; its ``fix_contacts`` plants the feet, across the
    seam)."""
    from mrlib.sampling.conditions import as_condition
    from mrlib.sampling.generation import check_conditions, draw_noise, label_inputs, sampler_record
    from mrlib.sampling.sampler import Sampler

    if method not in ("circular", "crossfade"):
        raise MotionValueError(f"method must be 'circular' or 'crossfade', got {method!r}")
    if start not in ("calm", "sample"):
        raise MotionValueError(f"start must be 'calm' or 'sample', got {start!r}")
    sampler = Sampler() if sampler is None else sampler
    cond = as_condition(0 if condition is None else condition)
    W, label = cond.weights(model), cond.name(model)
    if method == "circular":
        lengths, amp, conds = label_inputs(model, W, length, sampler)
        noises = draw_noise(lengths, amp, seed, 1, model.device)
        with torch.inference_mode():
            x = model.generator.run_batch(
                noises, check_conditions(model, conds, lengths), circular=True
            )
        x = x[0]
    else:
        T = label_inputs(model, W, length, sampler)[0][-1]
        n = max(1, round(CROSSFADE_S * model.fps))
        lengths, amp, conds = label_inputs(model, W, T + n, sampler)
        noises = draw_noise(lengths, amp, seed, 1, model.device)
        with torch.inference_mode():
            y = model.generator.run_batch(noises, check_conditions(model, conds, lengths))[0]
        w = torch.linspace(0, 1, n + 2)[1:-1]  # weight of the head, 0 -> 1 over the fade
        w = w * w * (3 - 2 * w)
        x = y[:, :T].clone()
        x[:, :n] = (1 - w) * y[:, T:] + w * y[:, :n]
    m = _loop_motion(model, x.cpu(), label, f"{label}_loop_seed{seed}")
    from mrlib.sampling.contact_labels import output_contacts, reads_at_rate

    if reads_at_rate(model, sampler, W):  # the cycle's labels at the condition's contact rate
        m = m.replace(contacts=output_contacts(model, x[None], W)[0])
    m.meta["loop_method"] = method
    m.meta["sampler"] = sampler_record(model, sampler, seed, 0, W)
    if sampler.fps is not None and abs(sampler.fps - model.fps) > 1e-6:
        m = _raised_loop(m, sampler.fps)  # before the feet are planted, as generate raises
    if sampler.fix_contacts and m.contacts is not None:
        from mrlib.sampling.cleanup import jitter_at

        m = _clean_loop(m, body, jitter=jitter_at(m.fps, model.fps))
    if start == "calm":
        k = _calm_start(m, body)
        m = roll_loop(m, k)
        m.meta["loop_start"] = k
    return m


@checked()
def loop_seam(motion: Motion, body=None) -> dict[str, float]:
    """How well a loop closes, on joint positions: the loop is played twice and each
    frame-to-frame step measured as the mean joint displacement (metres).

    Returns:
        ``seam``: the step from the last frame into the next cycle's first (metres);
        ``median``, ``p95``: the median and 95th percentile of the loop's own steps;
        ``rank``: the share of the loop's own steps smaller than the seam (0: the seam is
        the smallest step, as ``start="calm"`` makes it; about uniform on [0, 1] for a
        seam that is an ordinary step; 1: larger than every step of the loop, a jump).
    """
    T = motion.num_frames
    steps = _joint_steps(motion, body, 2 * T)  # (2T - 1,)
    seam = float(steps[T - 1])
    own = np.concatenate([steps[: T - 1], steps[T:]])
    return {
        "seam": seam,
        "median": float(np.median(own)),
        "p95": float(np.percentile(own, 95)),
        "rank": float(np.mean(own < seam)),
    }
