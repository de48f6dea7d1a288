"""The evaluation protocol: coverage, diversity and plausibility tables with calibration
rows, for one or several generators.

``evaluate(models, references)`` draws ``num_samples`` clips per training sequence
(label) from each generator, ``length_factor`` times as long as the training clip, with
fixed seeds, and scores them against that clip: the paper's Table 1 metrics (coverage
with ``T_c = 30`` and threshold ``eps``, Eq. 17-18, ``mrlib.metrics.coverage``; global
diversity by patched nearest neighbours with ``T_min = 30``, Eq. 19, and local diversity
with ``T_d = 15``, Eq. 20, ``mrlib.metrics.diversity``) and the
plausibility measures of ``mrlib.metrics.plausibility`` (foot skating, jitter, ground
penetration, Wasserstein distances of speed distributions). The result holds one row
per (method, sequence) and their mean and standard deviation per method, and writes
CSV, Markdown and a PNG plot.

A generator is any callable ``sample_fn(label, length, seed) -> Motion``, given by
method name in ``models``; wire a trained model in with a closure, e.g.
``{"ours": lambda label, length, seed: generate(model, label, length=length, seed=seed)}``
(``mrlib.generate`` returns one ``Motion`` without ``num``; :func:`model_sample_fn`).

**Calibration rows** (``mrlib.evaluation.calibration``, chosen by its
``CalibrationOptions``): the training clip played twice, its first
frame frozen, and other real takes, styles and contents, scored with the same code, so
the generators' numbers can be read against them. Real clips are scored at their own
length; the built rows are one clip each.

**Features.** Coverage and diversity use ``mrlib.metrics.windows.metric_features``: the 23
non-root joints' local rotations in 6D plus the 6 foot-contact labels (``D = 144``).
Clips without contact labels get them from ``mrlib.representation.contacts.foot_contacts`` (speed
threshold 0.25 m/s), so every clip is compared on the same channels. GANimator's
published numbers use its own features (21 joints of its skeleton plus 4 contacts), so
the values here are not on the same scale as GANimator's tables.

The settings and the table (``EvaluationResult``: Markdown, CSV, the summary) are in
``mrlib.evaluation.results``, the calibration motions in ``mrlib.evaluation.calibration``
and the plot in ``mrlib.viz.plots``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from mrlib import metrics as mt
from mrlib.errors import (
    ArgumentError,
    ClipTooShortError,
    MotionValueError,
    check_args,
    check_choice,
    check_flag,
    check_text,
    shown,
)
from mrlib.evaluation.calibration import CALIBRATION_METHODS, CalibrationOptions, calibration_rows
from mrlib.evaluation.results import (
    CALIB_PREFIX,
    MAX_EVAL_FRAMES,
    EvaluationResult,
    EvaluationSettings,
    contact_reading,
    rare_contact_notes,
)
from mrlib.metrics import plausibility as pl
from mrlib.model.trained import check_label_model
from mrlib.progress import bar as progress_bar
from mrlib.representation.body import check_body, resolve_body
from mrlib.representation.motion import Motion
from mrlib.training.data import instance_or_none

__all__ = ["SampleFn", "score_motions", "evaluate", "CalibrationOptions", "EvaluationSettings"]

SampleFn = Callable[[str, int, int], Motion]
"""``sample_fn(label, length, seed) -> Motion``: one generated clip of ``length`` frames."""


# ---------------------------------------------------------------------------------------
# Scoring
# ---------------------------------------------------------------------------------------
@dataclass
class _Reference:
    motion: Motion  # with contact labels
    features: np.ndarray  # (T, D) metric features
    kinematics: tuple[np.ndarray, np.ndarray]  # joints (T, 24, 3), feet (T, 6, 3)


class _ReferenceCache:
    """Contact labels, features and kinematics of training clips, computed once per
    evaluation (keyed by object identity; the clips are kept alive here)."""

    def __init__(self, body: Any, kind: str, contacts: bool = True) -> None:
        self.body, self.kind, self.contacts = body, kind, contacts
        self._store: dict[int, tuple[Motion, _Reference]] = {}

    def __call__(self, motion: Motion) -> _Reference:
        hit = self._store.get(id(motion))
        if hit is not None and hit[0] is motion:
            return hit[1]
        kin = pl.motion_kinematics(motion, self.body)
        labels, _ = pl.motion_contacts(motion, kin[1])
        m = motion.replace(contacts=labels)
        ref = _Reference(m, mt.metric_features(m, kind=self.kind, contacts=self.contacts), kin)
        self._store[id(motion)] = (motion, ref)
        return ref


def score_motions(
    motions: list[Motion],
    reference: Motion,
    *,
    settings: EvaluationSettings | None = None,
    body: Any = None,
    label: str | None = None,
    all_references: Mapping[str, Motion] | None = None,
    reconstruction: Motion | None = None,
    _cache: _ReferenceCache | None = None,
) -> dict[str, float]:
    """All metrics of one row: ``motions`` (B clips) scored against ``reference``.

    Args:
        motions: generated (or calibration) clips at the reference's frame rate.
        reference: the training clip.
        settings: windows, thresholds (default ``EvaluationSettings()``).
        body: ``BodyModel`` (default body when None).
        label: the sequence's label; with ``all_references`` (label -> training clip,
            two labels or more) the condition fidelity is computed.
        reconstruction: the model's reconstruction of ``reference`` (same length), for
            the reconstruction error.

    Returns:
        ``coverage_pct``, ``coverage_tight_pct`` (at ``tight_eps``), ``global_div``, ``local_div``, ``recon_error`` (NaN without a
        reconstruction), ``cond_fidelity_pct`` (NaN unless multi-label), the entries of
        ``mrlib.metrics.plausibility.plausibility_report`` with shares as ``*_pct``, ``samples``
        and ``frames`` (mean length).
    """
    s = settings or EvaluationSettings()
    motions = [motions] if isinstance(motions, Motion) else motions
    if not motions:
        raise MotionValueError("score_motions: no motions")
    body = resolve_body(body)
    for m in motions:
        if not isinstance(m, Motion):
            raise MotionValueError(f"expected Motions, got {type(m).__name__}")
        if abs(m.fps - reference.fps) > 1e-6:
            raise MotionValueError(
                f"{m!r} is at {m.fps:g} fps but the reference {reference!r} is at "
                f"{reference.fps:g} fps; resample it first (Motion.resample)"
            )
    # One body forward per clip: joints and feet for plausibility, feet for the contact
    # labels of clips that have none (the same labels as mrlib.representation.contacts.foot_contacts).
    kin = [pl.motion_kinematics(m, body) for m in motions]
    labelled = [pl.motion_contacts(m, feet) for m, (_, feet) in zip(motions, kin, strict=True)]
    gens = [m.replace(contacts=c) for m, (c, _) in zip(motions, labelled, strict=True)]
    g_feats = [mt.metric_features(m, s.feature_kind, s.contact_features) for m in gens]
    cache = _cache
    want = (body, s.feature_kind, s.contact_features)  # none, or another body's or features
    if cache is None or (cache.body, cache.kind, cache.contacts) != want:
        cache = _ReferenceCache(body, s.feature_kind, s.contact_features)
    ref = cache(reference)
    r_feats = ref.features

    row: dict[str, float] = {
        "samples": float(len(gens)),
        "frames": float(np.mean([len(m) for m in gens])),
    }
    row["coverage_pct"] = 100.0 * mt.coverage(g_feats, r_feats, window=s.coverage_window, eps=s.eps)
    row["coverage_tight_pct"] = 100.0 * mt.coverage(
        g_feats, r_feats, window=s.coverage_window, eps=s.tight_eps
    )
    row["global_div"] = float(mt.global_diversity(g_feats, r_feats, tmin=s.tmin))
    row["local_div"] = mt.local_diversity(g_feats, r_feats, window=s.local_window)
    row["recon_error"] = math.nan
    if reconstruction is not None:
        row["recon_error"] = mt.reconstruction_error(cache(reconstruction).features, r_feats)
    row["cond_fidelity_pct"] = math.nan
    if all_references is not None and len(all_references) > 1:
        if label not in all_references:
            raise MotionValueError(f"label {label!r} is not one of {sorted(all_references)}")
        refs = {k: cache(v).features for k, v in all_references.items()}
        row["cond_fidelity_pct"] = 100.0 * mt.condition_fidelity(
            [(f, label) for f in g_feats], refs, window=s.coverage_window
        )
    rep = pl.plausibility_report(
        motions,
        ref.motion,
        body,
        kinematics=kin,
        reference_kinematics=[ref.kinematics],
        skate_threshold=s.skate_threshold,
        penetration_threshold=s.penetration_threshold,
        ground_percentile=s.ground_percentile,
    )
    for k in ("skate_share", "penetration_share"):
        rep[k.replace("_share", "_pct")] = 100.0 * rep.pop(k)
    row.update(rep)
    return row


# ---------------------------------------------------------------------------------------
# Protocol
# ---------------------------------------------------------------------------------------
def _draw(
    sample_fn: SampleFn, method: str, label: str, length: int, seeds: range, bar: Any
) -> list[Motion]:
    out = []
    for seed in seeds:
        m = sample_fn(label, length, seed)
        if not isinstance(m, Motion):
            raise MotionValueError(
                f"{method}: sample_fn({label!r}, {length}, {seed}) returned "
                f"{type(m).__name__}, expected a mrlib.Motion"
            )
        out.append(m)
        bar.update(1)
    return out


def evaluate(
    models: Mapping[str, SampleFn],
    references: Mapping[str, Motion],
    settings: EvaluationSettings | None = None,
    *,
    reconstructions: Mapping[str, Mapping[str, Motion]] | None = None,
    calibration: CalibrationOptions | None = None,
    body: Any = None,
    progress: bool = True,
) -> EvaluationResult:
    """Score generators against their training clips, with calibration rows.

    Args:
        models: method name -> ``sample_fn(label, length, seed) -> Motion``
            (``SampleFn``), scored identically, in this order; empty to score only the
            calibration rows.
        references: label -> training clip (``Motion``), one per sequence.
        settings: the numbers of the protocol (default ``EvaluationSettings()``):
            ``num_samples`` clips drawn per sequence and method, each
            ``round(length_factor * T_ref)`` frames, sample ``i`` with seed ``seed + i``
            (the same seeds for every sequence and method); the coverage threshold
            ``eps``; the windows ``T_c, T_min, T_d``; the plausibility thresholds.
        reconstructions: method name -> label -> that method's reconstruction of the
            training clip (reconstruction error column).
        calibration: which calibration rows (``CalibrationOptions``: the rows at all,
            the real clips beside them and where to find them; its defaults when None).
        body: ``BodyModel`` (default body when None).
        progress: show progress (``mrlib.progress.bar``).

    Returns:
        an :class:`EvaluationResult`; the condition fidelity column is filled when there
        are two labels or more.
    """
    settings = settings or EvaluationSettings()
    calibration = calibration or CalibrationOptions()
    if not isinstance(models, Mapping):
        raise MotionValueError(
            "models must be a dict method name -> sample_fn(label, length, seed), got "
            f"{type(models).__name__}"
        )
    if not isinstance(references, Mapping) or not references:
        raise MotionValueError("references must be a non-empty dict label -> Motion")
    for label, ref in references.items():
        if not isinstance(ref, Motion):
            raise MotionValueError(
                f"references[{label!r}] must be a Motion, got {type(ref).__name__}"
            )
        frames = max(1, round(settings.length_factor * ref.num_frames)) * settings.num_samples
        if frames > MAX_EVAL_FRAMES:
            raise MotionValueError(
                f"references[{label!r}]: {settings.num_samples} samples of "
                f"{settings.length_factor:g} x its {ref.num_frames} frames are {frames} frames, "
                f"more than the {MAX_EVAL_FRAMES} mrlib scores per sequence; pass fewer "
                "num_samples (--samples), or a shorter clip"
            )
        need = max(settings.coverage_window, 2 * settings.tmin - 1, settings.local_window)
        if ref.num_frames < need:
            raise ClipTooShortError(
                f"references[{label!r}] has {ref.num_frames} frames; the metrics need at least "
                f"{need} (T_c = {settings.coverage_window}, 2 T_min - 1 = {2 * settings.tmin - 1})"
            )
    for k, fn in models.items():
        if not callable(fn):
            raise MotionValueError(f"the sampler of {k!r} is not callable")
    recons = reconstructions or {}
    body = resolve_body(body)

    cache = _ReferenceCache(body, settings.feature_kind, settings.contact_features)
    multi = dict(references) if len(references) > 1 else None
    seeds = range(settings.seed, settings.seed + settings.num_samples)
    rows: list[dict[str, Any]] = []
    notes: list[str] = []
    for method, fn in models.items():
        total = settings.num_samples * len(references)
        with progress_bar(total=total, desc=method, enabled=progress, leave=False) as bar:
            for label, ref in references.items():
                length = max(1, round(settings.length_factor * ref.num_frames))
                samples = _draw(fn, method, label, length, seeds, bar)
                row = score_motions(
                    samples, ref, settings=settings, body=body, label=label,
                    all_references=multi, reconstruction=recons.get(method, {}).get(label),
                    _cache=cache,
                )  # fmt: skip
                rows.append(
                    {"method": method, "kind": "model", "sequence": label, "source": "", **row}
                )

    if calibration.enabled:
        calib_rows: dict[str, list[dict[str, Any]]] = {}
        for label, ref in progress_bar(
            references.items(), desc="calibration", enabled=progress, leave=False
        ):
            others = calibration.others_of(label, ref, body, notes)
            for key, m in calibration_rows(ref, others, settings.length_factor).items():
                try:
                    row = score_motions(
                        [m], ref, settings=settings, body=body, label=label,
                        all_references=multi, _cache=cache,
                    )  # fmt: skip
                except ClipTooShortError as e:  # the metric calls the scored clip "generated"
                    why = str(e).replace("generated has", f"{m.name or 'the clip'} has")
                    notes.append(f"{label}: calibration row {key!r} left out: {why}")
                    continue
                calib_rows.setdefault(key, []).append(
                    {"method": CALIB_PREFIX + key, "kind": "calibration", "sequence": label,
                     "source": m.name or "", **row}
                )  # fmt: skip
        order = [k for k in CALIBRATION_METHODS if k in calib_rows]
        order += [k for k in calib_rows if k not in CALIBRATION_METHODS]
        for key in order:
            rows.extend(calib_rows[key])
    notes += rare_contact_notes(rows, references)
    return EvaluationResult(rows=rows, settings=settings, notes=notes)


# ----------------------------------------------------------------------------------------
# Trained checkpoints
# ----------------------------------------------------------------------------------------
def model_references(model: Any) -> dict[str, Motion]:
    """Training clips of a ``mrlib.sampling.generation.GenerativeModel`` as Motions, keyed by label
    (by clip name when several clips share a label)."""
    from mrlib.representation.features import features_to_motion

    labels = [model.labels[k] for k in model.clip_labels]
    unique = len(set(labels)) == len(labels)
    refs = {}
    for k, x in enumerate(model.features):
        key = labels[k] if unique else model.clip_names[k]
        refs[key] = features_to_motion(
            x, model.fps, betas=model.betas, label=labels[k], name=model.clip_names[k]
        )
    return refs


def model_sample_fn(model: Any, sampler: Any = None) -> SampleFn:
    """``sample_fn(key, length, seed)`` for :func:`evaluate` from a trained model; keys
    are those of :func:`model_references`. ``sampler``: a ``mrlib.Sampler``; default
    the raw output (``raw_sampler()``: one draw, no clean-up)."""
    from mrlib.sampling.generation import generate
    from mrlib.sampling.sampler import raw_sampler

    sampler = raw_sampler(sampler)

    key_to_label = {}
    for k, lab in enumerate(model.clip_labels):
        key_to_label[model.labels[lab]] = model.labels[lab]
        key_to_label[model.clip_names[k]] = model.labels[lab]

    def sample_fn(key: str, length: int, seed: int) -> Motion:
        return generate(model, key_to_label[key], length=length, seed=seed, sampler=sampler)

    return sample_fn


def _clip_index(model: Any, key: str) -> int:
    """The training clip of ``model`` that ``key`` (a clip name or label) refers to; a
    single-clip model answers 0 for any key."""
    for k, name in enumerate(model.clip_names):
        if key in (name, model.labels[model.clip_labels[k]]):
            return k
    if len(model.clip_names) == 1:
        return 0
    raise KeyError(f"{key!r} is neither a clip nor a label of this model ({model.clip_names})")


def _baselines(name: str, value: Any) -> Any:
    if value is None or isinstance(value, Mapping):
        return value
    raise ArgumentError(
        f"{name} must be a dict {{method name: model or {{key: model}}}} or None, got "
        f"{shown(value)}"
    )


@check_args(
    model=check_label_model,
    baselines=_baselines,
    name=check_text,
    contacts=lambda n, v: check_choice(n, v, ("raw", "clean", "both")),
    settings=instance_or_none(EvaluationSettings, "an EvaluationSettings"),
    calibration=instance_or_none(CalibrationOptions, "a CalibrationOptions"),
    body=check_body,
    progress=check_flag,
)
def evaluate_model(
    model: Any,
    baselines: Mapping[str, Any] | None = None,
    *,
    name: str = "ours",
    contacts: str = "both",
    settings: EvaluationSettings | None = None,
    calibration: CalibrationOptions | None = None,
    body: Any = None,
    progress: bool = True,
) -> EvaluationResult:
    """:func:`evaluate` a trained model on its own training clips, with reconstruction
    errors and calibration rows.

    ``baselines`` maps a method name to either one model or a dict key -> model trained on
    that sequence alone (GANimator-mode: one model per sequence); keys are those of
    :func:`model_references`. ``contacts`` says which output of every model (``model``
    and each baseline alike) is scored: ``"raw"`` the generator's own output,
    ``"clean"`` the output after the foot-contact clean-up
    (``mrlib.sampling.cleanup.cleanup_foot_contacts``, what ``mrlib.generate`` and
    ``mrlib sample`` return by default), ``"both"`` (the default, as ``mrlib evaluate``)
    the cleaned output under the method's name and the raw one beside it as
    ``"<method> (raw)"``, right after it. ``settings``, ``calibration``, ``body`` and
    ``progress`` are those of :func:`evaluate`; the model and the baselines sample with
    the fine noise, guidance and candidates of ``settings``
    (``EvaluationSettings.fine_noise``, ``.guidance``, ``.candidates``).
    """
    if contacts not in ("raw", "clean", "both"):
        raise MotionValueError(f"contacts must be 'raw', 'clean' or 'both', got {contacts!r}")
    from mrlib.sampling.generation import reconstruct

    s = settings or EvaluationSettings()
    refs = model_references(model)
    methods: dict[str, tuple[dict[str, Any], dict[str, Motion]]] = {
        name: (
            {key: model for key in refs},
            {key: reconstruct(model, _clip_index(model, key)) for key in refs},
        )
    }
    for bname, b in (baselines or {}).items():
        if bname in methods:
            raise MotionValueError(f"baselines has a second method named {bname!r}")
        per_key = dict(b) if isinstance(b, Mapping) else {key: b for key in refs}
        if sorted(per_key) != sorted(refs):
            raise MotionValueError(
                f"baseline {bname!r}: one model for each of {sorted(refs)}, got {sorted(per_key)}"
            )
        recon = {key: reconstruct(m, _clip_index(m, key)) for key, m in per_key.items()}
        methods[bname] = (per_key, recon)
    variants = {
        "raw": ((False, ""),),
        "clean": ((True, ""),),
        "both": ((True, ""), (False, " (raw)")),
    }
    samplers, recons = {}, {}
    for mname, (per_key, recon) in methods.items():
        sampler = s.sampler()
        fns = _per_key_sample_fns(per_key, sampler)  # one draw for the cleaned and raw rows
        for clean, suffix in variants[contacts]:
            samplers[mname + suffix] = fns[clean]
            recons[mname + suffix] = recon
    if len(samplers) != len(methods) * len(variants[contacts]):
        raise MotionValueError(f"method names clash with the ' (raw)' rows: {sorted(methods)}")
    out = evaluate(samplers, refs, settings, reconstructions=recons, calibration=calibration,
                   body=body, progress=progress)  # fmt: skip
    out.notes.insert(0, f"{name}: contact labels {contact_reading(model, s.sampler())}")
    return out


def _per_key_sample_fns(per_key: Mapping[str, Any], sampler: Any) -> dict[bool, SampleFn]:
    """``{False: raw, True: cleaned}`` ``sample_fn(key, length, seed)`` drawing from
    ``per_key[key]`` (a model trained on that sequence, or the one model for all) with its
    label for that sequence. One (ranked) draw serves both: the cleaned sample is the raw
    one with its feet planted, as ``mrlib.generate`` returns it."""
    from mrlib.sampling.generation import generate, plant_feet

    draws: dict[tuple[str, int, int], Motion] = {}

    def raw(key: str, length: int, seed: int) -> Motion:
        if (key, length, seed) not in draws:
            m = per_key[key]
            label = m.labels[m.clip_labels[_clip_index(m, key)]]
            draws[key, length, seed] = generate(m, label, length=length, seed=seed, sampler=sampler)
        return draws[key, length, seed]

    def clean(key: str, length: int, seed: int) -> Motion:
        m = per_key[key]
        label_index = m.clip_labels[_clip_index(m, key)]
        return plant_feet(m, [raw(key, length, seed)], [int(label_index)], sampler)[0]

    return {False: raw, True: clean}
