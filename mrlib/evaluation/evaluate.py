"""The evaluation protocol: coverage, diversity and plausibility tables with calibration
rows, for one or several generators.

``evaluate(sample_fn, references)`` draws ``num_samples`` clips per training sequence
(label) from a generator, ``length_factor`` times as long as the training clip, with
fixed seeds, and scores them against that clip: the paper's Table 1 metrics (coverage
with ``T_c = 30`` and threshold ``eps``, global diversity by patched nearest neighbours
with ``T_min = 30``, local diversity with ``T_d = 15``; ``mrlib.metrics.paper``) and the
plausibility measures of ``mrlib.metrics.plausibility`` (foot skating, jitter, ground
penetration, Wasserstein distances of speed distributions). The result holds one row
per (method, sequence) and their mean and standard deviation per method, and writes
CSV, Markdown and a PNG plot.

A generator is any callable ``sample_fn(label, length, seed) -> Motion``; wire a
trained model in with a closure, e.g.
``lambda label, length, seed: generate(model, label, length=length, seed=seed)``
(``mrlib.sampling.generation.generate`` returns one ``Motion`` for ``num_samples=1``).

**Calibration rows** (``mrlib.evaluation.calibration``): the training clip played twice, its first
frame frozen, and other real takes, styles and contents, scored with the same code, so
the generators' numbers can be read against them. Real clips are scored at their own
length; the built rows are one clip each.

**Features.** Coverage and diversity use ``mrlib.metrics.paper.metric_features``: the 23
non-root joints' local rotations in 6D plus the 6 foot-contact labels (``D = 144``).
Clips without contact labels get them from ``mrlib.representation.contacts.foot_contacts`` (speed
threshold 0.25 m/s), so every clip is compared on the same channels. GANimator's
published numbers use its own features (21 joints of its skeleton plus 4 contacts), so
the values here are not on the same scale as GANimator's tables.

The module is the protocol and its table (``EvaluationResult``: Markdown, CSV, the
summary) together, which runs a little past 600 lines; the calibration motions are in
``mrlib.evaluation.calibration`` and the plot in ``mrlib.viz.plots``.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mrlib.errors import ClipTooShortError, MotionValueError
from mrlib.evaluation.calibration import CALIBRATION_METHODS, calibration_rows, load_counterparts
from mrlib.metrics import paper as mt
from mrlib.metrics import plausibility as pl
from mrlib.representation.body import resolve_body
from mrlib.representation.motion import Motion
from mrlib.threads import with_policy

__all__ = [
    "SampleFn",
    "EvaluationSettings",
    "EvaluationResult",
    "score_motions",
    "evaluate",
]

SampleFn = Callable[[str, int, int], Motion]
"""``sample_fn(label, length, seed) -> Motion``: one generated clip of ``length`` frames."""

# Names of the calibration rows, in the order they are reported.
CALIB_PREFIX = "calib: "  # method name of a calibration row: CALIB_PREFIX + row name


# ---------------------------------------------------------------------------------------
# Settings
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class EvaluationSettings:
    """Everything that determines the numbers of an evaluation."""

    num_samples: int = 200  # generated clips per sequence
    length_factor: float = 2.0  # generated length / training clip length (GANimator: 2)
    seed: int = 0  # sample i uses seed + i, for every sequence and every method
    eps: float = 2.0  # coverage threshold on the mean per-frame distance (GANimator's)
    coverage_window: int = 30  # T_c, frames
    tmin: int = 30  # T_min, shortest PNN segment, frames
    local_window: int = 15  # T_d, frames
    feature_kind: str = "6d"  # mrlib.metrics.paper.metric_features(kind=...)
    skate_threshold: float = pl.SKATE_SPEED_THRESHOLD  # m/s
    penetration_threshold: float = pl.PENETRATION_THRESHOLD  # m
    ground_percentile: float = pl.GROUND_PERCENTILE  # of the reference's foot heights

    def __post_init__(self) -> None:
        for name in ("num_samples", "coverage_window", "tmin", "local_window"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise MotionValueError(f"{name} must be a positive integer, got {v!r}")
        for name in ("length_factor", "eps", "skate_threshold"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise MotionValueError(f"{name} must be a positive number, got {v!r}")
        if self.feature_kind not in ("6d", "rotmat"):
            raise MotionValueError(
                f"feature_kind must be '6d' or 'rotmat', got {self.feature_kind!r}"
            )

    def describe(self) -> str:
        """One paragraph stating the settings, for reports."""
        feats = (
            "local rotations of the 23 non-root SMPL joints in 6D + 6 foot-contact labels"
            if self.feature_kind == "6d"
            else "local rotation matrices of the 23 non-root SMPL joints + 6 foot-contact labels"
        )
        return (
            f"{self.num_samples} samples per sequence, {self.length_factor:g}x the training "
            f"length, seeds {self.seed}..{self.seed + self.num_samples - 1}. Coverage: "
            f"eps = {self.eps:g}, T_c = {self.coverage_window}; global diversity (PNN): "
            f"T_min = {self.tmin}; local diversity: T_d = {self.local_window}. Features: "
            f"{feats}; per-frame Euclidean distance, mean over frames. Foot skating: "
            f"horizontal speed of contact vertices while in contact, share above "
            f"{self.skate_threshold:g} m/s. Jitter: mean joint jerk / the training clip's. "
            f"Penetration: depth of the lowest foot vertex below the ground (percentile "
            f"{self.ground_percentile:g} of the training clip's foot-vertex heights), share "
            f"of frames deeper than {100 * self.penetration_threshold:g} cm. "
            "W: 1-D Wasserstein distance to the training clip's per-frame root ground speed "
            "and joint angular speeds (legs, arms, spine/head). Means and standard deviations "
            "per method are over sequences (population std)."
        )


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

    def __init__(self, body: Any, kind: str) -> None:
        self.body, self.kind = body, kind
        self._store: dict[int, tuple[Motion, _Reference]] = {}

    def __call__(self, motion: Motion) -> _Reference:
        hit = self._store.get(id(motion))
        if hit is not None and hit[0] is motion:
            return hit[1]
        kin = pl.motion_kinematics(motion, self.body)
        labels, _ = pl.motion_contacts(motion, kin[1])
        m = motion.replace(contacts=labels)
        ref = _Reference(m, mt.metric_features(m, kind=self.kind), kin)
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
        ``coverage_pct``, ``global_div``, ``local_div``, ``recon_error`` (NaN without a
        reconstruction), ``cond_fidelity_pct`` (NaN unless multi-label), the entries of
        ``mrlib.metrics.plausibility.plausibility_report`` with shares as ``*_pct``, ``samples``
        and ``frames`` (mean length).
    """
    s = settings or EvaluationSettings()
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
    g_feats = [mt.metric_features(m, kind=s.feature_kind) for m in gens]
    cache = _cache if _cache is not None else _ReferenceCache(body, s.feature_kind)
    ref = cache(reference)
    r_feats = ref.features

    row: dict[str, float] = {
        "samples": float(len(gens)),
        "frames": float(np.mean([len(m) for m in gens])),
    }
    row["coverage_pct"] = 100.0 * mt.coverage(g_feats, r_feats, window=s.coverage_window, eps=s.eps)
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
# Result
# ---------------------------------------------------------------------------------------
# (key, Markdown header, format) of the reported metric columns.
METRIC_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("coverage_pct", "Coverage %", "{:.1f}"),
    ("global_div", "Global div.", "{:.2f}"),
    ("local_div", "Local div.", "{:.2f}"),
    ("recon_error", "Recon. err.", "{:.3f}"),
    ("cond_fidelity_pct", "Cond. fid. %", "{:.1f}"),
    ("skate_speed", "Skate m/s", "{:.3f}"),
    ("skate_pct", "Skating %", "{:.1f}"),
    ("jerk_ratio", "Jerk ratio", "{:.2f}"),
    ("penetration_cm", "Pen. cm", "{:.2f}"),
    ("penetration_pct", "Pen. %", "{:.1f}"),
    ("w_root_speed", "W root m/s", "{:.3f}"),
    ("w_angspeed_legs", "W legs rad/s", "{:.2f}"),
    ("w_angspeed_arms", "W arms rad/s", "{:.2f}"),
    ("w_angspeed_spine", "W spine rad/s", "{:.2f}"),
)
_ID_COLUMNS = ("method", "kind", "sequence", "source")
_EXTRA_COLUMNS = (
    "samples", "frames", "contact_share", "contacts_from_motion",
    "jerk", "jerk_reference", "ground",
)  # fmt: skip
CSV_COLUMNS = _ID_COLUMNS + tuple(k for k, _, _ in METRIC_COLUMNS) + _EXTRA_COLUMNS
# Panels of EvaluationResult.plot.
PLOT_COLUMNS = (
    "coverage_pct", "global_div", "local_div", "skate_pct",
    "jerk_ratio", "penetration_cm", "w_root_speed", "w_angspeed_legs",
)  # fmt: skip


def _fmt(value: Any, fmt: str) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "–"
    return fmt.format(value)


@dataclass
class EvaluationResult:
    """Rows of an evaluation: one per (method, sequence).

    Attributes:
        rows: dicts with ``method``, ``kind`` (``"model"`` or ``"calibration"``),
            ``sequence`` (the label), ``source`` (the clip a calibration row was built
            from, empty for models) and the metrics of ``score_motions``.
        settings: what the numbers were computed with.
        notes: remarks gathered during the run (missing calibration clips, ...).
    """

    rows: list[dict[str, Any]]
    settings: EvaluationSettings
    notes: list[str] = field(default_factory=list)

    @property
    def methods(self) -> list[str]:
        """Methods in order of first appearance (models first, then calibration rows)."""
        return list(dict.fromkeys(r["method"] for r in self.rows))

    def summary(self) -> list[dict[str, Any]]:
        """Per method: ``method``, ``kind``, ``sequences`` and ``<metric>_mean`` /
        ``<metric>_std`` over its sequences (population std; NaN entries left out)."""
        out = []
        for method in self.methods:
            rows = [r for r in self.rows if r["method"] == method]
            d: dict[str, Any] = {"method": method, "kind": rows[0]["kind"], "sequences": len(rows)}
            for key, _, _ in METRIC_COLUMNS:
                v = np.array([r.get(key, math.nan) for r in rows], dtype=np.float64)
                v = v[~np.isnan(v)]
                d[f"{key}_mean"] = float(v.mean()) if len(v) else math.nan
                d[f"{key}_std"] = float(v.std()) if len(v) else math.nan
            out.append(d)
        return out

    def _columns(self) -> list[tuple[str, str, str]]:
        """Metric columns with at least one value (reconstruction and fidelity are
        often absent)."""
        return [
            c for c in METRIC_COLUMNS
            if any(not math.isnan(float(r.get(c[0], math.nan))) for r in self.rows)
        ]  # fmt: skip

    def to_markdown(self) -> str:
        """The per-sequence table, the per-method mean ± std table and the settings."""
        cols = self._columns()
        lines = ["## Per sequence", ""]
        lines.append("| Method | Sequence | " + " | ".join(h for _, h, _ in cols) + " |")
        lines.append("|---|---|" + "---:|" * len(cols))
        last = None
        for r in self.rows:
            name = r["method"] if r["method"] != last else ""
            last = r["method"]
            seq = r["sequence"] + (f" ({r['source']})" if r.get("source") else "")
            vals = [_fmt(r.get(k), f) for k, _, f in cols]
            lines.append(f"| {name} | {seq} | " + " | ".join(vals) + " |")
        lines += ["", "## Mean ± std over sequences", ""]
        lines.append("| Method | Sequences | " + " | ".join(h for _, h, _ in cols) + " |")
        lines.append("|---|---:|" + "---:|" * len(cols))
        for d in self.summary():
            vals = [
                f"{_fmt(d[f'{k}_mean'], f)} ± {_fmt(d[f'{k}_std'], f)}"
                if not math.isnan(d[f"{k}_mean"])
                else "–"
                for k, _, f in cols
            ]
            lines.append(f"| {d['method']} | {d['sequences']} | " + " | ".join(vals) + " |")
        lines += ["", "## Settings", "", self.settings.describe()]
        lines += [
            "",
            "Columns: Skating % = share of contact vertex-frames sliding faster than the "
            "threshold; Jerk ratio = mean joint jerk / the training clip's; Pen. cm = mean "
            "depth below the ground; Pen. % = share of frames deeper than the threshold; "
            "W = Wasserstein distance to the training clip's speed distribution. Rows "
            "named 'calib: ...' are real or trivially built motions scored with the same "
            "code, to read the other rows against.",
        ]
        if self.notes:
            lines += ["", "Notes:", ""] + [f"- {n}" for n in self.notes]
        return "\n".join(lines) + "\n"

    def to_csv(self, path: str | Path) -> Path:
        """Per-sequence rows as CSV (columns ``CSV_COLUMNS``; NaN left empty)."""
        return _write_csv(path, CSV_COLUMNS, self.rows)

    def summary_to_csv(self, path: str | Path) -> Path:
        """Per-method mean/std as CSV."""
        summ = self.summary()
        cols = ["method", "kind", "sequences"] + [
            f"{k}_{s}" for k, _, _ in METRIC_COLUMNS for s in ("mean", "std")
        ]
        return _write_csv(path, cols, summ)

    def save(self, out_dir: str | Path) -> dict[str, Path]:
        """Write ``evaluation.csv``, ``evaluation_summary.csv``, ``evaluation.md`` and the
        settings as ``evaluation_settings.json`` into ``out_dir`` (created). Returns the
        paths by kind. The figure is ``mrlib.viz.plots.plot_evaluation(result, path)``."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = {
            "csv": self.to_csv(out / "evaluation.csv"),
            "summary_csv": self.summary_to_csv(out / "evaluation_summary.csv"),
            "markdown": out / "evaluation.md",
        }
        paths["markdown"].write_text("# Evaluation\n\n" + self.to_markdown(), encoding="utf-8")
        paths["settings"] = out / "evaluation_settings.json"
        paths["settings"].write_text(
            json.dumps(asdict(self.settings), indent=2) + "\n", encoding="utf-8"
        )
        return paths


def _write_csv(path: str | Path, columns: Any, rows: list[dict[str, Any]]) -> Path:
    path = Path(path)
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(columns)
        for r in rows:
            vals = []
            for c in columns:
                v = r.get(c, "")
                if isinstance(v, float):
                    v = "" if math.isnan(v) else f"{v:.6g}"
                vals.append(v)
            w.writerow(vals)
    return path


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
    sample_fn: SampleFn | None,
    references: Mapping[str, Motion],
    num_samples: int = 200,
    length_factor: float = 2.0,
    seed: int = 0,
    eps: float = 2.0,
    calibration: bool = True,
    extra_models: Mapping[str, SampleFn] | None = None,
    *,
    name: str = "model",
    reconstructions: Mapping[str, Motion] | None = None,
    extra_reconstructions: Mapping[str, Mapping[str, Motion]] | None = None,
    calibration_others: str | Mapping[str, Mapping[str, Motion]] | None = "auto",
    data_dir: str | Path | None = None,
    body: Any = None,
    progress: bool = True,
    settings: EvaluationSettings | None = None,
) -> EvaluationResult:
    """Score generators against their training clips, with calibration rows.

    Args:
        sample_fn: ``sample_fn(label, length, seed) -> Motion`` (``SampleFn``), the main
            method, reported as ``name``; None to evaluate only ``extra_models``.
        references: label -> training clip (``Motion``), one per sequence.
        num_samples: clips drawn per sequence and method.
        length_factor: generated length = ``round(length_factor * T_ref)`` frames.
        seed: sample ``i`` is drawn with seed ``seed + i`` (same seeds for every
            sequence and method).
        eps: coverage threshold.
        calibration: add the calibration rows (``calibration_rows``).
        extra_models: more methods by name, scored identically.
        reconstructions: label -> the main model's reconstruction of the training clip
            (reconstruction error column).
        extra_reconstructions: method name -> label -> reconstruction.
        calibration_others: ``"auto"`` finds other real takes / styles / contents of
            Bandai Namco references in ``data_dir`` (``find_bandai_counterparts``);
            None uses none; or label -> {row name: Motion}.
        data_dir: the Bandai Namco folder for ``"auto"`` (default ``default_data_dir()``).
        body: ``BodyModel`` (default body when None).
        progress: show a tqdm progress bar.
        settings: all settings at once, instead of ``num_samples``, ``length_factor``,
            ``seed`` and ``eps`` (the windows ``T_c, T_min, T_d`` and the plausibility
            thresholds are only set here); passing both is an error.

    Returns:
        an :class:`EvaluationResult`; the condition fidelity column is filled when there
        are two labels or more.
    """
    from tqdm.auto import tqdm

    given = dict(num_samples=num_samples, length_factor=length_factor, seed=seed, eps=eps)
    if settings is None:
        settings = EvaluationSettings(**given)
    else:
        default = EvaluationSettings()
        clash = [k for k, v in given.items() if v != getattr(default, k)]
        if clash:
            raise MotionValueError(
                f"pass {', '.join(clash)} inside settings, not next to it "
                "(settings would silently override them)"
            )
    if not isinstance(references, Mapping) or not references:
        raise MotionValueError("references must be a non-empty dict label -> Motion")
    for label, ref in references.items():
        if not isinstance(ref, Motion):
            raise MotionValueError(
                f"references[{label!r}] must be a Motion, got {type(ref).__name__}"
            )
        need = max(settings.coverage_window, 2 * settings.tmin - 1, settings.local_window)
        if ref.num_frames < need:
            raise ClipTooShortError(
                f"references[{label!r}] has {ref.num_frames} frames; the metrics need at least "
                f"{need} (T_c = {settings.coverage_window}, 2 T_min - 1 = {2 * settings.tmin - 1})"
            )
    models: dict[str, SampleFn] = {}
    if sample_fn is not None:
        models[name] = sample_fn
    for k, fn in (extra_models or {}).items():
        if k in models:
            raise MotionValueError(f"extra_models has a second method named {k!r}")
        models[k] = fn
    for k, fn in models.items():
        if not callable(fn):
            raise MotionValueError(f"the sampler of {k!r} is not callable")
    recons = {name: reconstructions or {}, **(extra_reconstructions or {})}
    body = resolve_body(body)

    cache = _ReferenceCache(body, settings.feature_kind)
    multi = dict(references) if len(references) > 1 else None
    seeds = range(settings.seed, settings.seed + settings.num_samples)
    rows: list[dict[str, Any]] = []
    notes: list[str] = []
    for method, fn in models.items():
        total = settings.num_samples * len(references)
        with tqdm(total=total, desc=method, disable=not progress, leave=False) as bar:
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

    if calibration:
        calib_rows: dict[str, list[dict[str, Any]]] = {}
        for label, ref in tqdm(
            references.items(), desc="calibration", disable=not progress, leave=False
        ):
            if calibration_others == "auto":
                others = load_counterparts(label, ref, data_dir, body, notes)
            elif calibration_others is None:
                others = {}
            else:
                others = dict(calibration_others.get(label, {}))
            for key, m in calibration_rows(ref, others, settings.length_factor).items():
                try:
                    row = score_motions(
                        [m], ref, settings=settings, body=body, label=label,
                        all_references=multi, _cache=cache,
                    )  # fmt: skip
                except ClipTooShortError as e:
                    notes.append(f"{label}: calibration row {key!r} ({m.name}) left out: {e}")
                    continue
                source = m.name or ""
                calib_rows.setdefault(key, []).append(
                    {"method": CALIB_PREFIX + key, "kind": "calibration", "sequence": label,
                     "source": source, **row}
                )  # fmt: skip
        order = [k for k in CALIBRATION_METHODS if k in calib_rows]
        order += [k for k in calib_rows if k not in CALIBRATION_METHODS]
        for key in order:
            rows.extend(calib_rows[key])
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


def model_sample_fn(model: Any, fix_contacts: bool = False) -> SampleFn:
    """``sample_fn(key, length, seed)`` for :func:`evaluate` from a trained model; keys
    are those of :func:`model_references`."""
    from mrlib.sampling.generation import generate

    key_to_label = {}
    for k, lab in enumerate(model.clip_labels):
        key_to_label[model.labels[lab]] = model.labels[lab]
        key_to_label[model.clip_names[k]] = model.labels[lab]

    def sample_fn(key: str, length: int, seed: int) -> Motion:
        return generate(
            model, key_to_label[key], length=length, seed=seed, fix_contacts=fix_contacts
        )

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


@with_policy
def evaluate_model(
    model: Any,
    baselines: Mapping[str, Any] | None = None,
    *,
    name: str = "ours",
    contacts: str = "raw",
    **kwargs: Any,
) -> EvaluationResult:
    """:func:`evaluate` a trained model on its own training clips, with reconstruction
    errors and calibration rows.

    ``baselines`` maps a method name to either one model or a dict key -> model trained on
    that sequence alone (GANimator-mode: one model per sequence); keys are those of
    :func:`model_references`. ``contacts``: ``"raw"`` scores the generator's output,
    ``"clean"`` the output after the foot-contact clean-up
    (``mrlib.sampling.generation.cleanup_foot_contacts``), ``"both"`` both, the raw one as
    ``"<name> (raw)"``. Extra keyword arguments go to :func:`evaluate`.
    """
    if contacts not in ("raw", "clean", "both"):
        raise MotionValueError(f"contacts must be 'raw', 'clean' or 'both', got {contacts!r}")
    from mrlib.sampling.generation import generate, reconstruct

    refs = model_references(model)
    recon = {key: reconstruct(model, _clip_index(model, key)) for key in refs}
    extra, extra_recon = {}, {}
    for bname, b in (baselines or {}).items():
        per_key = dict(b) if isinstance(b, Mapping) else {key: b for key in refs}

        def fn(key: str, length: int, seed: int, _models=per_key) -> Motion:
            m = _models[key]
            label = m.labels[m.clip_labels[_clip_index(m, key)]]
            return generate(m, label, length=length, seed=seed, fix_contacts=False)

        extra[bname] = fn
        extra_recon[bname] = {
            key: reconstruct(m, _clip_index(m, key)) for key, m in per_key.items()
        }
    if contacts == "both":
        extra = {f"{name} (raw)": model_sample_fn(model), **extra}
        extra_recon = {f"{name} (raw)": recon, **extra_recon}
    return evaluate(
        model_sample_fn(model, fix_contacts=contacts != "raw"),
        refs,
        extra_models=extra or None,
        name=name,
        reconstructions=recon,
        extra_reconstructions=extra_recon or None,
        **kwargs,
    )
