"""Each label's reading of the generator's contact output, chosen by the model at the end
of training.

The generator outputs a foot vertex's contact label as a number near 0 or 1; a label
sample reads it either where it exceeds 0.5 (the paper's cut) or at the label's contact
rate (``mrlib.sampling.contact_labels``). Which of the two keeps a label's samples nearer
its own clips differs from model to model and label to label
(docs/notes/2026-12-07-contact-rate.md: the cut lost a slow walk's contacts on a 30-fps
model, the rate moved a fast walk away from its clip on a 15-fps one).
:func:`choose_contact_reading` asks the model's own training clips: per label, ``num``
draws of twice the label's longest clip (the default sampler's, without the clean-up) are
read both ways (draws of at most ``CHOICE_MAX_SECONDS``), and the rate is chosen where its
samples' windows are nearer their own label's clips than the cut's by more than ``margin``
(the condition fidelity of ``mrlib.metrics.coverage``, windows of ``window`` frames). A
model of one label (every window is its own) or whose clips of some label are shorter
than a window keeps the cut for every label. Nothing but the training clips and the model
is read. The trainer calls it when a label model's training ends and keeps
the answer in the checkpoint (``GenerativeModel.contact_at_rate``).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from mrlib.errors import MrlibError, check_count
from mrlib.metrics.coverage import condition_fidelity
from mrlib.metrics.windows import model_references
from mrlib.model.checkpoint import CheckpointWarning, load_checkpoint, save_checkpoint
from mrlib.model.trained import is_speech_model
from mrlib.representation.features import features_to_motions
from mrlib.sampling.conditions import Condition
from mrlib.sampling.contact_labels import output_contacts
from mrlib.sampling.generation import label_inputs, sample_ranked
from mrlib.sampling.sampler import Sampler

__all__ = [
    "CHOICE_SAMPLES",
    "CHOICE_SEED",
    "CHOICE_MARGIN",
    "CHOICE_MAX_SECONDS",
    "choose_contact_reading",
    "settle_contact_reading",
]

CHOICE_SAMPLES = 8  # draws per label
CHOICE_SEED = 7919  # a seed of its own: not the seeds evaluations and notebooks draw with
CHOICE_MARGIN = 0.01  # the rate must win by one point of fidelity; ties keep the paper's cut
CHOICE_MAX_SECONDS = 60.0  # draws of twice the longest clip, at most this long


def choose_contact_reading(
    model,
    num: int = CHOICE_SAMPLES,
    seed: int = CHOICE_SEED,
    margin: float = CHOICE_MARGIN,
    window: int = 30,
) -> tuple[str, ...]:
    """The labels of ``model`` whose samples read their contacts at the label's rate (see
    the module's docstring). Deterministic for a model, seed and torch thread count."""
    num = check_count("num", num)
    _, clip_labels, feats = model_references(model)
    refs = {
        lab: np.concatenate([f for f, lb in zip(feats, clip_labels, strict=True) if lb == lab])
        for lab in dict.fromkeys(clip_labels)
    }
    if len(refs) < 2 or any(len(r) < window for r in refs.values()):
        return ()
    longest = max(window, int(CHOICE_MAX_SECONDS * model.fps))
    sampler = Sampler(fix_contacts=False)
    chosen = []
    for k, label in enumerate(model.labels):
        if label not in refs:
            continue
        W = Condition.label(label).weights(model)
        clips = zip(model.features, model.clip_labels, strict=True)
        n = max(min(2 * int(max(len(x) for x, c in clips if c == k)), longest), window)
        lengths, amp, conds = label_inputs(model, W, n, sampler)
        out = sample_ranked(model, conds, lengths, amp, seed, num, sampler.candidates)[-1]
        cut = features_to_motions(
            out.transpose(1, 2), model.fps, betas=model.betas, normalizer=model.normalizer,
            label=label, names=[f"{label}_{b}" for b in range(num)],
        )  # fmt: skip
        c = output_contacts(model, out, W)
        rate = [m.replace(contacts=c[b]) for b, m in enumerate(cut)]
        f_cut = condition_fidelity(cut, refs, window)
        f_rate = condition_fidelity(rate, refs, window)
        if f_rate > f_cut + margin:
            chosen.append(label)
    return tuple(chosen)


def settle_contact_reading(
    model, progress: bool = False, checkpoint: str | Path | None = None
) -> tuple[str, ...] | None:
    """:func:`choose_contact_reading` for a finished label model without a recorded
    choice, set on it (``model.contact_at_rate``), written into ``checkpoint`` (the file
    it was loaded from) when given, and returned; None for a speech model (its samples
    follow audio), an unfinished one, or one that has a choice already."""
    done = model.trained_levels >= model.num_levels
    if is_speech_model(model) or not done or model.contact_at_rate is not None:
        return None
    if progress:
        print(f"choosing the contact reading of {len(model.labels)} label(s)", flush=True)
    try:
        model.contact_at_rate = choose_contact_reading(model)
    except MrlibError as e:  # the choice refines sampling; a model is never lost to it
        warnings.warn(
            f"could not choose the contact reading ({e}): every label is cut at 0.5",
            CheckpointWarning,
            stacklevel=2,
        )
        model.contact_at_rate = ()
    if checkpoint is not None:
        state = load_checkpoint(checkpoint)
        state["contact_at_rate"] = list(model.contact_at_rate)
        save_checkpoint(checkpoint, state)
    return model.contact_at_rate
