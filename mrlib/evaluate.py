"""The evaluation protocol: coverage, diversity and plausibility tables with calibration
rows, for one or several generators.

``evaluate(sample_fn, references)`` draws ``num_samples`` clips per training sequence
(label) from a generator, ``length_factor`` times as long as the training clip, with
fixed seeds, and scores them against that clip: the paper's Table 1 metrics (coverage
with ``T_c = 30`` and threshold ``eps``, global diversity by patched nearest neighbours
with ``T_min = 30``, local diversity with ``T_d = 15``; ``mrlib.metrics``) and the
plausibility measures of ``mrlib.plausibility`` (foot skating, jitter, ground
penetration, Wasserstein distances of speed distributions). The result holds one row
per (method, sequence) and their mean and standard deviation per method, and writes
CSV, Markdown and a PNG plot.

A generator is any callable ``sample_fn(label, length, seed) -> Motion``; wire a
trained model in with a closure, e.g.
``lambda label, length, seed: generate(model, label, length=length, seed=seed)``
(``mrlib.sample.generate`` returns one ``Motion`` for ``num_samples=1``).

**Calibration rows.** The metrics alone are hard to read: a periodic clip (a walk) is
covered by anything walk-like, and an under-trained generator scores more "diverse"
than a second real take. ``calibration_rows`` builds comparison motions from the data,
scored with the same code and settings as the generators:

* ``played twice``: the training clip twice in a row, the second copy continuing the
  root path (coverage 100 %, global diversity ~0: a perfect copy);
* ``frozen first frame``: the first frame held for ``length_factor`` times the clip's
  length (no motion at all; coverage ~0 because its computed contact labels say both
  feet are always down: on the rotation channels alone a frozen walk frame can lie
  within ``eps`` of every window);
* ``other take`` / ``other style``: another real recording of the same content (same
  style, another take; or another style), when one exists. A second take is not
  always the closer one: actors vary a style between takes;
* ``different content``: a real clip of other content (a bow against a walk).

For Bandai Namco clips (``dataset-1_<content>_<style>_<take>``) the real counterparts
are found by name in ``$MRLIB_DATA_DIR`` (``find_bandai_counterparts``). Real clips are
scored at their own length; the synthetic rows are one clip each.

**Features.** Coverage and diversity use ``mrlib.metrics.metric_features``: the 23
non-root joints' local rotations in 6D plus the 6 foot-contact labels (``D = 144``).
Clips without contact labels get them from ``mrlib.contacts.foot_contacts`` (speed
threshold 0.25 m/s), so every clip is compared on the same channels. GANimator's
published numbers use its own features (21 joints of its skeleton plus 4 contacts), so
the values here are not on the same scale as GANimator's tables.
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from mrlib import metrics as mt
from mrlib import plausibility as pl
from mrlib.errors import ClipTooShortError, MotionValueError
from mrlib.motion import Motion
from mrlib.rotations import axis_angle_to_matrix, matrix_to_axis_angle

__all__ = [
    "SampleFn",
    "EvaluationSettings",
    "EvaluationResult",
    "play_twice",
    "freeze_first_frame",
    "default_data_dir",
    "parse_bandai_name",
    "find_bandai_counterparts",
    "calibration_rows",
    "score_motions",
    "evaluate",
    "CALIBRATION_METHODS",
]

SampleFn = Callable[[str, int, int], Motion]
"""``sample_fn(label, length, seed) -> Motion``: one generated clip of ``length`` frames."""

# Names of the calibration rows, in the order they are reported.
PLAYED_TWICE = "played twice"
FROZEN = "frozen first frame"
OTHER_TAKE = "other take"
OTHER_STYLE = "other style"
DIFFERENT_CONTENT = "different content"
CALIBRATION_METHODS = (PLAYED_TWICE, FROZEN, OTHER_TAKE, OTHER_STYLE, DIFFERENT_CONTENT)
_CALIB_PREFIX = "calib: "


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
    feature_kind: str = "6d"  # mrlib.metrics.metric_features(kind=...)
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
# Calibration motions
# ---------------------------------------------------------------------------------------
def _yaw_matrix(angle: float) -> np.ndarray:
    """Rotation about +Y by ``angle`` radians, ``(3, 3)``; maps +Z to (sin, 0, cos)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _heading(root_orient: np.ndarray) -> np.ndarray:
    """``(T, 3)`` axis-angle of the pelvis -> ``(T,)`` yaw (radians) of its +Z axis."""
    R = axis_angle_to_matrix(torch.from_numpy(np.asarray(root_orient, np.float64))).numpy()
    fwd = R[:, :, 2]  # (T, 3): the body's forward direction
    return np.arctan2(fwd[:, 0], fwd[:, 2])


def play_twice(motion: Motion) -> Motion:
    """The clip followed by a copy of itself that continues its root path.

    The copy is turned about the vertical axis and shifted on the ground so that its
    first frame is where the clip would be one frame after its last: heading (pelvis
    yaw) and ground position extrapolated from the last two frames. A walk keeps walking
    instead of jumping back to its start, and a clip moving along a circle continues on
    it exactly. Heights are kept. Contact labels, when present, are repeated.

    Args:
        motion: ``poses (T, 24, 3)``, ``trans (T, 3)``; ``T >= 2``.
    Returns:
        a ``Motion`` of ``2 T`` frames named ``"<name> x2"``.
    """
    T = motion.num_frames
    if T < 2:
        raise ClipTooShortError(f"{motion!r}: playing a clip twice needs at least 2 frames")
    # Frame T extrapolates the last frame: its heading turns on by the last frame's yaw
    # change, its position moves on by the last step turned by that change. The copy is
    # the rigid motion (yaw about +Y, then a shift) that takes frame 0 there.
    yaw = _heading(motion.poses[:, 0])
    turn = float(yaw[-1] - yaw[-2])
    Ry = _yaw_matrix(float(yaw[-1] - yaw[0]) + turn)
    R0 = axis_angle_to_matrix(torch.from_numpy(motion.poses[:, 0].astype(np.float64)))
    poses2 = motion.poses.astype(np.float64).copy()
    poses2[:, 0] = matrix_to_axis_angle(torch.from_numpy(Ry) @ R0).numpy()
    tr = motion.trans.astype(np.float64)
    step = _yaw_matrix(turn) @ (tr[-1] - tr[-2])
    anchor = np.array([tr[-1, 0] + step[0], tr[0, 1], tr[-1, 2] + step[2]])
    trans2 = (tr - tr[0]) @ Ry.T + anchor  # (T, 3); Ry keeps heights
    contacts = None if motion.contacts is None else np.concatenate([motion.contacts] * 2)
    return motion.replace(
        poses=np.concatenate([motion.poses, poses2.astype(np.float32)]),
        trans=np.concatenate([motion.trans, trans2.astype(np.float32)]),
        contacts=contacts,
        name=f"{motion.name or 'clip'} x2",
        meta=dict(motion.meta, calibration=PLAYED_TWICE),
    )


def freeze_first_frame(motion: Motion, length: int | None = None) -> Motion:
    """The first frame held still for ``length`` frames (default ``2 T``); no contact
    labels (computed ones are all 1: nothing moves)."""
    n = 2 * motion.num_frames if length is None else length
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise MotionValueError(f"length must be a positive integer, got {length!r}")
    return motion.replace(
        poses=np.repeat(motion.poses[:1], n, axis=0),
        trans=np.repeat(motion.trans[:1], n, axis=0),
        contacts=None,
        name=f"{motion.name or 'clip'} frame 0",
        meta=dict(motion.meta, calibration=FROZEN),
    )


def default_data_dir() -> Path:
    """The Bandai Namco dataset folder: ``$MRLIB_DATA_DIR``, else
    ``../shared/data/bandai-namco-motion-1`` next to the repository."""
    env = os.environ.get("MRLIB_DATA_DIR")
    if env:
        return Path(env).expanduser()
    return Path(__file__).resolve().parents[2] / "shared" / "data" / "bandai-namco-motion-1"


_BANDAI = re.compile(
    r"^(?:(?P<prefix>dataset-\d+)_)?(?P<content>[A-Za-z0-9-]+)_(?P<style>[A-Za-z0-9-]+)_(?P<take>\d+)$"
)


def parse_bandai_name(name: str) -> dict[str, str] | None:
    """``"dataset-1_walk_happy_001"`` (or ``"walk_happy_001"``) -> ``{"prefix":
    "dataset-1", "content": "walk", "style": "happy", "take": "001"}``; None when the
    name does not follow the Bandai Namco pattern."""
    m = _BANDAI.match(Path(str(name)).stem)
    if m is None:
        return None
    d = m.groupdict()
    d["prefix"] = d["prefix"] or ""
    return d


def find_bandai_counterparts(
    name: str,
    data_dir: str | Path | None = None,
    *,
    different_content: str | None = None,
    other_style: str = "normal",
) -> dict[str, Path]:
    """Real clips to calibrate against, found by Bandai Namco file names.

    Args:
        name: the training clip, e.g. ``"dataset-1_walk_happy_001"``.
        data_dir: the dataset folder (with a ``data/`` subfolder) or the folder of BVH
            files; default ``default_data_dir()``.
        different_content: content of the ``"different content"`` clip; default
            ``"bow"`` (``"walk"`` when the clip is a bow).
        other_style: preferred style of the ``"other style"`` clip (the first other
            style in alphabetical order when it is the clip's own or missing).

    Returns:
        ``{"other take": path, "other style": path, "different content": path}``, only
        the entries that exist: another take of the same content and style (lowest take
        number), the same content in another style (same take number when there is
        one), and the other content in the ``"normal"`` style. Empty when the name is
        not a Bandai Namco name or the folder is missing.
    """
    ref = parse_bandai_name(name)
    root = Path(data_dir) if data_dir is not None else default_data_dir()
    folder = root / "data" if (root / "data").is_dir() else root
    if ref is None or not folder.is_dir():
        return {}
    clips = []
    for p in sorted(folder.glob("*.bvh")):
        d = parse_bandai_name(p.stem)
        if d is not None and d["prefix"] == ref["prefix"]:
            clips.append((d, p))

    def pick(cands: list, prefer_take: str | None = None) -> Path | None:
        if not cands:
            return None
        same = [c for c in cands if c[0]["take"] == prefer_take]
        return sorted(same or cands, key=lambda c: (int(c[0]["take"]), c[1].name))[0][1]

    out: dict[str, Path] = {}
    take = pick(
        [c for c in clips if (c[0]["content"], c[0]["style"]) == (ref["content"], ref["style"])
         and c[0]["take"] != ref["take"]]
    )  # fmt: skip
    if take is not None:
        out[OTHER_TAKE] = take
    styles = sorted(
        {c[0]["style"] for c in clips if c[0]["content"] == ref["content"]} - {ref["style"]}
    )
    if styles:
        style = other_style if other_style in styles else styles[0]
        out[OTHER_STYLE] = pick(
            [c for c in clips if c[0]["content"] == ref["content"] and c[0]["style"] == style],
            ref["take"],
        )
    content = different_content or ("walk" if ref["content"] == "bow" else "bow")
    other = [c for c in clips if c[0]["content"] == content]
    if other:
        normal = [c for c in other if c[0]["style"] == "normal"]
        out[DIFFERENT_CONTENT] = pick(normal or other, "001")
    return out


def calibration_rows(
    reference: Motion,
    others: Mapping[str, Motion] | None = None,
    length_factor: float = 2.0,
) -> dict[str, Motion]:
    """Comparison motions for one training clip.

    Args:
        reference: the training clip.
        others: real clips by row name (``"other take"``, ``"other style"``,
            ``"different content"``, or any name), e.g. loaded from the paths of
            ``find_bandai_counterparts``; used as they are.
        length_factor: the frozen frame lasts ``round(length_factor * T)`` frames.

    Returns:
        ``{"played twice": ..., "frozen first frame": ..., **others}``.
    """
    if not isinstance(reference, Motion):
        raise MotionValueError(f"reference must be a Motion, got {type(reference).__name__}")
    if not (np.isfinite(length_factor) and length_factor > 0):
        raise MotionValueError(f"length_factor must be positive, got {length_factor}")
    rows = {
        PLAYED_TWICE: play_twice(reference),
        FROZEN: freeze_first_frame(reference, max(1, round(length_factor * reference.num_frames))),
    }
    for key, m in (others or {}).items():
        if not isinstance(m, Motion):
            raise MotionValueError(f"others[{key!r}] must be a Motion, got {type(m).__name__}")
        rows[key] = m
    return rows


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
    """All metrics of one row: ``motions`` (S clips) scored against ``reference``.

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
        ``mrlib.plausibility.plausibility_report`` with shares as ``*_pct``, ``samples``
        and ``frames`` (mean length).
    """
    s = settings or EvaluationSettings()
    if not motions:
        raise MotionValueError("score_motions: no motions")
    if body is None:
        from mrlib.body import load_body_model

        body = load_body_model()
    for m in motions:
        if not isinstance(m, Motion):
            raise MotionValueError(f"expected Motions, got {type(m).__name__}")
        if abs(m.fps - reference.fps) > 1e-6:
            raise MotionValueError(
                f"{m!r} is at {m.fps:g} fps but the reference {reference!r} is at "
                f"{reference.fps:g} fps; resample it first (Motion.resample)"
            )
    # One body forward per clip: joints and feet for plausibility, feet for the contact
    # labels of clips that have none (the same labels as mrlib.contacts.foot_contacts).
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
_PLOT_COLUMNS = (
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

    def plot(self, path: str | Path | None = None):
        """Bars (mean over sequences) and dots (sequences) per method for the main
        metrics; calibration rows in grey. Returns the matplotlib Figure; saved to
        ``path`` when given."""
        from matplotlib import colormaps
        from matplotlib.figure import Figure  # no pyplot: works headless, no global state

        methods = self.methods
        kinds = {r["method"]: r["kind"] for r in self.rows}
        headers = {k: h for k, h, _ in METRIC_COLUMNS}
        cmap = colormaps["tab10"]
        colors, model_i = [], 0
        for m in methods:
            if kinds[m] == "calibration":
                colors.append("0.6")
            else:
                colors.append(cmap(model_i % 10))
                model_i += 1
        fig = Figure(figsize=(16, 7.5), layout="constrained")
        axes = fig.subplots(2, 4)
        rng = np.random.default_rng(0)  # x jitter of the dots only
        x = np.arange(len(methods))
        for ax, key in zip(axes.ravel(), _PLOT_COLUMNS, strict=True):
            for i, m in enumerate(methods):
                v = np.array([r.get(key, math.nan) for r in self.rows if r["method"] == m], float)
                v = v[np.isfinite(v)]
                if not len(v):
                    continue
                ax.bar(i, v.mean(), color=colors[i], alpha=0.55, width=0.7)
                ax.scatter(i + rng.uniform(-0.18, 0.18, len(v)), v, s=14, color="k", zorder=3)
            ax.set_title(headers[key], fontsize=10)
            if key == "jerk_ratio":  # spans decades (a noisy bow: x100); 0 must stay visible
                ax.set_yscale("symlog", linthresh=1.0)
            ax.set_xticks(
                x,
                [m.replace(_CALIB_PREFIX, "") for m in methods],
                rotation=35,
                ha="right",
                fontsize=8,
            )
            ax.grid(axis="y", alpha=0.3)
        if any(kinds[m] == "calibration" for m in methods):
            fig.suptitle(
                "Methods (colour) and calibration rows (grey); dots: sequences", fontsize=11
            )
        if path is not None:
            fig.savefig(path, dpi=110)
        return fig

    def save(self, out_dir: str | Path) -> dict[str, Path]:
        """Write ``evaluation.csv``, ``evaluation_summary.csv``, ``evaluation.md`` and
        ``evaluation.png`` (and the settings as ``evaluation_settings.json``) into
        ``out_dir`` (created). Returns the paths by kind."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = {
            "csv": self.to_csv(out / "evaluation.csv"),
            "summary_csv": self.summary_to_csv(out / "evaluation_summary.csv"),
            "markdown": out / "evaluation.md",
            "png": out / "evaluation.png",
        }
        paths["markdown"].write_text("# Evaluation\n\n" + self.to_markdown(), encoding="utf-8")
        self.plot(paths["png"])
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


def _load_counterparts(
    label: str, reference: Motion, data_dir: Any, body: Any, notes: list[str]
) -> dict[str, Motion]:
    name = reference.name or Path(str(reference.meta.get("source", ""))).stem
    paths = find_bandai_counterparts(name, data_dir) if name else {}
    if not paths:
        notes.append(
            f"{label}: no real calibration clips (reference {name!r} is not a Bandai Namco "
            f"name, or {data_dir or default_data_dir()} is missing)"
        )
        return {}
    from mrlib.io import load_motion

    out = {}
    for key, p in paths.items():
        m = load_motion(p, body=body)
        out[key] = m.resample(reference.fps) if abs(m.fps - reference.fps) > 1e-6 else m
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
    if body is None:
        from mrlib.body import load_body_model

        body = load_body_model()

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
                others = _load_counterparts(label, ref, data_dir, body, notes)
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
                    {"method": _CALIB_PREFIX + key, "kind": "calibration", "sequence": label,
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
    """Training clips of a ``mrlib.sample.GenerativeModel`` as Motions, keyed by label
    (by clip name when several clips share a label)."""
    from mrlib.features import features_to_motion

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
    from mrlib.sample import generate

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
    (``mrlib.sample.cleanup_foot_contacts``), ``"both"`` both, the raw one as
    ``"<name> (raw)"``. Extra keyword arguments go to :func:`evaluate`.
    """
    if contacts not in ("raw", "clean", "both"):
        raise MotionValueError(f"contacts must be 'raw', 'clean' or 'both', got {contacts!r}")
    from mrlib.sample import generate, reconstruct

    refs = model_references(model)
    recon = {key: reconstruct(model, _clip_index(model, key)) for key in refs}
    extra, extra_recon = {}, {}
    for bname, b in (baselines or {}).items():
        per_key = dict(b) if isinstance(b, Mapping) else {key: b for key in refs}

        def fn(key: str, length: int, seed: int, _models=per_key) -> Motion:
            m = _models[key]
            label = m.labels[m.clip_labels[_clip_index(m, key)]]
            return generate(m, label, length=length, seed=seed)

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
