"""Reference code of body-part composition by FiLM, the alternative to the splice that
``mrlib.sampling.constraints.compose`` had as ``generate_many_parts(..., method="film")``,
kept for ``bench/constraints.py --only parts``, which measures it against the splice.

One generator pass, each group's channels modulated by its own condition's FiLM
parameters at every level (``LevelGenerator.modulate``; the channel-to-joint map of the
skeleton-aware convolutions says which channels are a group's: the root displacement
belongs to the pelvis, each contact label to its foot). The networks see the whole body,
so a part's label leaks into its neighbours through the convolutions: on the Bandai
walks the parts kept their labels less often than spliced ones
(``docs/notes/2026-12-06-study-options.md``). It has no gait to align: one sample.

Not maintained as a claim: the benchmark imports it (``from experiments.film_parts
import generate_film_parts``, with ``bench/`` on the path as when a benchmark runs).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import torch

from mrlib.sampling.constraints.compose import _groups


def channel_masks(groups) -> list[torch.Tensor]:
    """Per ``(joints, condition)`` group, ``(C,)`` 1 on the feature channels its joints own."""
    from mrlib.representation.features import channel_joint

    owner = channel_joint()
    return [torch.from_numpy(np.isin(owner, js).astype(np.float32)) for js, _ in groups]


def generate_film_parts(
    model, parts: Mapping[str, str], length: int | None = None, *, seed: int | None = None,
    num_samples: int = 1, sharpen: int = 0, sampler=None, body=None,
) -> list:  # fmt: skip
    """``num_samples`` Motions of a label model with each body part of ``parts``
    (``{"upper": "walk_happy", "lower": "walk_sad"}``) under its own label, by FiLM
    (module docstring); ``sharpen``: Adam steps of the noise fit of
    ``mrlib.sampling.constraints.sharpen`` (0: none); ``sampler``: a ``mrlib.Sampler``
    (fine noise, guidance, and whether the feet are planted)."""
    from mrlib.representation.features import features_to_motions
    from mrlib.sampling.cleanup import cleanup_foot_contacts
    from mrlib.sampling.conditions import label_weights
    from mrlib.sampling.constraints.sharpen import Sharpening, sharpened_features
    from mrlib.sampling.generation import (
        check_conditions,
        draw_noise,
        guided_weights,
        label_inputs,
        noise_amplitude,
        sample_features,
    )
    from mrlib.sampling.sampler import Sampler

    sampler = Sampler() if sampler is None else sampler
    groups = _groups(parts)
    tag = ",".join(f"{p}={c}" for p, c in parts.items())
    Ws = [label_weights(model, c) for _, c in groups]
    lengths, _, _ = label_inputs(model, Ws[0], length, sampler)
    amp = torch.stack([noise_amplitude(model, W, sampler) for W in Ws]).mean(0)
    masks = channel_masks(groups)
    Gs = [guided_weights(W, sampler) for W in Ws]
    conds = [
        [(m, G[i].expand(1, lengths[i], -1)) for m, G in zip(masks, Gs, strict=True)]
        for i in range(model.num_levels)
    ]
    if sharpen:
        noises = draw_noise(lengths, amp, seed, num_samples, model.device)
        cs = check_conditions(model, conds, lengths, num_samples)
        x = sharpened_features(model, noises, cs, {js: c for js, c in groups},
                               Sharpening(steps=sharpen))  # fmt: skip
    else:
        x = sample_features(model, conds, lengths, amp, seed=seed, num_samples=num_samples)
    names = [f"{tag}_seed{seed}_{b}" for b in range(num_samples)]
    out = features_to_motions(x.transpose(1, 2), model.fps, betas=model.betas,
                              normalizer=model.normalizer, label=tag, names=names)  # fmt: skip
    if sampler.fix_contacts:
        out = [cleanup_foot_contacts(m, body) for m in out]
    for m in out:
        m.label = tag
        m.meta["parts"] = dict(parts)
    return out
