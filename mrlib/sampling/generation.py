"""Sampling from a trained model: :func:`generate` (random motion under a label
condition, any length, one sample or a batch, with or without every level's output) and
:func:`reconstruct` (a training clip regenerated from its fixed noise), with the
foot-contact clean-up (``mrlib.sampling.cleanup``) as the sampler asks.

What drives each level is a condition (``mrlib.sampling.conditions``: a label, a
crossover, labels per level range, a blend); how the generator is sampled is a
:class:`~mrlib.sampling.sampler.Sampler` (fine noise, guidance, the clean-up), passed to
each call rather than kept on the model. Levels are 1-based in the public API (level 1
is the coarsest), as in the paper.
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence

import numpy as np
import torch

from mrlib.errors import ClipTooShortError, MotionValueError, check_count, check_number, check_seed
from mrlib.model.pyramid import PackedLevels, level_fps, pyramid_lengths, shortest_length
from mrlib.model.trained import GenerativeModel
from mrlib.representation.features import features_to_motion, features_to_motions
from mrlib.representation.motion import Motion
from mrlib.sampling.arguments import checked
from mrlib.sampling.cleanup import cleanup_foot_contacts, jitter_at
from mrlib.sampling.conditions import Condition, as_condition
from mrlib.sampling.contact_labels import output_contacts, reads_at_rate
from mrlib.sampling.ranking import best_candidates, can_rank, critic_scores
from mrlib.sampling.sampler import Sampler

# one sample: a 10-minute walk stays within mrlib.representation.motion's 1000 m
MAX_SAMPLE_SECONDS = 600.0
MAX_SAMPLE_FRAMES = 200_000  # all samples of one call or command (~0.5 GB while generating)

__all__ = [
    "generate",
    "reconstruct",
    "reconstruction_error",
    "training_floor",
    "plant_feet",
    "guided_weights",
    "noise_amplitude",
    "label_inputs",
    "sample_features",
    "sample_ranked",
    "MAX_SAMPLE_SECONDS",
    "MAX_SAMPLE_FRAMES",
]


# -- the sampler's settings ----------------------------------------------------------------
def guided_weights(W: torch.Tensor, sampler: Sampler) -> torch.Tensor:
    """Label weights ``W (L, K)`` under the sampler's guidance g: ``W + g (W - 1/K)``,
    each level's condition pushed away from the mean of all labels
    (``mrlib.sampling.sampler.GUIDANCE``). Rows still sum to one; with g > 0 some weights
    are negative, which the linear label embedding takes as extrapolation beyond the
    label. A one-label model has nothing to push from."""
    g = sampler.guidance
    if g == 0:
        return W
    return W + g * (W - 1.0 / W.shape[-1])


def noise_amplitude(
    model: GenerativeModel, W: torch.Tensor | None, sampler: Sampler
) -> torch.Tensor:
    """``(L,)`` sigma of each level's sampling noise: the training ``sigma_i`` of the
    level's label mix ``W (L, K)`` (``Condition.weights``; None: the first label), the
    finest level's scaled by the sampler's ``fine_noise``."""
    sigma = model.sigma.float()  # (K, L)
    amp = sigma[0].clone() if W is None else (W.float() * sigma.T).sum(1)
    amp[-1] = amp[-1] * sampler.fine_noise
    return amp


# -- sampling -----------------------------------------------------------------------------
def sample_features(
    model: GenerativeModel,
    conds: list[torch.Tensor],
    lengths: Sequence[int],
    noise_amplitude: torch.Tensor,
    seed: int | None = None,
    num_samples: int = 1,
    keep: bool = False,
    circular: bool = False,
) -> torch.Tensor | list[torch.Tensor]:
    """The generic sampler every other one builds on.

    Args:
        conds: per level a condition ``(B or 1, T_i, D)`` (any control signal, e.g.
            one-hot labels constant over time or per-frame speech features).
        lengths: ``[T_1, ..., T_L]`` frames per level.
        noise_amplitude: ``(L,)`` or ``(B, L)`` sigma of the noise z_i ~ N(0, sigma_i),
            shared across channels.
        keep: return every level's output.
        circular: periodic levels: the output loops seamlessly (``mrlib.sampling.constraints``).
    Returns:
        normalised features ``(B, C, T_L)`` or the list of all levels ``[(B, C, T_i)]``.
    """
    L = model.num_levels
    if len(lengths) != L or len(conds) != L:
        raise MotionValueError(
            f"need {L} lengths and {L} conditions, got {len(lengths)} and {len(conds)}"
        )
    num_samples = check_count("num_samples", num_samples)
    seed = check_seed("seed", seed)
    check_sample_length(model, int(lengths[-1]), num_samples)
    noises = draw_noise(lengths, noise_amplitude, seed, num_samples, model.device)
    cs = check_conditions(model, conds, lengths, num_samples)
    with torch.inference_mode():
        outs = model.generator.run_batch(noises, cs, keep=True, circular=circular)
    return outs if keep else outs[-1]


def sample_ranked(
    model: GenerativeModel,
    conds: list[torch.Tensor],
    lengths: Sequence[int],
    noise_amplitude: torch.Tensor,
    seed: int | None,
    num_samples: int,
    candidates: int,
) -> list[torch.Tensor]:
    """:func:`sample_features` (every level's output) of the best of ``candidates`` draws
    per sample by the model's critics (``mrlib.sampling.ranking``). Candidate ``j`` of
    sample ``b`` is noise stream ``(seed, b K + j)``: one candidate is
    :func:`sample_features` itself. A model without critics, or conditions split by
    channel group, draw once. Batches of at most ``MAX_SAMPLE_FRAMES`` frames."""
    K = check_count("candidates", candidates)
    num_samples = check_count("num_samples", num_samples)
    cs = check_conditions(model, conds, lengths, num_samples) if K > 1 else None
    if cs is None or not can_rank(model, cs):
        return sample_features(model, conds, lengths, noise_amplitude, seed, num_samples, True)
    seed = check_seed("seed", seed)
    check_sample_length(model, int(lengths[-1]), num_samples)
    seed = int(seed) if seed is not None else int(torch.seed() % 2**63)
    noises = draw_noise(lengths, noise_amplitude, seed, num_samples * K, model.device)
    per = max(1, MAX_SAMPLE_FRAMES // (int(lengths[-1]) * K))  # samples per batch
    kept: list[list[torch.Tensor]] = []
    for b0 in range(0, num_samples, per):
        b1 = min(num_samples, b0 + per)
        z = [n[b0 * K : b1 * K] for n in noises]
        c = [x[b0:b1].repeat_interleave(K, 0) for x in cs]
        with torch.inference_mode():
            outs = model.generator.run_batch(z, c, keep=True)
            best = best_candidates(critic_scores(model, outs, c), K)
        kept.append([o[best] for o in outs])
    return [torch.cat([k[i] for k in kept]) for i in range(len(lengths))]


def check_sample_length(model: GenerativeModel, frames: int, num_samples: int = 1) -> None:
    """Refuse, before anything is allocated, a sample longer than ``MAX_SAMPLE_SECONDS``
    or a batch of more than ``MAX_SAMPLE_FRAMES`` frames in all, with the way around."""
    fps = float(model.fps)
    if frames > MAX_SAMPLE_SECONDS * fps + 1:
        raise MotionValueError(
            f"length: {frames} frames ({frames / fps:.0f} s at {fps:g} fps) is longer than the "
            f"{MAX_SAMPLE_SECONDS:.0f} s mrlib generates in one sample (a longer walk leaves "
            "the 1000 m a motion may span); generate shorter pieces and join them with "
            "mrlib.sampling.constraints.keyframes.continue_motion"
        )
    if frames * num_samples > MAX_SAMPLE_FRAMES:
        raise MotionValueError(
            f"num: {num_samples} samples of {frames} frames are more than the "
            f"{MAX_SAMPLE_FRAMES} frames generated in one call; generate them in smaller batches"
        )


def draw_noise(
    lengths: Sequence[int],
    noise_amplitude: torch.Tensor,
    seed: int | None,
    num_samples: int = 1,
    device: str | torch.device = "cpu",
) -> list[torch.Tensor]:
    """The noise maps of :func:`sample_features`: per level ``(B, 1, T_i)``, sample ``b``
    drawn from its own stream ``(seed, b)`` (a sample does not depend on the batch size
    it was generated in) and scaled by its level's ``sigma_i``."""
    L = len(lengths)
    base = int(seed) if seed is not None else int(torch.seed() % 2**63)
    amp = torch.as_tensor(noise_amplitude, dtype=torch.float32)
    amp = amp.expand(num_samples, L) if amp.ndim == 1 else amp
    z = [torch.empty(num_samples, 1, n) for n in lengths]
    for b in range(num_samples):
        state = np.random.SeedSequence([base, b]).generate_state(2, np.uint32)
        g = torch.Generator().manual_seed(int(state[0]) << 32 | int(state[1]))
        for i in range(L):
            z[i][b, 0] = torch.randn(lengths[i], generator=g)
    return [(z[i] * amp[:, i, None, None]).to(device) for i in range(L)]  # (B, 1, T_i)


def check_conditions(
    model: GenerativeModel, conds: list, lengths: Sequence[int], num_samples: int = 1
) -> list:
    """Per-level conditions checked against the model and the level lengths and put on
    its device; a condition constant over time becomes ``(B, 1, D)`` (its FiLM
    parameters are then computed once per sample). A level's condition may also be a
    list of ``(channel mask (C,), condition)`` pairs (``MultiResGenerator.run_batch``)."""
    out = []
    for i, c in enumerate(conds):
        if isinstance(c, (list, tuple)):
            parts = []
            for mask, cc in c:
                (cc,) = check_conditions(model, [cc], lengths[i : i + 1], num_samples)
                m = torch.as_tensor(mask, dtype=torch.float32, device=model.device)
                parts.append((m, cc))
            out.append(parts)
            continue
        c = torch.as_tensor(c, dtype=torch.float32)
        if c.ndim != 3 or c.shape[1] != lengths[i] or c.shape[2] != model.generator.cond_dim:
            raise MotionValueError(
                f"condition of level {i + 1} must be (B, {lengths[i]}, "
                f"{model.generator.cond_dim}), got {tuple(c.shape)}"
            )
        if c.stride(1) == 0 or bool((c == c[:, :1]).all()):
            c = c[:, :1]  # constant over time (a label): FiLM once per sample
        out.append(c.expand(num_samples, -1, -1).to(model.device))  # (B, T_i or 1, D)
    return out


def _layout(model: GenerativeModel, table: torch.Tensor) -> PackedLevels:
    return PackedLevels.from_table(table, model.config.model.kernel_size - 1, model.device)


def _to_motion(
    model: GenerativeModel, x: torch.Tensor, fps: float, label: str | None, name: str
) -> Motion:
    return features_to_motion(
        x.T, fps, betas=model.betas, normalizer=model.normalizer, label=label, name=name
    )


def _to_motions(
    model: GenerativeModel, x: torch.Tensor, fps: float, label: str | None, names: list[str]
) -> list[Motion]:
    """``(B, C, T)`` normalised features -> B Motions in one conversion."""
    return features_to_motions(
        x.transpose(1, 2), fps, betas=model.betas, normalizer=model.normalizer,
        label=label, names=names,
    )  # fmt: skip


def label_inputs(
    model: GenerativeModel, W: torch.Tensor, length: int | None, sampler: Sampler
) -> tuple[list[int], torch.Tensor, list[torch.Tensor]]:
    """What :func:`sample_features` needs for label weights ``W (L, K)``
    (``Condition.weights``): the level lengths for ``length`` output frames (None: the
    first training clip of the coarsest level's main label), the noise amplitude ``(L,)``
    of each level's label mix (:func:`noise_amplitude`), and the per-level conditions
    ``(1, T_i, K)`` under the sampler's guidance (:func:`guided_weights`)."""
    L = model.num_levels
    main = int(W[0].argmax())
    if length is None:
        length = (
            int(model.lengths[model.clip_labels.index(main), -1])
            if main in model.clip_labels
            else int(model.lengths[0, -1])
        )
    length = check_count("length", length)  # its bound: sample_features
    pad = (model.config.model.kernel_size - 1) // 2
    factor = model.config.model.scale_factor
    need = shortest_length(L, factor, min_length=pad + 1)
    if length < need:
        raise ClipTooShortError(
            f"a sample of {length} frames is shorter than this model draws: at least {need} "
            f"frames ({need / model.fps:.3g} s at the model's {model.fps:g} fps)"
        )
    lengths = pyramid_lengths(int(length), L, factor, min_length=pad + 1)
    amp = noise_amplitude(model, W, sampler)
    G = guided_weights(W, sampler)
    conds = [G[i].expand(1, lengths[i], -1) for i in range(L)]
    return lengths, amp, conds


def sampler_record(
    model: GenerativeModel, sampler: Sampler, seed: int | None, index: int, W: torch.Tensor
) -> dict:
    """What made a label sample, as ``meta["sampler"]`` records it: seed, index in the
    batch, the sampler's fine_noise and guidance, the labels and per-level weights ``W``."""
    return {
        "seed": seed, "index": index, "fine_noise": sampler.fine_noise,
        "guidance": sampler.guidance, "candidates": sampler.candidates,
        "match_contact_rate": reads_at_rate(model, sampler, W),
        "labels": list(model.labels),
        "label_weights": W.tolist(), "fps": sampler.fps or model.fps,
    }  # fmt: skip


# training_floor's cache: per model (weakly held: a model dropped is gone from it), per
# clips and body; 0.1 s per 120-frame clip otherwise, as much as the draw itself
_FLOORS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def training_floor(model: GenerativeModel, labels: Sequence[int] | None = None, body=None):
    """The height (m) the planted feet of the model's training clips rest at
    (``mrlib.sampling.cleanup.contact_floor``), over the clips of ``labels`` (indices;
    all clips when None or when none has them): the floor the foot-contact clean-up
    puts generated feet on. None without contact labels. Computed once per model, clips
    and body (a module-level cache that does not keep the model alive)."""
    from mrlib.metrics.plausibility import motion_kinematics
    from mrlib.sampling.cleanup import contact_floor

    cache = _FLOORS.setdefault(model, {})
    clips = [k for k, lab in enumerate(model.clip_labels) if labels is None or lab in labels]
    clips = tuple(clips or range(len(model.clip_labels)))
    key = (clips, body)
    if key not in cache:
        feet, cs = [], []
        for k in clips:
            m = features_to_motion(model.features[k], model.fps, betas=model.betas)
            if m.contacts is not None:
                feet.append(motion_kinematics(m, body)[1])
                cs.append(m.contacts)
        cache[key] = contact_floor(feet, cs) if feet else None
    return cache[key]


def plant_feet(
    model: GenerativeModel,
    motions: list[Motion],
    labels: Sequence[int],
    sampler: Sampler,
    body=None,
) -> list[Motion]:
    """The sampler's foot-contact clean-up of raw samples of ``labels`` (indices) drawn
    with ``sampler`` at ``fix_contacts=False``: what :func:`generate` returns with the
    clean-up on, from the same draws."""
    floor = training_floor(model, labels, body)
    # the generator's frame-to-frame jitter spans fps / model.fps frames once raised:
    # filtered over the same time (bench/output_rate.py)
    jitter = jitter_at(sampler.fps or model.fps, model.fps)
    return [cleanup_foot_contacts(m, body, floor=floor, jitter=jitter) for m in motions]


def _label_samples(
    model: GenerativeModel,
    condition: Condition,
    num: int,
    length: int | None,
    seed: int | None,
    sampler: Sampler,
    body,
    levels: bool,
) -> tuple[list[Motion], list[list[Motion]] | None]:
    """``num`` samples of ``condition`` and, with ``levels``, each one's per-level
    Motions (raw)."""
    W = condition.weights(model)  # (L, K)
    L = model.num_levels
    lengths, amp, conds = label_inputs(model, W, length, sampler)
    outs = sample_ranked(model, conds, lengths, amp, seed, num, sampler.candidates)
    label = condition.name(model)
    tag = "unseeded" if seed is None else f"seed{seed}"
    names = [f"{label}_{tag}_{b}" for b in range(num)]
    motions = _to_motions(model, outs[-1], model.fps, label, names)
    if reads_at_rate(model, sampler, W):
        c = output_contacts(model, outs[-1], W)
        motions = [m.replace(contacts=c[b]) for b, m in enumerate(motions)]
    if sampler.fps is not None and sampler.fps != model.fps:  # raised before the feet are planted
        motions = [m.resample(sampler.fps, smooth=True, keep_duration=True) for m in motions]
    for b, m in enumerate(motions):  # what made the sample, saved with it (npz meta_json)
        m.meta["sampler"] = sampler_record(model, sampler, seed, b, W)
    if sampler.fix_contacts:
        motions = plant_feet(model, motions, [int(k) for k in W.argmax(1).unique()], sampler, body)
    if not levels:
        return motions, None
    fps_i = level_fps(model.fps, lengths)
    per_level = [
        [_to_motion(model, outs[i][b], fps_i[i], label, f"{label}_level{i + 1}") for i in range(L)]
        for b in range(num)
    ]
    return motions, per_level


def shaped_samples(motions: list, per_level: list | None, num: int | None):
    """The return convention of :func:`generate` (and ``generate_from_audio``)."""
    out = motions if per_level is None else list(zip(motions, per_level, strict=True))
    return out[0] if num is None else out


@checked()
def generate(
    model: GenerativeModel,
    condition: str | int | Condition | None = None,
    *,
    length: int | None = None,
    seed: int | None = None,
    num: int | None = None,
    sampler: Sampler | None = None,
    levels: bool = False,
    body=None,
):
    """Random motion of a label model: one sample, a batch, and every level's output.

    Args:
        model: a loaded model (``mrlib.load_model(checkpoint)``). A checkpoint's path is
            refused with an ``ArgumentError`` that gives the line loading it: mrlib never
            loads a model behind a sampling call (a loop of calls would read the file
            every time, on a device the caller did not choose). Arguments of the wrong
            type are refused the same way before any work (``mrlib.sampling.arguments``).
        condition: a label name (``"walk_happy"``) or index, the same at every level, or
            a ``mrlib.Condition`` (``Condition.crossover(a, b, level)``,
            ``Condition.levels([...])``, ``Condition.blend(a, b, w)``); None: the
            model's first label.
        length: frames of the output (any length, also longer than the training clips,
            up to ``MAX_SAMPLE_SECONDS``); default: the first training clip of the
            coarsest level's main label.
        seed: for reproducible noise: sample ``b`` is noise stream ``(seed, b)``, so it
            does not depend on ``num`` (the single sample is ``b = 0``).
        num: None for one sample; a count ``k`` for a batch of ``k``.
        sampler: a ``mrlib.Sampler`` (fine noise, guidance, the foot-contact clean-up;
            ``Sampler(fix_contacts=False)`` gives the generator's raw output); default
            ``Sampler()``: the paper's sampler, each sample the best of
            ``Sampler.candidates`` draws by the model's critics, with the feet planted by
            :func:`cleanup_foot_contacts` (milliseconds per clip).
        levels: also return every level's output ``[level 1, ..., level L]`` as Motions
            at the level's frame rate (``fps * T_i / T_L``), always raw: the pyramid
            coarse to fine.
    Returns:
        One type per call shape:

        * ``num=None, levels=False``: a ``Motion``;
        * ``num=k, levels=False``: a list of ``k`` Motions (also for ``k = 1``);
        * ``num=None, levels=True``: ``(motion, [level Motions])``;
        * ``num=k, levels=True``: a list of ``k`` such pairs.

        Motions are SMPL parameters at the training fps; ``meta["sampler"]`` records
        what made each (seed, index in the batch, fine_noise, guidance, the per-level
        label weights), and ``save_motion`` keeps it in the .npz.
    """
    condition = as_condition(0 if condition is None else condition)
    sampler = Sampler() if sampler is None else sampler
    if condition.parts_of is not None:
        raise MotionValueError(
            "a body-part condition splices samples of several labels: generate it with "
            "mrlib.sampling.constraints.generate_parts(model, condition, ...), which takes "
            "the same length, seed, num and sampler"
        )
    count = 1 if num is None else num
    motions, per_level = _label_samples(
        model, condition, count, length, seed, sampler, body, levels
    )
    return shaped_samples(motions, per_level, num)


@checked(clip_index=lambda n, v: check_number(n, v, low=0, integer=True))
def _reconstruct_features(model: GenerativeModel, clip_index: int) -> list[torch.Tensor]:
    """Normalised features ``[(1, C, T_i)]`` of every level of training clip
    ``clip_index`` regenerated from its fixed noise (z*_1 at level 1, zero above) and
    its own label, as in the reconstruction loss."""
    N = len(model.clip_names)
    if not 0 <= clip_index < N:
        raise MotionValueError(f"clip_index {clip_index} out of range [0, {N})")
    dev = model.device
    lengths = model.lengths[clip_index].tolist()
    layout = _layout(model, torch.tensor([lengths]))
    cond = torch.zeros(len(model.labels), 1)
    cond[model.clip_labels[clip_index]] = 1
    conds = [layout.pack([cond.expand(-1, n)], i).transpose(1, 2) for i, n in enumerate(lengths)]
    noises = [layout.pack([model.zstar[clip_index]], 0)]
    noises += [torch.zeros(1, 1, layout.sizes[i], device=dev) for i in range(1, len(lengths))]
    with torch.no_grad():
        outs = model.generator.run(layout, noises, conds, keep=True)
    return [layout.unpack(o, i)[0][None] for i, o in enumerate(outs)]


@checked(clip_index=lambda n, v: check_number(n, v, low=0, integer=True))
def reconstruct(
    model: GenerativeModel, clip_index: int, *, levels: bool = False
) -> Motion | tuple[Motion, list[Motion]]:
    """Training clip ``clip_index`` regenerated from its fixed noise z* and its label
    (no sampler: the reconstruction the training loss sees). Returns a ``Motion``; with
    ``levels``, ``(motion, [level Motions])``, every level's output at the level's frame
    rate (``fps * T_i / T_L``)."""
    outs = _reconstruct_features(model, clip_index)
    label = model.labels[model.clip_labels[clip_index]]
    name = f"{model.clip_names[clip_index]}_reconstruction"
    motion = _to_motion(model, outs[-1][0], model.fps, label, name)
    if not levels:
        return motion
    fps_i = level_fps(model.fps, [o.shape[-1] for o in outs])
    per_level = [
        _to_motion(model, o[0], f, label, f"{name}_level{i + 1}")
        for i, (o, f) in enumerate(zip(outs, fps_i, strict=True))
    ]
    return motion, per_level


def reconstruction_error(model: GenerativeModel, clip_index: int) -> float:
    """Mean absolute error between the normalised features of the reconstruction and of
    the training clip: the training's L_rec at the finest level."""
    out = _reconstruct_features(model, clip_index)[-1][0]
    target = model.normalizer.normalize(model.features[clip_index].to(out.device)).T
    return float((out - target).abs().mean())
