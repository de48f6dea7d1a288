"""The table of an evaluation (``mrlib.evaluation.evaluate``): the settings that determine
its numbers (:class:`EvaluationSettings`) and its rows, one per (method, sequence), with
their mean and standard deviation per method as Markdown and CSV
(:class:`EvaluationResult`; the plot is ``mrlib.viz.plots.plot_evaluation``). Both names
are also reachable as ``mrlib.evaluation.evaluate.<name>``.
"""

from __future__ import annotations

import csv
import json
import math
import numbers
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mrlib.errors import MotionValueError
from mrlib.metrics import plausibility as pl
from mrlib.sampling.sampler import CANDIDATES, FINE_NOISE, GUIDANCE, Sampler

__all__ = [
    "CALIB_PREFIX",
    "MAX_EVAL_FRAMES",
    "MAX_EVAL_SAMPLES",
    "EvaluationSettings",
    "METRIC_COLUMNS",
    "CSV_COLUMNS",
    "PLOT_COLUMNS",
    "EvaluationResult",
    "RARE_CONTACT",
    "rare_contact_notes",
    "contact_reading",
]

# Bounds checked before anything is drawn: 1000 samples is the most `mrlib sample --num`
# writes too (each takes a generation and a clean-up: minutes for the tutorial model), and
# the samples of one sequence are held together (about 2 KB a frame while scored).
MAX_EVAL_SAMPLES = 1000
MAX_LENGTH_FACTOR = 20.0  # generated length / training length (GANimator's is 2)
MAX_EVAL_FRAMES = 1_000_000  # num_samples x the generated length, per sequence (~2 GB)

# Names of the calibration rows, in the order they are reported.
CALIB_PREFIX = "calib: "  # method name of a calibration row: CALIB_PREFIX + row name


# ---------------------------------------------------------------------------------------
# Settings
# ---------------------------------------------------------------------------------------
# The frame features of ``mrlib evaluate --features``, as EvaluationSettings fields.
FEATURE_SETS = {
    "mrlib": {"feature_kind": "6d", "contact_features": True},
    "paper": {"feature_kind": "rotmat", "contact_features": False},
}


@dataclass(frozen=True)
class EvaluationSettings:
    """Everything that determines the numbers of an evaluation."""

    num_samples: int = 200  # generated clips per sequence
    length_factor: float = 2.0  # generated length / training clip length (GANimator: 2)
    seed: int = 0  # sample i uses seed + i, for every sequence and every method
    eps: float = 2.0  # coverage threshold on the mean per-frame distance (GANimator's)
    # a tighter one, reported beside it: at 2.0 a frozen frame of a slow clip can count as
    # covering it, at 1.0 none of the Bandai walks' did (notebook 05, "Choosing eps")
    tight_eps: float = 1.0
    coverage_window: int = 30  # T_c, frames
    tmin: int = 30  # T_min, shortest PNN segment, frames
    local_window: int = 15  # T_d, frames
    feature_kind: str = "6d"  # mrlib.metrics.windows.metric_features(kind=...)
    # the 6 foot-contact labels appended to the features; False with "rotmat": the paper's
    # distance (Sec. 5: the Frobenius norm on the local joint rotation matrices), whose
    # scale differs from mrlib's, so eps and tight_eps are to be chosen for it
    contact_features: bool = True
    skate_threshold: float = pl.SKATE_SPEED_THRESHOLD  # m/s
    penetration_threshold: float = pl.PENETRATION_THRESHOLD  # m
    ground_percentile: float = pl.GROUND_PERCENTILE  # of the reference's foot heights
    # the sampler of a trained model's samples (evaluate_model; mrlib.Sampler's settings,
    # its foot-contact clean-up is evaluate_model's ``contacts``)
    fine_noise: float = FINE_NOISE
    guidance: float = GUIDANCE
    candidates: int = CANDIDATES
    # contact labels at each label's rate (True), at 0.5 (False), as the model chose (None)
    match_contact_rate: bool | None = None

    def __post_init__(self) -> None:
        self.sampler()  # the sampler's settings within their bounds
        for name in ("num_samples", "coverage_window", "tmin", "local_window"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise MotionValueError(f"{name} must be a positive integer, got {v!r}")
        for name in ("length_factor", "eps", "tight_eps", "skate_threshold"):
            v = getattr(self, name)
            real = isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_))
            if not (real and np.isfinite(v) and v > 0):
                raise MotionValueError(f"{name} must be a positive number, got {v!r}")
        if self.tight_eps > self.eps:
            raise MotionValueError(
                f"tight_eps (--tight-eps) {self.tight_eps:g} is looser than eps (--eps) "
                f"{self.eps:g}: the tighter coverage threshold must not exceed it"
            )
        if self.num_samples > MAX_EVAL_SAMPLES:
            raise MotionValueError(
                f"num_samples (--samples): {self.num_samples} samples per sequence are more "
                f"than the {MAX_EVAL_SAMPLES} mrlib evaluates; pass at most {MAX_EVAL_SAMPLES} "
                "(the paper's table uses 200)"
            )
        if self.length_factor > MAX_LENGTH_FACTOR:
            raise MotionValueError(
                f"length_factor: {self.length_factor:g} x the training length is more than "
                f"the {MAX_LENGTH_FACTOR:g} mrlib evaluates (GANimator's is 2)"
            )
        if not isinstance(self.contact_features, bool):
            raise MotionValueError(
                f"contact_features must be True or False, got {self.contact_features!r}"
            )
        if self.feature_kind not in ("6d", "rotmat"):
            raise MotionValueError(
                f"feature_kind must be '6d' or 'rotmat', got {self.feature_kind!r}"
            )

    def sampler(self) -> Sampler:
        """The ``mrlib.Sampler`` the model's samples are drawn with: these settings, no
        foot-contact clean-up (evaluate_model plants the feet of the same draws for the
        cleaned rows)."""
        return Sampler(
            self.fine_noise, self.guidance, fix_contacts=False, candidates=self.candidates,
            match_contact_rate=self.match_contact_rate,
        )  # fmt: skip

    def describe(self) -> str:
        """One paragraph stating the settings, for reports."""
        feats = (
            "local rotations of the 23 non-root SMPL joints in 6D"
            if self.feature_kind == "6d"
            else "local rotation matrices of the 23 non-root SMPL joints"
        ) + (" + 6 foot-contact labels" if self.contact_features else " (no contact labels)")
        return (
            f"{self.num_samples} samples per sequence, {self.length_factor:g}x the training "
            f"length, seeds {self.seed}..{self.seed + self.num_samples - 1}. Coverage: "
            f"eps = {self.eps:g} (tight: {self.tight_eps:g}), T_c = {self.coverage_window}; global diversity (PNN): "
            f"T_min = {self.tmin}; local diversity: T_d = {self.local_window}. Features: "
            f"{feats}; per-frame Euclidean distance, mean over frames. Foot skating: "
            f"horizontal speed of contact vertices while in contact, share above "
            f"{self.skate_threshold:g} m/s. Jitter: mean joint jerk / the training clip's. "
            f"Penetration: depth of the lowest foot vertex below the ground (percentile "
            f"{self.ground_percentile:g} of the training clip's foot-vertex heights), share "
            f"of frames deeper than {100 * self.penetration_threshold:g} cm. "
            "W: 1-D Wasserstein distance to the training clip's per-frame root ground speed "
            "and joint angular speeds (legs, arms, spine/head). Means and standard deviations "
            "per method are over sequences (population std). Sampler of the trained model: "
            f"fine noise {self.fine_noise:g}, guidance {self.guidance:g}, best of "
            f"{self.candidates} candidate(s) by the critics"
            + {
                True: ", contact labels at each label's contact rate.",
                False: ", contact labels where the output exceeds 0.5.",
                None: ", contact labels read as the model chose per label.",
            }[self.match_contact_rate]
        )


def contact_reading(model, sampler) -> str:
    """How ``sampler`` reads the contact labels of ``model``'s label samples, in words."""
    if sampler.match_contact_rate is not None:
        return "at each label's rate" if sampler.match_contact_rate else "cut at 0.5"
    chosen = getattr(model, "contact_at_rate", None)
    if chosen is None:
        return "cut at 0.5 (the checkpoint records no choice)"
    if not chosen:
        return "cut at 0.5 for every label (the model's choice)"
    return (
        f"at the label's rate for {', '.join(chosen)}, cut at 0.5 for the rest (the model's choice)"
    )


# ---------------------------------------------------------------------------------------
# Result
# ---------------------------------------------------------------------------------------
# (key, Markdown header, format) of the reported metric columns.
METRIC_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("coverage_pct", "Coverage %", "{:.1f}"),
    ("coverage_tight_pct", "Coverage (tight eps) %", "{:.1f}"),
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


# a row in contact on less than this share of its clip's contact vertex-frames gets a note:
# its skating (over its contact frames) measures little of its motion
RARE_CONTACT = 1.0 / 3.0


def rare_contact_notes(rows: list[dict[str, Any]], references: dict[str, Any]) -> list[str]:
    """Notes for the ``rows`` whose motions are labelled in contact far less often than
    their sequence's clip (under ``RARE_CONTACT`` of its share): skating is the share of
    contact vertex-frames that slide, so it reads low where few frames are in contact,
    as in samples of a model that has not learnt its contacts, or a clip without labels,
    whose contacts are where its feet are slow (a foot that slides is never one)."""
    notes = []
    for r in rows:
        ref = references.get(r["sequence"])
        if ref is None or ref.contacts is None or not math.isfinite(r.get("contact_share", 0)):
            continue
        share = float((np.asarray(ref.contacts) > 0.5).mean())
        if r["contact_share"] < RARE_CONTACT * share:
            own = "their own labels" if r.get("contacts_from_motion", 1) > 0.5 else "slow feet"
            notes.append(
                f"{r['method']}, {r['sequence']}: in contact ({own}) on "
                f"{100 * r['contact_share']:.1f} % of foot vertex-frames against the clip's "
                f"{100 * share:.1f} %, so its Skating % counts few frames"
            )
    return notes


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
        often absent); the tight coverage only where its eps differs from ``eps``."""
        same_eps = self.settings.tight_eps == self.settings.eps
        return [
            c for c in METRIC_COLUMNS
            if any(not math.isnan(float(r.get(c[0], math.nan))) for r in self.rows)
            and not (same_eps and c[0] == "coverage_tight_pct")
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

    def to_csv(self, path: str | Path, *, overwrite: bool = True) -> Path:
        """Per-sequence rows as CSV (columns ``CSV_COLUMNS``; NaN left empty)."""
        return _write_csv(path, CSV_COLUMNS, self.rows, overwrite=overwrite)

    def summary_to_csv(self, path: str | Path, *, overwrite: bool = True) -> Path:
        """Per-method mean/std as CSV."""
        summ = self.summary()
        cols = ["method", "kind", "sequences"] + [
            f"{k}_{s}" for k, _, _ in METRIC_COLUMNS for s in ("mean", "std")
        ]
        return _write_csv(path, cols, summ, overwrite=overwrite)

    def save(self, out_dir: str | Path, *, overwrite: bool = True) -> dict[str, Path]:
        """Write ``evaluation.csv``, ``evaluation_summary.csv``, ``evaluation.md`` and the
        settings as ``evaluation_settings.json`` into ``out_dir`` (created). Returns the
        paths by kind. The figure is ``mrlib.viz.plots.plot_evaluation(result, path)``.

        The files are written in one ``mrlib.io.transaction.output_transaction``: all four,
        or (a full disk, a file that cannot be replaced) none, ``out_dir`` as it was;
        never through a symbolic link; ``overwrite=False`` refuses, before writing any,
        files already there."""
        from mrlib.io.outputs import check_writable
        from mrlib.io.transaction import make_folders, output_transaction

        out = Path(out_dir)
        names = {
            "csv": "evaluation.csv",
            "summary_csv": "evaluation_summary.csv",
            "markdown": "evaluation.md",
            "settings": "evaluation_settings.json",
        }
        for name in names.values():
            check_writable(out / name, overwrite=overwrite)
        with output_transaction():
            make_folders(out)
            return self._save_files(out, names, overwrite)

    def _save_files(self, out: Path, names: dict[str, str], overwrite: bool) -> dict[str, Path]:
        from mrlib.io.outputs import write_text

        paths = {
            "csv": self.to_csv(out / names["csv"], overwrite=overwrite),
            "summary_csv": self.summary_to_csv(out / names["summary_csv"], overwrite=overwrite),
        }
        paths["markdown"] = write_text(
            out / names["markdown"], "# Evaluation\n\n" + self.to_markdown(), overwrite=overwrite
        )
        paths["settings"] = write_text(
            out / names["settings"],
            json.dumps(asdict(self.settings), indent=2) + "\n",
            overwrite=overwrite,
        )
        return paths


def _write_csv(
    path: str | Path, columns: Any, rows: list[dict[str, Any]], *, overwrite: bool = True
) -> Path:
    import io

    from mrlib.io.outputs import write_text

    with io.StringIO(newline="") as f:
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
        text = f.getvalue()
    return write_text(Path(path), text, overwrite=overwrite)
