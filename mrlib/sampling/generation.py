"""Sampling from a trained model: random generation under one or several conditions,
any length, per-level condition assignment and blending, reconstruction of the training
clips, and an optional foot-contact clean-up (``mrlib.sampling.cleanup``).

Levels are 1-based in this module's public API (level 1 is the coarsest), as in the
paper; ``conditions=[("walk_normal", (1, 4)), ("walk_happy", (5, 8))]`` gives levels
1-4 the first label and levels 5-8 the second.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from mrlib.errors import MotionValueError, check_count, check_number, check_seed
from mrlib.model.pyramid import PackedLevels, level_fps, pyramid_lengths
from mrlib.model.trained import GenerativeModel
from mrlib.representation.features import features_to_motion, features_to_motions
from mrlib.representation.motion import Motion
from mrlib.sampling.arguments import checked
from mrlib.sampling.cleanup import cleanup_foot_contacts
from mrlib.threads import with_policy

# one sample: a 10-minute walk stays within mrlib.representation.motion's 1000 m
MAX_SAMPLE_SECONDS = 600.0
MAX_GUIDANCE = MAX_FINE_NOISE = 10.0  # sampler settings: 1 already leaves the training poses
MAX_SAMPLE_FRAMES = 200_000  # all samples of one call or command (~0.5 GB while generating)

__all__ = [
    "label_weights",
    "guided_weights",
    "noise_amplitude",
    "sample_features",
    "generate",
    "generate_many",
    "generate_levels",
    "reconstruct",
    "reconstruct_levels",
    "reconstruct_features",
    "training_floor",
    "reconstruction_error",
]


# -- conditions ---------------------------------------------------------------------------
def label_weights(
    model: GenerativeModel,
    condition: str | int | None = None,
    conditions: Sequence[tuple[str | int, tuple[int, int]]] | None = None,
    blend: tuple[str | int, str | int, float | Sequence[float]] | None = None,
) -> torch.Tensor:
    """Per-level label weights ``(L, K)``: row i is the condition vector of level i+1.

    Exactly one of: ``condition`` (one label at every level); ``conditions`` (labels
    assigned to 1-based inclusive level ranges that together cover 1..L once); ``blend``
    ``(a, b, w)``: ``(1 - w) * a + w * b`` with ``w`` a float or one weight per level
    (the FiLM embedding is linear in the condition, so this interpolates embeddings).
    """
    L, K = model.num_levels, len(model.labels)
    given = sum(x is not None for x in (condition, conditions, blend))
    if given != 1:
        raise MotionValueError("give exactly one of condition, conditions or blend")
    W = torch.zeros(L, K)
    if condition is not None:
        W[:, model.label_index(condition)] = 1
    elif conditions is not None:
        covered = np.zeros(L, int)
        for lab, (lo, hi) in conditions:
            if not 1 <= lo <= hi <= L:
                raise MotionValueError(
                    f"level range ({lo}, {hi}) must satisfy 1 <= lo <= hi <= {L}"
                )
            W[lo - 1 : hi, model.label_index(lab)] = 1
            covered[lo - 1 : hi] += 1
        if not (covered == 1).all():
            raise MotionValueError(
                f"level ranges must cover levels 1..{L} exactly once, coverage {covered.tolist()}"
            )
    else:
        a, b, w = blend
        w = torch.as_tensor(w, dtype=torch.float32).reshape(-1)
        if w.numel() == 1:
            w = w.expand(L)
        if w.numel() != L:
            raise MotionValueError(f"blend weights need 1 or {L} values, got {w.numel()}")
        if not bool(((w >= 0) & (w <= 1)).all()):
            raise MotionValueError(
                f"blend weights must be in [0, 1], got {w.tolist()}; to exaggerate a label "
                "beyond its clips use the model's guidance"
            )
        W[:, model.label_index(a)] += 1 - w
        W[:, model.label_index(b)] += w
    return W


def guided_weights(model: GenerativeModel, W: torch.Tensor) -> torch.Tensor:
    """Label weights ``W (L, K)`` under ``model.guidance`` g: ``W + g (W - 1/K)``, each
    level's condition pushed away from the mean of all labels (``GUIDANCE``). Rows still
    sum to one; with g > 0 some weights are negative, which the linear label embedding
    takes as extrapolation beyond the label. A one-label model has nothing to push from."""
    g = float(model.guidance)
    if not (np.isfinite(g) and 0 <= g <= MAX_GUIDANCE):
        raise MotionValueError(f"guidance must be in [0, {MAX_GUIDANCE:g}], got {model.guidance!r}")
    if g == 0:
        return W
    return W + g * (W - 1.0 / W.shape[-1])


# -- sampling -----------------------------------------------------------------------------
def noise_amplitude(model: GenerativeModel, W: torch.Tensor | None = None) -> torch.Tensor:
    """``(L,)`` sigma of each level's sampling noise: the training ``sigma_i`` of the
    level's label mix ``W (L, K)`` (:func:`label_weights`; default: the first label),
    the finest level's scaled by ``model.fine_noise``."""
    fine = float(model.fine_noise)
    if not (np.isfinite(fine) and 0 <= fine <= MAX_FINE_NOISE):
        raise MotionValueError(
            f"fine_noise must be in [0, {MAX_FINE_NOISE:g}], got {model.fine_noise!r}"
        )
    sigma = model.sigma.float()  # (K, L)
    amp = sigma[0].clone() if W is None else (W.float() * sigma.T).sum(1)
    amp[-1] = amp[-1] * fine
    return amp


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
            f"num_samples: {num_samples} samples of {frames} frames are more than the "
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
    model: GenerativeModel, W: torch.Tensor, length: int | None = None
) -> tuple[list[int], torch.Tensor, list[torch.Tensor]]:
    """What :func:`sample_features` needs for label weights ``W (L, K)``
    (:func:`label_weights`): the level lengths for ``length`` output frames (default:
    the first training clip of the coarsest level's main label), the noise amplitude
    ``(L,)`` of each level's label mix (:func:`noise_amplitude`), and the per-level
    conditions ``(1, T_i, K)`` (under ``model.guidance``, :func:`guided_weights`)."""
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
    lengths = pyramid_lengths(int(length), L, model.config.model.scale_factor, min_length=pad + 1)
    amp = noise_amplitude(model, W)
    G = guided_weights(model, W)
    conds = [G[i].expand(1, lengths[i], -1) for i in range(L)]
    return lengths, amp, conds


def sampler_record(model: GenerativeModel, seed: int | None, index: int, W: torch.Tensor) -> dict:
    """What made a label sample, as ``meta["sampler"]`` records it: seed, index in the
    batch, the sampler's fine_noise and guidance, the labels and per-level weights ``W``."""
    return {
        "seed": seed, "index": index, "fine_noise": float(model.fine_noise),
        "guidance": float(model.guidance), "labels": list(model.labels),
        "label_weights": W.tolist(),
    }  # fmt: skip


@with_policy
def training_floor(model: GenerativeModel, labels: Sequence[int] | None = None, body=None):
    """The height (m) the planted feet of the model's training clips rest at
    (``mrlib.sampling.cleanup.contact_floor``), over the clips of ``labels`` (indices;
    all clips when None or when none has them): the floor the foot-contact clean-up
    puts generated feet on. None without contact labels. Cached on the model."""
    from mrlib.metrics.plausibility import motion_kinematics
    from mrlib.sampling.cleanup import contact_floor

    cache = model.__dict__.setdefault("_training_floor", {})
    clips = [k for k, lab in enumerate(model.clip_labels) if labels is None or lab in labels]
    key = tuple(clips or range(len(model.clip_labels)))
    if key not in cache:
        feet, cs = [], []
        for k in key:
            m = features_to_motion(model.features[k], model.fps, betas=model.betas)
            if m.contacts is not None:
                feet.append(motion_kinematics(m, body)[1])
                cs.append(m.contacts)
        cache[key] = contact_floor(feet, cs) if feet else None
    return cache[key]


def _label_samples(
    model: GenerativeModel,
    num_samples: int,
    condition,
    length: int | None,
    seed: int | None,
    conditions,
    blend,
    fix_contacts: bool | str,
    body,
    levels: bool,
) -> tuple[list[Motion], list[list[Motion]] | None]:
    """What :func:`generate`, :func:`generate_many` and :func:`generate_levels` share:
    ``num_samples`` samples and, with ``levels``, each one's per-level Motions."""
    W = label_weights(model, condition, conditions, blend)  # (L, K)
    L = model.num_levels
    lengths, amp, conds = label_inputs(model, W, length)
    outs = sample_features(
        model, conds, lengths, amp, seed=seed, num_samples=num_samples, keep=True
    )
    names = [model.labels[int(k)] for k in W.argmax(1)]
    label = (
        names[0]
        if len(set(names)) == 1 and float(W.max(1).values.min()) == 1.0
        else "+".join(dict.fromkeys(names))
    )
    names = [f"{label}_seed{seed}_{b}" for b in range(num_samples)]
    motions = _to_motions(model, outs[-1], model.fps, label, names)
    for b, m in enumerate(motions):  # what made the sample, saved with it (npz meta_json)
        m.meta["sampler"] = sampler_record(model, seed, b, W)
    if fix_contacts:
        method = fix_contacts if isinstance(fix_contacts, str) else "ik"
        floor = training_floor(model, [int(k) for k in W.argmax(1).unique()], body)
        motions = [cleanup_foot_contacts(m, body, method=method, floor=floor) for m in motions]
    if not levels:
        return motions, None
    fps_i = level_fps(model.fps, lengths)
    per_level = [
        [_to_motion(model, outs[i][b], fps_i[i], label, f"{label}_level{i + 1}") for i in range(L)]
        for b in range(num_samples)
    ]
    return motions, per_level


@checked()
@with_policy
def generate(
    model: GenerativeModel,
    condition: str | int | None = None,
    length: int | None = None,
    seed: int | None = None,
    *,
    conditions: Sequence[tuple[str | int, tuple[int, int]]] | None = None,
    blend: tuple[str | int, str | int, float | Sequence[float]] | None = None,
    fix_contacts: bool | str = True,
    body=None,
) -> Motion:
    """One random motion under label conditions (several: :func:`generate_many`; every
    level's output too: :func:`generate_levels`).

    Args:
        model: a loaded model (``mrlib.load_model(checkpoint)``). A checkpoint's path is
            refused with an ``ArgumentError`` that gives the line loading it: mrlib never
            loads a model behind a sampling call (a loop of calls would read the file
            every time, on a device the caller did not choose). Arguments of the wrong
            type are refused the same way before any work (``mrlib.sampling.arguments``).
        condition: a label name (``"walk_happy"``) or index for every level; or use
            ``conditions`` / ``blend`` (see :func:`label_weights`).
        length: frames of the output (any length, also longer than the training clips,
            up to ``MAX_SAMPLE_SECONDS``); default: the first training clip of the
            coarsest level's main label.
        seed: for reproducible noise (the sample is stream ``(seed, 0)``, the first of
            ``generate_many`` with the same seed).
        fix_contacts: plant the feet with :func:`cleanup_foot_contacts` (default: its
            ``"ik"`` method, milliseconds per clip); a method name (``"ik"``,
            ``"optimise"``), or False for the generator's raw output.
    Returns:
        a ``Motion`` (SMPL parameters at the training fps); ``meta["sampler"]`` records
        what made it (seed, index in the batch, fine_noise, guidance, the per-level label
        weights), and ``save_motion`` keeps it in the .npz.
    """
    motions, _ = _label_samples(
        model, 1, condition, length, seed, conditions, blend, fix_contacts, body, False
    )
    return motions[0]


@checked()
@with_policy
def generate_many(
    model: GenerativeModel,
    condition: str | int | None = None,
    length: int | None = None,
    seed: int | None = None,
    *,
    num_samples: int,
    conditions: Sequence[tuple[str | int, tuple[int, int]]] | None = None,
    blend: tuple[str | int, str | int, float | Sequence[float]] | None = None,
    fix_contacts: bool | str = True,
    body=None,
) -> list[Motion]:
    """``num_samples`` motions of :func:`generate`'s kind in one batch: always a list.
    Sample ``b`` is noise stream ``(seed, b)``, so it does not depend on the batch size
    (sample 0 is ``generate(..., seed=seed)``)."""
    motions, _ = _label_samples(
        model, num_samples, condition, length, seed, conditions, blend, fix_contacts, body, False
    )
    return motions


@checked()
@with_policy
def generate_levels(
    model: GenerativeModel,
    condition: str | int | None = None,
    length: int | None = None,
    seed: int | None = None,
    *,
    conditions: Sequence[tuple[str | int, tuple[int, int]]] | None = None,
    blend: tuple[str | int, str | int, float | Sequence[float]] | None = None,
    fix_contacts: bool | str = True,
    body=None,
) -> tuple[Motion, list[Motion]]:
    """:func:`generate`'s motion and every level's output ``[level 1, ..., level L]`` as
    Motions at the level's frame rate (``fps * T_i / T_L``), always raw: the pyramid
    coarse to fine, for plots such as notebook 02's."""
    motions, levels = _label_samples(
        model, 1, condition, length, seed, conditions, blend, fix_contacts, body, True
    )
    return motions[0], levels[0]


@checked(clip_index=lambda n, v: check_number(n, v, low=0, integer=True))
def reconstruct_features(model: GenerativeModel, clip_index: int) -> list[torch.Tensor]:
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
def reconstruct(model: GenerativeModel, clip_index: int) -> Motion:
    """Training clip ``clip_index`` regenerated from z* and its label (with every level:
    :func:`reconstruct_levels`)."""
    outs = reconstruct_features(model, clip_index)
    label = model.labels[model.clip_labels[clip_index]]
    name = f"{model.clip_names[clip_index]}_reconstruction"
    return _to_motion(model, outs[-1][0], model.fps, label, name)


@checked(clip_index=lambda n, v: check_number(n, v, low=0, integer=True))
def reconstruct_levels(model: GenerativeModel, clip_index: int) -> tuple[Motion, list[Motion]]:
    """:func:`reconstruct`'s motion and every level's output as Motions at the level's
    frame rate (``fps * T_i / T_L``)."""
    outs = reconstruct_features(model, clip_index)
    label = model.labels[model.clip_labels[clip_index]]
    name = f"{model.clip_names[clip_index]}_reconstruction"
    motion = _to_motion(model, outs[-1][0], model.fps, label, name)
    fps_i = level_fps(model.fps, [o.shape[-1] for o in outs])
    levels = [
        _to_motion(model, o[0], f, label, f"{name}_level{i + 1}")
        for i, (o, f) in enumerate(zip(outs, fps_i, strict=True))
    ]
    return motion, levels


def reconstruction_error(model: GenerativeModel, clip_index: int) -> float:
    """Mean absolute error between the normalised features of the reconstruction and of
    the training clip: the training's L_rec at the finest level."""
    out = reconstruct_features(model, clip_index)[-1][0]
    target = model.normalizer.normalize(model.features[clip_index].to(out.device)).T
    return float((out - target).abs().mean())
