"""Contact labels of a label sample at its label's contact rate.

The generator outputs each foot vertex's contact label as a number that training pulls
towards 0 or 1; the paper cuts it at 0.5. Where the output is unsure (values between the
two, most often on a slow walk whose contacts start and end gradually), the cut can label
far fewer frames in contact than the label's training clips have: the giant walk of the
held-out Bandai styles, 34 % of its samples' frames against its clip's 50 %
(docs/notes/2026-12-07-contact-rate.md).

:func:`rate_matched_contacts` labels each vertex of a sample in contact on the frames of
its highest output, as many as the label's training clips are in contact (the share of
their frames, per vertex: :func:`label_contact_rates`; mixed conditions weigh the labels'
rates by the condition's mean weights over levels). The cut this needs is kept within
``CONTACT_BAND``: an output above its upper end is always a contact, one below its lower
end never, so that a confident output is not overruled to reach a rate. This is what
``Sampler(match_contact_rate=True)`` does to label samples (``mrlib.generate``, and the
paths, keyframes, continuations, loops and body parts of ``mrlib.sampling.constraints``) of
the labels it is chosen for. Which reading serves a label is not the same on every model
(on the 15-fps ``preview`` models the happy walk's fidelity fell with it, the same note),
so each model chooses per label at the end of training (``mrlib.sampling.contact_choice``,
``GenerativeModel.contact_at_rate``); ``Sampler(match_contact_rate=True / False)`` reads
every label one way.

Dimension letters (``mrlib`` glossary): B samples, T frames, K labels.
"""

from __future__ import annotations

import weakref

import numpy as np
import torch

from mrlib.errors import MotionValueError
from mrlib.representation.skeleton import CONTACT_NAMES

__all__ = [
    "CONTACT_BAND",
    "label_contact_rates",
    "condition_contact_rates",
    "rate_matched_contacts",
    "output_contacts",
    "reads_at_rate",
]

# Outputs within 0.1 of a label are that label whatever the rate asks.
CONTACT_BAND = (0.1, 0.9)

_NC = len(CONTACT_NAMES)
_RATES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def label_contact_rates(model) -> np.ndarray:
    """``(K, 6)``: per label, the share of its training clips' frames in which each foot
    vertex is labelled in contact (frames pooled over the label's clips; computed once
    per model)."""
    if model in _RATES:
        return _RATES[model]
    rates = np.zeros((len(model.labels), _NC))
    for k in range(len(model.labels)):
        cs = [
            np.asarray(x[:, -_NC:].detach().cpu(), np.float64) > 0.5
            for x, lab in zip(model.features, model.clip_labels, strict=True)
            if lab == k
        ]
        if cs:
            rates[k] = np.concatenate(cs).mean(0)
    _RATES[model] = rates
    return rates


def condition_contact_rates(model, W: torch.Tensor) -> np.ndarray:
    """``(6,)``: the labels' contact rates weighed by a condition's mean weights over
    levels (``W (L, K)``, ``Condition.weights(model)``)."""
    w = np.asarray(torch.as_tensor(W).detach().cpu(), np.float64).mean(0)
    w = np.clip(w, 0.0, None)
    if w.sum() <= 0:
        raise MotionValueError("the condition weighs no label")
    return (w / w.sum()) @ label_contact_rates(model)


def rate_matched_contacts(
    raw: np.ndarray | torch.Tensor, rates: np.ndarray, band: tuple[float, float] = CONTACT_BAND
) -> np.ndarray:
    """Contact labels ``(B, T, 6)`` in {0, 1} (float32) from the generator's contact
    outputs ``raw (B, T, 6)`` (denormalised): per sample and vertex, the frames whose
    output exceeds the ``1 - rate`` quantile of that sample's outputs, the cut clipped
    to ``band``."""
    x = np.asarray(torch.as_tensor(raw).detach().cpu(), np.float64)
    rates = np.asarray(rates, np.float64)
    if x.ndim != 3 or x.shape[-1] != _NC or rates.shape != (_NC,):
        raise MotionValueError(
            f"need outputs (B, T, {_NC}) and rates ({_NC},), got {x.shape} and {rates.shape}"
        )
    lo, hi = band
    cut = np.quantile(x, 1.0 - np.clip(rates, 0.0, 1.0), axis=1)  # (6, B, 6)
    cut = np.clip(cut[np.arange(_NC), :, np.arange(_NC)].T, lo, hi)  # (B, 6)
    return (x > cut[:, None, :]).astype(np.float32)


def output_contacts(model, x: torch.Tensor, W: torch.Tensor) -> np.ndarray:
    """Contact labels ``(B, T, 6)`` at the rate of condition ``W`` (``(L, K)``) for the
    generator's normalised output ``x (B, C, T)``."""
    y = x.detach().cpu().transpose(1, 2)
    y = y if model.normalizer is None else model.normalizer.denormalize(y)
    return rate_matched_contacts(y[..., -_NC:], condition_contact_rates(model, W))


def reads_at_rate(model, sampler, W: torch.Tensor) -> bool:
    """Whether a label sample of condition ``W`` (``(L, K)``) drawn with ``sampler`` reads
    its contacts at the condition's rate: ``sampler.match_contact_rate`` when set, else the
    model's choice for the label of highest mean weight over levels
    (``GenerativeModel.contact_at_rate``; a model without a choice, from a checkpoint
    written before models chose, reads at 0.5)."""
    if sampler.match_contact_rate is not None:
        return bool(sampler.match_contact_rate)
    chosen = getattr(model, "contact_at_rate", None)
    if not chosen:
        return False
    k = int(torch.as_tensor(W).detach().cpu().float().mean(0).argmax())
    return model.labels[k] in chosen
