"""Condition control: which label drives which temporal resolution, and how to check it.

A model trained with style mixing (paper Sec. 4.3) can take one label ``A`` at the coarse
levels ``1..i`` and another label ``B`` at the fine levels ``i+1..L``
(``mrlib.sample.generate(model, conditions=[(A, (1, i)), (B, (i + 1, L))])``). The paper
claims the result combines A's coarse motion with B's fine detail. This module measures
that claim and builds the interactive view of it:

- :func:`crossover_evidence`: distances of a crossover sample's *low-pass* content and of
  its *high-frequency residual* to A and to B (four numbers);
- :func:`nearest_sequence_strip` / :func:`plot_nearest_sequence`: for every window of a
  generated clip, the training sequence its nearest window comes from;
- :func:`condition_fidelity_of_model`: ``mrlib.metrics.condition_fidelity`` of
  single-condition samples, per label;
- :func:`interactive_crossover`: an ipywidgets UI (coarse / fine label, crossover level,
  seed, blend weight) that regenerates a mesh view and the nearest-sequence strip.

**Bands.** The split into "coarse" and "fine" content follows the model's own pyramid:
level ``i`` runs at ``fps_i = fps * T_i / T_L`` (``mrlib.pyramid.level_fps``), so it can
only represent frequencies below its Nyquist frequency ``fps_i / 2``; everything above
that must come from levels ``i+1..L``. The default cutoff of the low-pass filter is
therefore the Nyquist frequency of the crossover level. We filter the *final* output
rather than compare the level-``i`` output itself: the level-``i`` output of a
crossover sample is made by label A alone, so comparing it with A would be true by
construction; what the claim needs is that A's coarse content *survives* the fine levels
run under B. The filter is a zero-phase Butterworth filter (:func:`lowpass`), steep
enough that the two bands barely overlap.

**Features and distances.** Per-frame features are the local joint rotations in 6D
(``mrlib.metrics.metric_features(motion, contacts=False)``, ``D = 138``): the root's
global orientation and path are left out, as in every mrlib metric, and the binary
contact labels are left out of the band split (a low-pass of a 0/1 step is not
"coarse motion"). The low-pass band is compared by the nearest-neighbour distance of
each frame (or ``window``) to the reference frames, averaged
(``mrlib.metrics.local_diversity``), so a difference of timing or phase between the
sample and the reference does not count. The residual band is compared by its
per-channel RMS over time (a ``(D,)`` profile, timing-free by construction): a
per-frame nearest neighbour of two noise-like residuals measures their energies more
than their shape (whichever reference has the weaker residual is "nearest" to
everything; on a 6-level model trained on four Bandai walks, 18 of 18 per-frame
residual verdicts named the label whose pure samples had the weaker residual), while
the profile tells which joints carry how much fine detail. By default both bands are
compared with pure samples of A and of B from the same model (see
:func:`crossover_evidence`).

**What we measured** (the ``tutorial`` networks at 400 iterations per block, four Bandai
walks normal/happy/sad/angry_001, 6 samples per case, all 12 ordered label pairs at
crossover levels 1-7). With the
paper's unconditional critics both halves of the claim hold in 17 of 84 cases, at least
once for 8 of the 12 pairs, almost all at crossover levels 1-2; from level 3 on the
low-pass band comes from A (as claimed) but the residual also follows A: the fine
levels add detail that fits the coarse motion they are given rather than B's. With
conditional critics (``ModelConfig.critic_condition``, scoring mixed samples with each
level's label) condition fidelity rises from 72 % to 94 %, but the crossover becomes a
switch: below a pair-dependent level the whole sample follows B, above it A (both
halves hold in 1 of 84 cases). Scoring mixed samples without a label
(``critic_mixed="none"``) keeps the low band with A (23 of 24 cases at levels 2 and 4) but
the residual with A too (fidelity 82 %); at 800 iterations per block the low band
follows A in 24 of 24 cases and the residual B in 2 of 24 (fidelity 96 %).

The ``tutorial`` preset gives the label term of each critic a branch of its own that
sees only the detail band ``x - box_5(x)`` (``ModelConfig.critic_band="detail"``), and
scores every level of a mixed sample with the label that drove it: the fine critics can
then ask for B's detail without asking the coarse motion to become B's. On its own that
made the residual follow B in 11 of 24 cases at levels 2 and 4 of the 12 pairs, the low
band A in 21 of 24, both in 8 (fidelity 96.5 %): it worked when the coarse label was the
more energetic one (angry as A: 5 of 6 cases with both halves) and not when it was the
calmest (sad as A: 0 of 6), since the fine detail of these walks scales with the coarse
motion it rides on.

What makes the crossover hold both ways is the detail-statistics term
(``LossWeights.detail``, weight 100 in ``tutorial``): it pulls the per-channel RMS of
the detail each level adds to that of its label's training clips. With it, both halves
hold in 23, 23, 22, 22 and 24 of 24 cases (training seeds 0-4) at condition fidelity
93.3, 92.2, 90.9, 94.7 and 93.5 %, coverage 100 % (eps = 2); all misses but one (a
residual, angry -> happy at level 4) are low bands of the two most alike walks, normal
and happy, at level 2. Weight 200 gives 24, 23 and 23 of 24 but fidelity 93.1, 87.5 and
85.8 %. Independent checks on a weight-200 model (seed 0; in brackets the model without
the term): the residual is nearer B by its log-RMS profile in 23 of 24 (9), by its RMS
profile scaled to unit norm in 16 (12), and with the training clips as references in 19
(13), so the term moves the residual's shape as well as its amount, though less.
``tests/test_control.py`` trains a small model on two Bandai walks with the term and
checks both directions. A nearly untrained model (2 iterations per block) already takes
the residual from B in 20 of 24 cases (the low band from A in 11, fidelity 25 %): the
fine levels make the residual whatever their weights, so only both halves together, on
a model whose single-label samples are faithful, are evidence for the claim.
``bench/condition_control.py`` prints all of these figures for one training seed.

Dimension letters: T frames, D feature channels, S samples, N windows, L levels.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mrlib.errors import MotionValueError
from mrlib.metrics import condition_fidelity, metric_features
from mrlib.motion import Motion

__all__ = [
    "lowpass",
    "split_bands",
    "rms_profile",
    "band_distances",
    "crossover_cutoff",
    "crossover_conditions",
    "crossover_blend",
    "CrossoverEvidence",
    "crossover_evidence",
    "evidence_table",
    "NearestSequenceStrip",
    "nearest_sequence_strip",
    "plot_nearest_sequence",
    "ConditionFidelity",
    "condition_fidelity_of_model",
    "coverage_per_sequence",
    "TrainRecord",
    "train_or_reuse",
    "crop_to_bodies",
    "CrossoverView",
    "interactive_crossover",
]


# ---------------------------------------------------------------------------------------
# Bands
# ---------------------------------------------------------------------------------------
FILTER_ORDER = 4  # Butterworth order of each pass (forward and backward)


def _check_cutoff(fps: float, cutoff_hz: float) -> None:
    if not (np.isfinite(fps) and fps > 0):
        raise MotionValueError(f"fps must be a positive number, got {fps}")
    if not (np.isfinite(cutoff_hz) and 0 < cutoff_hz < fps / 2):
        raise MotionValueError(
            f"cutoff must lie in (0, fps/2) = (0, {fps / 2:g}) Hz, got {cutoff_hz}"
        )


def lowpass(x: np.ndarray, fps: float, cutoff_hz: float) -> np.ndarray:
    """Zero-phase Butterworth low-pass along time (``scipy.signal.sosfiltfilt``).

    Order ``FILTER_ORDER`` run forwards and backwards: no delay, and an amplitude
    response ``1 / (1 + (tan(pi f / fps) / tan(pi f_c / fps))^8)`` (the digital
    Butterworth's), i.e. ``1/2`` at the cutoff and under 0.4% from twice the cutoff on.

    Args:
        x: ``(T, D)`` per-frame features.
        fps: frame rate of ``x``.
        cutoff_hz: cutoff frequency, in ``(0, fps / 2)``.
    Returns:
        ``(T, D)`` float64. Clip ends are padded by odd reflection (scipy's default), so
        constants and straight lines pass (to about 1e-4 of their range).
    """
    from scipy.signal import butter, sosfiltfilt

    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 2:
        raise MotionValueError(f"lowpass expects (T, D) features, got shape {x.shape}")
    _check_cutoff(fps, cutoff_hz)
    if len(x) < 2:
        return x.copy()
    sos = butter(FILTER_ORDER, cutoff_hz, btype="low", fs=fps, output="sos")
    pad = min(len(x) - 1, 3 * (2 * len(sos) + 1))  # scipy's default, shortened for short clips
    return sosfiltfilt(sos, x, axis=0, padlen=pad)


def split_bands(x: np.ndarray, fps: float, cutoff_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """``x (T, D)`` -> ``(low, high)``, both ``(T, D)``, with ``low + high == x``:
    :func:`lowpass` and the residual."""
    low = lowpass(x, fps, cutoff_hz)
    return low, np.asarray(x, np.float64) - low


def _check_level(model: Any, level: int) -> int:
    L = model.num_levels
    if isinstance(level, bool) or not isinstance(level, (int, np.integer)):
        raise MotionValueError(f"crossover level must be an integer, got {level!r}")
    if not 1 <= level <= L - 1:
        raise MotionValueError(
            f"crossover level must be in 1..{L - 1} (levels 1..i coarse, i+1..{L} fine), "
            f"got {level}"
        )
    return int(level)


def crossover_cutoff(model: Any, level: int, length: int) -> float:
    """Nyquist frequency (Hz) of level ``level`` (1-based) for a clip of ``length``
    frames: ``fps_i / 2`` with ``fps_i = fps * T_i / T_L`` (``mrlib.pyramid.level_fps``)."""
    from mrlib.pyramid import level_fps, pyramid_lengths

    level = _check_level(model, level)
    mc = model.config.model
    lengths = pyramid_lengths(
        int(length), mc.num_levels, mc.scale_factor, min_length=(mc.kernel_size - 1) // 2 + 1
    )
    return level_fps(model.fps, lengths)[level - 1] / 2


def crossover_conditions(
    model: Any, coarse_label: str | int, fine_label: str | int, level: int
) -> list[tuple[str | int, tuple[int, int]]]:
    """``[(coarse_label, (1, level)), (fine_label, (level + 1, L))]`` for ``generate``."""
    level = _check_level(model, level)
    model.label_index(coarse_label), model.label_index(fine_label)  # validate both
    return [(coarse_label, (1, level)), (fine_label, (level + 1, model.num_levels))]


# ---------------------------------------------------------------------------------------
# Crossover evidence
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CrossoverEvidence:
    """Where a coarse-A / fine-B sample's two bands come from (A = ``coarse_label``).

    ``low_to_coarse`` / ``low_to_fine``: mean per-frame nearest-neighbour distance of
    the crossover samples' low-pass band to A's / B's references (module docstring);
    ``high_to_coarse`` / ``high_to_fine``: distance of their residual's RMS profile to
    A's / B's. ``per_sample (S, 4)`` holds the four numbers per sample, in field order.
    ``residual_rms``: RMS norm of the residual band of the crossover samples, of A's and
    of B's references (the energy of the fine detail, and whose it resembles).
    """

    coarse_label: str
    fine_label: str
    level: int  # levels 1..level use the coarse label, level+1..L the fine one
    cutoff_hz: float
    reference: str  # "samples" (pure-label samples of the model) or "clips"
    low_to_coarse: float
    low_to_fine: float
    high_to_coarse: float
    high_to_fine: float
    residual_rms: tuple[float, float, float]  # crossover, coarse references, fine references
    per_sample: np.ndarray = field(repr=False)

    @property
    def low_holds(self) -> bool:
        """The low-pass band is closer to the coarse label than to the fine one."""
        return self.low_to_coarse < self.low_to_fine

    @property
    def high_holds(self) -> bool:
        """The residual band is closer to the fine label than to the coarse one."""
        return self.high_to_fine < self.high_to_coarse

    @property
    def holds(self) -> bool:
        """Both directions hold."""
        return self.low_holds and self.high_holds

    def as_rows(self) -> list[dict[str, Any]]:
        """One table row per band: the two distances, the label the band is closer to,
        and the one the crossover should give it."""
        a, b = self.coarse_label, self.fine_label
        return [
            {
                "band": f"low-pass (< {self.cutoff_hz:.1f} Hz)",
                f"to {a} (coarse)": self.low_to_coarse,
                f"to {b} (fine)": self.low_to_fine,
                "closer to": a if self.low_holds else b,
                "expected": a,
            },
            {
                "band": f"residual (> {self.cutoff_hz:.1f} Hz)",
                f"to {a} (coarse)": self.high_to_coarse,
                f"to {b} (fine)": self.high_to_fine,
                "closer to": b if self.high_holds else a,
                "expected": b,
            },
        ]

    def to_markdown(self) -> str:
        rows = self.as_rows()
        keys = list(rows[0])
        out = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
        for r in rows:
            cells = [f"{v:.4g}" if isinstance(v, float) else str(v) for v in r.values()]
            out.append("| " + " | ".join(cells) + " |")
        return "\n".join(out)

    def plot(self, axes: Any = None):
        """Bars per band: distance to the coarse label A and to the fine label B, with
        the per-sample values as dots. The bands have their own scales.

        Args:
            axes: two matplotlib Axes (low-pass, residual); a new figure when None.
        Returns:
            the two Axes.
        """
        import matplotlib.pyplot as plt

        if axes is None:
            _, axes = plt.subplots(1, 2, figsize=(9, 3.6), layout="constrained")
        axes = np.atleast_1d(axes)
        if len(axes) != 2:
            raise MotionValueError("CrossoverEvidence.plot needs two axes (one per band)")
        a, b = self.coarse_label, self.fine_label
        panels = (
            ("low", "low-pass band: per-frame NN distance", "expected: closer to A"),
            ("high", "residual band: RMS-profile distance", "expected: closer to B"),
        )
        for k, (ax, (key, title, note)) in enumerate(zip(axes, panels, strict=True)):
            vals = [getattr(self, f"{key}_to_coarse"), getattr(self, f"{key}_to_fine")]
            ax.bar([0, 1], vals, 0.6, color=["tab:blue", "tab:orange"])
            ps = self.per_sample[:, 2 * k : 2 * k + 2]
            jitter = np.linspace(-0.15, 0.15, len(ps)) if len(ps) > 1 else np.zeros(1)
            for j in range(2):
                ax.scatter(j + jitter, ps[:, j], s=7, color="k", zorder=3)
            ax.set_xticks([0, 1], [f"A = {a}\n(coarse, 1-{self.level})", f"B = {b}\n(fine)"])
            ax.set_title(f"{title}\n({note})", fontsize=9)
            ax.set_ylabel(f"distance to {self.reference}")
        axes[0].figure.suptitle(
            f"crossover at level {self.level}: bands split at {self.cutoff_hz:.1f} Hz",
            fontsize=10,
        )
        return axes


def evidence_table(evidences: Sequence[CrossoverEvidence]) -> str:
    """Several :class:`CrossoverEvidence` as one Markdown table, a row each: labels,
    crossover level, cutoff, the four distances and whether each direction holds."""
    head = (
        "| coarse (A) | fine (B) | level | cutoff Hz | low to A | low to B | "
        "residual to A | residual to B | low from A | residual from B |"
    )
    out = [head, "|" + "---|" * 10]
    yes = {True: "yes", False: "**no**"}
    for e in evidences:
        out.append(
            f"| {e.coarse_label} | {e.fine_label} | {e.level} | {e.cutoff_hz:.1f} | "
            f"{e.low_to_coarse:.3f} | {e.low_to_fine:.3f} | {e.high_to_coarse:.4f} | "
            f"{e.high_to_fine:.4f} | {yes[e.low_holds]} | {yes[e.high_holds]} |"
        )
    return "\n".join(out)


def _reference_features(
    model: Any, kind: str = "6d", contacts: bool = True
) -> tuple[list[str], list[str], list[np.ndarray]]:
    """Training clips of a model as metric features: ``(names, labels, [(T_k, D)])``."""
    from mrlib.features import features_to_motion

    names, labels, feats = [], [], []
    for k, x in enumerate(model.features):
        lab = model.labels[model.clip_labels[k]]
        m = features_to_motion(x, model.fps, betas=model.betas, label=lab, name=model.clip_names[k])
        names.append(model.clip_names[k])
        labels.append(lab)
        feats.append(metric_features(m, kind=kind, contacts=contacts))
    return names, labels, feats


def _nn_distance(x: np.ndarray, refs: Sequence[np.ndarray], window: int) -> float:
    """Mean over the windows of ``x (T, D)`` of the distance to the nearest window among
    ``refs`` (windows never straddle two references). For one reference this is
    ``mrlib.metrics.local_diversity(x, refs[0], window)``."""
    from mrlib.metrics import _pair, _window_nn

    per_ref = []
    for r in refs:
        g, rr = _pair(x, r)
        per_ref.append(_window_nn(g, rr, window, False)[0])
    return float(np.min(per_ref, axis=0).mean())


def rms_profile(x: np.ndarray) -> np.ndarray:
    """Per-channel root mean square over time, ``(T, D) -> (D,)``."""
    x = np.asarray(x, np.float64)
    if x.ndim != 2 or len(x) == 0:
        raise MotionValueError(f"rms_profile expects (T, D) with T >= 1, got shape {x.shape}")
    return np.sqrt((x * x).mean(0))


def _check_count(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise MotionValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def band_distances(
    x: np.ndarray,
    coarse_refs: Sequence[np.ndarray],
    fine_refs: Sequence[np.ndarray],
    fps: float,
    cutoff_hz: float,
    window: int = 1,
) -> np.ndarray:
    """The four crossover distances of one clip, ``(4,)``: low band to the coarse and
    to the fine references, residual band to the coarse and to the fine references.

    Args:
        x: ``(T, D)`` features of the clip (e.g. ``metric_features(m, contacts=False)``).
        coarse_refs, fine_refs: lists of ``(T_k, D)`` features of each label's references.
        fps: frame rate of all of them; cutoff_hz: band split (:func:`split_bands`).
        window: window of the low-band nearest-neighbour distance.
    Returns:
        ``[low_to_coarse, low_to_fine, high_to_coarse, high_to_fine]``: low band, mean
        nearest-neighbour distance to the nearest reference window; residual band,
        distance of :func:`rms_profile` to the references' mean profile.
    """
    window = _check_count("window", window)
    bands = [_split_refs(r, fps, cutoff_hz, window) for r in (coarse_refs, fine_refs)]
    return _band_distances(split_bands(x, fps, cutoff_hz), *bands, window)


def _split_refs(
    refs: Sequence[np.ndarray], fps: float, cutoff_hz: float, window: int
) -> tuple[list[np.ndarray], np.ndarray]:
    """References -> (their low bands, the mean RMS profile ``(D,)`` of their residuals)."""
    if len(refs) == 0:
        raise MotionValueError("need at least one reference clip per label")
    lows, profiles = [], []
    for r in refs:
        r = np.asarray(r, np.float64)
        if r.ndim != 2 or len(r) < window:
            raise MotionValueError(
                f"a reference must be (T, D) with T >= window {window}, got shape {r.shape}"
            )
        lo, hi = split_bands(r, fps, cutoff_hz)
        lows.append(lo)
        profiles.append(rms_profile(hi))
    return lows, np.mean(profiles, 0)


def _band_distances(
    bands: tuple[np.ndarray, np.ndarray],
    coarse: tuple[list[np.ndarray], np.ndarray],
    fine: tuple[list[np.ndarray], np.ndarray],
    window: int,
) -> np.ndarray:
    low, high = bands
    p = rms_profile(high)
    return np.array(
        [
            _nn_distance(low, coarse[0], window),
            _nn_distance(low, fine[0], window),
            float(np.linalg.norm(p - coarse[1])),
            float(np.linalg.norm(p - fine[1])),
        ]
    )


REFERENCE_SEED_OFFSET = 1_000_003  # pure-label reference samples share no noise with the mix


def crossover_evidence(
    model: Any,
    coarse_label: str | int,
    fine_label: str | int,
    level: int,
    num_samples: int = 8,
    seed: int = 0,
    cutoff: float | None = None,
    *,
    length: int | None = None,
    window: int = 1,
    reference: str = "samples",
) -> CrossoverEvidence:
    """Does a coarse-A / fine-B sample take its low-pass band from A and its
    high-frequency residual from B?

    Generates ``num_samples`` crossover samples (A at levels ``1..level``, B above),
    splits them into bands (:func:`split_bands`) and compares each band with A's and
    with B's references:

    - low-pass band: mean per-frame (``window``) nearest-neighbour distance to the
      nearest window over all of the label's references;
    - residual band: Euclidean distance between the sample's residual RMS profile
      (:func:`rms_profile`, ``(D,)``) and the mean profile of the label's references.

    The references are, with ``reference="samples"`` (default), ``num_samples`` pure-A
    and pure-B samples of the same length (seed ``seed + REFERENCE_SEED_OFFSET``, so no
    noise is shared with the crossover); with ``"clips"``, the training clips of A and
    B. Pure samples answer the question inside the model; training clips also measure
    how far the model is from the data, and their residual band carries far more energy
    than generated motion does, which then swamps the comparison.

    Args:
        model: a ``mrlib.sample.GenerativeModel``.
        coarse_label: label A (name or index); fine_label: label B.
        level: the crossover level ``i``, ``1 <= i <= L - 1``.
        num_samples: ``S`` samples of each kind (seeded; a sample does not depend on S).
        seed: noise seed of the crossover samples.
        cutoff: low-pass half-power frequency in Hz; default the Nyquist frequency of
            level ``i`` (:func:`crossover_cutoff`).
        length: frames per sample; default the longer of A's and B's first training clip.
        window: window of the low-band nearest-neighbour distance in frames (1: per frame).
        reference: ``"samples"`` or ``"clips"``.
    Returns:
        :class:`CrossoverEvidence`.
    """
    from mrlib.sample import generate

    num_samples = _check_count("num_samples", num_samples)
    window = _check_count("window", window)
    if reference not in ("samples", "clips"):
        raise MotionValueError(f"reference must be 'samples' or 'clips', got {reference!r}")
    conds = crossover_conditions(model, coarse_label, fine_label, level)
    a, b = model.label_index(coarse_label), model.label_index(fine_label)
    if a == b:
        raise MotionValueError("coarse and fine label are the same; nothing to compare")
    if length is None:
        length = max(int(model.lengths[model.clip_labels.index(k), -1]) for k in (a, b))
    length = _check_count("length", length)
    if length < window:
        raise MotionValueError(f"length {length} is shorter than the window {window}")
    cutoff = crossover_cutoff(model, level, length) if cutoff is None else float(cutoff)
    _check_cutoff(model.fps, cutoff)

    def samples(seed_: int, **cond: Any) -> list[np.ndarray]:
        ms = generate(model, length=length, seed=seed_, num_samples=num_samples, **cond)
        return [
            metric_features(m, contacts=False) for m in ([ms] if isinstance(ms, Motion) else ms)
        ]

    if reference == "samples":
        refs = {k: samples(seed + REFERENCE_SEED_OFFSET, condition=k) for k in (a, b)}
    else:
        _, clip_labels, feats = _reference_features(model, contacts=False)
        refs = {
            k: [f for f, lab in zip(feats, clip_labels, strict=True) if lab == model.labels[k]]
            for k in (a, b)
        }
    split = {k: _split_refs(refs[k], model.fps, cutoff, window) for k in (a, b)}
    rows, energy = [], []
    for x in samples(seed, conditions=conds):
        bands = split_bands(x, model.fps, cutoff)
        energy.append(np.linalg.norm(rms_profile(bands[1])))
        rows.append(_band_distances(bands, split[a], split[b], window))
    per = np.asarray(rows)  # (S, 4)
    mean = per.mean(0)
    return CrossoverEvidence(
        coarse_label=model.labels[a],
        fine_label=model.labels[b],
        level=int(level),
        cutoff_hz=float(cutoff),
        reference="pure samples" if reference == "samples" else "training clips",
        low_to_coarse=float(mean[0]),
        low_to_fine=float(mean[1]),
        high_to_coarse=float(mean[2]),
        high_to_fine=float(mean[3]),
        residual_rms=(
            float(np.mean(energy)),
            float(np.linalg.norm(split[a][1])),
            float(np.linalg.norm(split[b][1])),
        ),
        per_sample=per,
    )


# ---------------------------------------------------------------------------------------
# Nearest training sequence of every window
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class NearestSequenceStrip:
    """For each ``window``-frame window of a generated clip (by first frame), the training
    sequence holding its nearest window.

    Attributes:
        names: the training sequences (clip names, or the keys of the references given).
        labels: their labels.
        index: ``(N,)`` int, index into ``names`` per generated window, ``N = T - w + 1``.
        start: ``(N,)`` int, first frame of the nearest window inside that sequence.
        distance: ``(N,)`` mean per-frame distance to it.
        window: ``w`` in frames; fps: frame rate of the generated clip.
    """

    names: tuple[str, ...]
    labels: tuple[str, ...]
    index: np.ndarray
    start: np.ndarray
    distance: np.ndarray
    window: int
    fps: float

    def shares(self) -> dict[str, float]:
        """Share of generated windows whose nearest window is in each sequence."""
        n = len(self.index)
        return {nm: float((self.index == k).sum() / n) for k, nm in enumerate(self.names)}

    def label_shares(self) -> dict[str, float]:
        """Share of generated windows per label of the nearest sequence."""
        out: dict[str, float] = {}
        for nm_share, lab in zip(self.shares().values(), self.labels, strict=True):
            out[lab] = out.get(lab, 0.0) + nm_share
        return out


def _references_of(model_or_references: Any) -> tuple[list[str], list[str], list[np.ndarray]]:
    if isinstance(model_or_references, Mapping):
        if not model_or_references:
            raise MotionValueError("references is empty")
        names, labels, feats = [], [], []
        for key, ref in model_or_references.items():
            names.append(str(key))
            labels.append(ref.label if isinstance(ref, Motion) and ref.label else str(key))
            feats.append(metric_features(ref))
        return names, labels, feats
    if hasattr(model_or_references, "features") and hasattr(model_or_references, "clip_labels"):
        return _reference_features(model_or_references)
    raise MotionValueError(
        "model_or_references must be a GenerativeModel or a mapping name -> Motion / (T, D) "
        f"features, got {type(model_or_references).__name__}"
    )


def nearest_sequence_strip(
    motion: Motion | np.ndarray, model_or_references: Any, window: int = 30
) -> NearestSequenceStrip:
    """Which training sequence every generated window is closest to.

    Args:
        motion: a generated ``Motion`` (or its ``(T, D)`` metric features).
        model_or_references: a ``GenerativeModel`` (its training clips) or a mapping
            name -> ``Motion`` or ``(T_k, D)`` features (``mrlib.metrics.metric_features``).
        window: window length in frames (30, as coverage and condition fidelity).
    Returns:
        :class:`NearestSequenceStrip`; the distances are those of
        ``mrlib.metrics.condition_fidelity`` (6D local rotations + contacts).
    """
    from mrlib.metrics import _pair, _window_nn

    window = _check_count("window", window)
    names, labels, refs = _references_of(model_or_references)
    x = metric_features(motion)
    fps = float(motion.fps) if isinstance(motion, Motion) else float("nan")
    if len(x) < window:
        raise MotionValueError(f"the clip has {len(x)} frames, fewer than the window {window}")
    dists, starts = [], []
    for nm, r in zip(names, refs, strict=True):
        if len(r) < window:
            raise MotionValueError(f"reference {nm!r} has {len(r)} frames < window {window}")
        g, rr = _pair(x, r, "generated", f"reference {nm!r}")
        d, s = _window_nn(g, rr, int(window), False)
        dists.append(d)
        starts.append(s)
    D, S = np.stack(dists), np.stack(starts)  # (K, N)
    idx = D.argmin(0)
    cols = np.arange(D.shape[1])
    return NearestSequenceStrip(
        names=tuple(names),
        labels=tuple(labels),
        index=idx,
        start=S[idx, cols],
        distance=D[idx, cols],
        window=int(window),
        fps=fps,
    )


_STRIP_COLOURS = (
    "tab:blue",
    "tab:orange",
    "tab:green",
    "tab:red",
    "tab:purple",
    "tab:brown",
    "tab:pink",
    "tab:gray",
    "tab:olive",
    "tab:cyan",
)


def plot_nearest_sequence(
    strip: NearestSequenceStrip, axes: Any = None, *, title: str | None = None
):
    """Two panels over generated time: a colour band naming the nearest training sequence
    of every window, and where in that sequence the window is (start frame, seconds).
    Diagonal runs in the lower panel are stretches that follow one training clip.

    Args:
        strip: from :func:`nearest_sequence_strip`.
        axes: two matplotlib Axes (band, position); a new figure when None.
    Returns:
        the two Axes.
    """
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    if axes is None:
        _, axes = plt.subplots(
            2, 1, figsize=(9, 3.4), sharex=True, gridspec_kw={"height_ratios": [1, 3]}
        )
    axes = np.atleast_1d(axes)
    if len(axes) != 2:
        raise MotionValueError("plot_nearest_sequence needs two axes")
    fps = strip.fps if np.isfinite(strip.fps) else 1.0
    unit = "s" if np.isfinite(strip.fps) else "frames"
    K, N = len(strip.names), len(strip.index)
    colours = [_STRIP_COLOURS[k % len(_STRIP_COLOURS)] for k in range(K)]
    t = np.arange(N) / fps
    band, pos = axes
    band.imshow(
        strip.index[None],
        aspect="auto",
        cmap=ListedColormap(colours),
        vmin=-0.5,
        vmax=K - 0.5,
        interpolation="nearest",
        extent=(0, N / fps, 0, 1),
    )
    band.set_yticks([])
    band.tick_params(labelbottom=False)
    pos.set_xlim(0, N / fps)
    band.set_title(
        title or f"nearest training sequence of every {strip.window}-frame window", fontsize=10
    )
    for k in range(K):
        on = strip.index == k
        if on.any():
            pos.scatter(t[on], strip.start[on] / fps, s=6, color=colours[k])
    pos.set_xlabel(f"generated window start ({unit})")
    pos.set_ylabel(f"position in source ({unit})")
    shares = strip.shares()
    handles = [
        Patch(color=colours[k], label=f"{nm} [{lab}] {100 * shares[nm]:.0f}%")
        for k, (nm, lab) in enumerate(zip(strip.names, strip.labels, strict=True))
    ]
    pos.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return axes


# ---------------------------------------------------------------------------------------
# Condition fidelity of a model
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ConditionFidelity:
    """Condition fidelity of single-condition samples (``mrlib.metrics.condition_fidelity``).

    ``overall`` pools every window of every sample (all samples have the same length, so
    it is the mean of ``per_label``). ``confusion (K, K)``: row = requested label, column
    = label of the nearest training window, shares of windows (rows sum to 1; with one
    clip per label its diagonal is ``per_label``), in the order of ``labels``."""

    overall: float
    per_label: dict[str, float]
    labels: tuple[str, ...]
    confusion: np.ndarray
    num_samples: int
    length: int
    window: int
    seed: int

    def to_markdown(self) -> str:
        rows = ["| label | condition fidelity |", "|---|---|"]
        rows += [f"| {k} | {100 * v:.1f}% |" for k, v in self.per_label.items()]
        rows.append(f"| **all** | **{100 * self.overall:.1f}%** |")
        return "\n".join(rows)

    def plot(self, ax: Any = None):
        """The confusion matrix as an image, shares in %."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(4.6, 3.8))
        K = len(self.labels)
        ax.imshow(100 * self.confusion, cmap="Blues", vmin=0, vmax=100)
        for i in range(K):
            for j in range(K):
                v = 100 * self.confusion[i, j]
                ax.text(j, i, f"{v:.0f}", ha="center", va="center",
                        color="white" if v > 60 else "black", fontsize=9)  # fmt: skip
        ax.set_xticks(range(K), self.labels, rotation=30, ha="right")
        ax.set_yticks(range(K), self.labels)
        ax.set_xlabel("label of the nearest training window")
        ax.set_ylabel("requested label")
        ax.set_title(f"condition fidelity {100 * self.overall:.1f}% (diagonal, %)", fontsize=10)
        return ax


def condition_fidelity_of_model(
    model: Any,
    num_samples: int = 10,
    length: int | None = None,
    seed: int = 0,
    window: int = 30,
) -> ConditionFidelity:
    """Generate ``num_samples`` samples of every label (one label at every level) and
    measure the share of their windows whose nearest training window has that label.

    Args:
        model: a ``GenerativeModel``.
        length: frames per sample; default twice the longest training clip (samples
            longer than the training clips, as the paper's evaluation uses).
        seed: noise seed (every label's samples use the same seed).
        window: window in frames (30, the paper's ``T_c``).
    Returns:
        :class:`ConditionFidelity`. When several training clips share a label their
        frames are joined into one reference per label (``condition_fidelity`` takes
        one reference per label), so a few windows straddle two clips.
    """
    from mrlib.sample import generate

    num_samples = _check_count("num_samples", num_samples)
    _, labels, feats = _reference_features(model)
    refs = {
        lab: np.concatenate([f for f, lb in zip(feats, labels, strict=True) if lb == lab])
        for lab in dict.fromkeys(labels)
    }
    if length is None:
        length = 2 * int(model.lengths[:, -1].max())
    per_label, names = {}, list(refs)
    confusion = np.zeros((len(names), len(names)))
    for k, lab in enumerate(names):
        ms = generate(model, lab, length=int(length), seed=seed, num_samples=num_samples)
        ms = [ms] if isinstance(ms, Motion) else ms
        per_label[lab] = condition_fidelity(ms, refs, window=window)
        for m in ms:
            shares = nearest_sequence_strip(m, refs, window).shares()
            confusion[k] += [shares[n] / len(ms) for n in names]
    return ConditionFidelity(
        overall=float(np.mean(list(per_label.values()))),
        per_label=per_label,
        labels=tuple(names),
        confusion=confusion,
        num_samples=int(num_samples),
        length=int(length),
        window=int(window),
        seed=int(seed),
    )


def coverage_per_sequence(
    model: Any,
    num_samples: int = 20,
    length_factor: float = 2.0,
    seed: int = 0,
    eps: float | Sequence[float] = 2.0,
    window: int = 30,
) -> dict[str, float] | dict[float, dict[str, float]]:
    """``mrlib.metrics.coverage`` of every training sequence by samples of its label.

    For clip k (label l, ``T_k`` frames): ``num_samples`` samples of label l, each
    ``round(length_factor * T_k)`` frames, and the mean over them of the share of clip
    k's ``window``-frame windows with a generated window closer than ``eps``.

    Args:
        eps: one threshold, or several (the same samples serve every threshold).
    Returns:
        clip name -> coverage in [0, 1]; for several thresholds, eps -> that dict.
    """
    from mrlib.metrics import coverage_profile
    from mrlib.sample import generate

    num_samples = _check_count("num_samples", num_samples)
    if not (np.isfinite(length_factor) and length_factor > 0):
        raise MotionValueError(f"length_factor must be positive, got {length_factor}")
    many = not isinstance(eps, (int, float, np.floating, np.integer))
    epss = [float(e) for e in (eps if many else [eps])]
    if not epss or not all(np.isfinite(e) and e > 0 for e in epss):
        raise MotionValueError(f"eps must be positive numbers, got {eps}")
    names, labels, feats = _reference_features(model)
    out: dict[float, dict[str, float]] = {e: {} for e in epss}
    for name, lab, ref in zip(names, labels, feats, strict=True):
        length = max(window, round(length_factor * len(ref)))
        ms = generate(model, lab, length=length, seed=seed, num_samples=num_samples)
        # coverage = mean over samples of the share of reference windows closer than eps
        # (mrlib.metrics.coverage); the profiles are computed once for all thresholds
        prof = np.stack(
            [coverage_profile(m, ref, window) for m in ([ms] if isinstance(ms, Motion) else ms)]
        )
        for e in epss:
            out[e][name] = float((prof < e).mean(1).mean())
    return out if many else out[epss[0]]


@dataclass(frozen=True)
class TrainRecord:
    """How a model of :func:`train_or_reuse` came about."""

    checkpoint: Any  # pathlib.Path
    wall_time_s: float  # training time of the run that wrote the checkpoint
    reused: bool  # True: an earlier, finished run with the same config and clips


def train_or_reuse(
    data: Any, config: Any, out_dir: Any, *, body: Any = None, progress: bool = True
) -> tuple[Any, TrainRecord]:
    """Train with ``mrlib.train.train`` unless ``out_dir`` already holds a finished run
    with the same config (field for field, as saved next to the checkpoint) and the same
    clips; then load it. Notebooks use this so that a
    reader's long run is not repeated on every execution.

    Returns:
        ``(model, record)``: the ``GenerativeModel`` and a :class:`TrainRecord`; for a
        reused run the wall time is the last ``time_s`` of its ``losses.csv`` (the time
        of its last logged iteration, without the final checkpoint write).
    """
    import csv
    import json
    from pathlib import Path

    from mrlib.config import config_to_json
    from mrlib.sample import load_model
    from mrlib.train import train

    out = Path(out_dir)
    ckpt, log = out / "checkpoint.pt", out / "losses.csv"
    if ckpt.exists() and ckpt.with_suffix(".pt.json").exists() and log.exists():
        # Compare the JSON itself: a field missing from it means an older mrlib wrote the
        # run, whose defaults may differ from today's.
        saved = json.loads(ckpt.with_suffix(".pt.json").read_text())
        if saved == json.loads(config_to_json(config)):
            model = load_model(ckpt)
            if model.trained_levels == model.num_levels and model.clip_names == list(data.names):
                with open(log, newline="") as fh:
                    rows = list(csv.DictReader(fh))
                wall = float(rows[-1]["time_s"]) if rows else float("nan")
                return model, TrainRecord(ckpt, wall, True)
    res = train(data, config, out, body=body, progress=progress)
    return load_model(res.checkpoint), TrainRecord(res.checkpoint, res.wall_time_s, False)


# ---------------------------------------------------------------------------------------
# Interactive crossover
# ---------------------------------------------------------------------------------------
def crop_to_bodies(image: np.ndarray, pad: int = 16, min_saturation: int = 25) -> np.ndarray:
    """Crop a ``render_meshes`` image ``(H, W, 3)`` uint8 to its coloured pixels (skin,
    contact markers) plus ``pad`` pixels: the white background and the grey floor have
    (almost) equal RGB channels and fall away. Returns the image unchanged when nothing
    is coloured."""
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] < 3:
        raise MotionValueError(f"expected an (H, W, 3) image, got shape {img.shape}")
    rgb = img[..., :3].astype(np.int16)
    coloured = (rgb.max(-1) - rgb.min(-1)) > min_saturation  # (H, W)
    rows, cols = np.flatnonzero(coloured.any(1)), np.flatnonzero(coloured.any(0))
    if len(rows) == 0:
        return img
    r0, r1 = max(0, rows[0] - pad), min(img.shape[0], rows[-1] + pad + 1)
    c0, c1 = max(0, cols[0] - pad), min(img.shape[1], cols[-1] + pad + 1)
    return img[r0:r1, c0:c1]


@dataclass
class CrossoverView:
    """What one call of the interactive view made."""

    motion: Motion
    weights: np.ndarray  # (L, K) per-level label weights used (mrlib.sample.label_weights)
    strip: NearestSequenceStrip
    image: np.ndarray | None  # (H, W, 3) mesh render, None when rendering is off
    title: str


def crossover_blend(
    model: Any, coarse_label: str | int, fine_label: str | int, level: int, weight: float
) -> tuple[str | int, str | int, list[float]]:
    """``blend=(coarse, fine, w)`` for ``generate``: weight 0 of the fine label at levels
    ``1..level`` and ``weight`` at ``level+1..L`` (1: a plain crossover, 0: pure coarse)."""
    level = _check_level(model, level)
    if not (np.isfinite(weight) and 0.0 <= weight <= 1.0):
        raise MotionValueError(f"blend weight must be in [0, 1], got {weight}")
    L = model.num_levels
    return coarse_label, fine_label, [0.0] * level + [float(weight)] * (L - level)


def interactive_crossover(
    model: Any,
    body: Any = None,
    *,
    frames: int = 5,
    length: int | None = None,
    window: int = 30,
    render: bool = True,
    coarse: str | None = None,
    fine: str | None = None,
    level: int | None = None,
) -> tuple[Any, Callable[[], CrossoverView]]:
    """An ipywidgets UI for label crossover.

    Controls: *coarse* label (levels ``1..i``), *fine* label (levels ``i+1..L``), the
    crossover level ``i``, the seed, and *fine weight* ``w`` in [0, 1]: the fine levels get
    the condition ``(1 - w) * coarse + w * fine`` (FiLM is linear in the condition, so this
    interpolates the two labels' embeddings; see ``mrlib.sample.label_weights``), the
    coarse levels stay pure. ``w = 1`` is the plain crossover of the paper, ``w = 0`` the
    coarse label alone; one number per control keeps the UI readable (per-level weights
    are available through ``generate(blend=(a, b, [w_1, ..., w_L]))``).

    Every change regenerates the sample and redraws, into an ``Output`` widget, a mesh
    render of ``frames`` frames (``mrlib.render_meshes``) titled with the labels and the
    nearest-sequence strip (:func:`plot_nearest_sequence`).

    Args:
        model: a ``GenerativeModel`` with at least two levels.
        body: body model for rendering (default ``load_body_model()`` when rendering).
        frames: mesh snapshots per render.
        length: frames per sample; default the longest training clip.
        window: window of the nearest-sequence strip.
        render: draw the mesh view (off: only the strip, e.g. without pyvista).
        coarse, fine, level: initial control values (default: the first label, the
            last label, ``L // 2``).
    Returns:
        ``(widget, update)``: the ``VBox`` to display and the callback; ``update()``
        regenerates with the current control values and returns a :class:`CrossoverView`.
    """
    import ipywidgets as w
    import matplotlib.pyplot as plt
    from IPython.display import display

    from mrlib.render import evenly_spaced_frames, render_meshes
    from mrlib.sample import generate, label_weights

    L = model.num_levels
    if L < 2:
        raise MotionValueError("a crossover needs a model with at least two levels")
    if len(model.labels) < 1:
        raise MotionValueError("the model has no labels")
    if render and body is None:
        from mrlib.body import load_body_model

        body = load_body_model()
    length = int(model.lengths[:, -1].max()) if length is None else int(length)
    references = _references_of(model)  # computed once, reused by every update
    labels = list(model.labels)

    first = [model.labels[model.label_index(x)] for x in (coarse or labels[0], fine or labels[-1])]
    level = max(1, L // 2) if level is None else _check_level(model, level)
    coarse = w.Dropdown(options=labels, value=first[0], description="coarse")
    fine = w.Dropdown(options=labels, value=first[1], description="fine")
    level = w.IntSlider(
        value=level, min=1, max=L - 1, description="crossover i", continuous_update=False
    )
    seed = w.BoundedIntText(value=0, min=0, max=2**31 - 1, description="seed")
    weight = w.FloatSlider(
        value=1.0, min=0.0, max=1.0, step=0.05, description="fine weight", continuous_update=False
    )
    out = w.Output()
    status = w.HTML()

    def update(*_: Any) -> CrossoverView:
        a, b, i, wt = coarse.value, fine.value, int(level.value), float(weight.value)
        blend = crossover_blend(model, a, b, i, wt)
        W = label_weights(model, blend=blend).numpy()
        motion = generate(model, blend=blend, length=length, seed=int(seed.value))
        strip = _strip_from(motion, references, window)
        fine_txt = b if wt == 1.0 else f"{1 - wt:.2f} {a} + {wt:.2f} {b}"
        title = f"coarse '{a}' at levels 1-{i}, fine '{fine_txt}' at levels {i + 1}-{L} (seed {seed.value})"
        image = None
        if render:
            frame_ids = evenly_spaced_frames(len(motion), frames)
            image = crop_to_bodies(render_meshes(motion, body, frames=frame_ids))
        fig = plt.figure(figsize=(10, 6.4 if render else 3.4))
        ratios = [4, 0.5, 2] if render else [0.5, 2]  # (mesh view,) band, positions
        grid = fig.add_gridspec(len(ratios), 1, height_ratios=ratios)
        axs = [fig.add_subplot(g) for g in grid]
        if render:
            axs[0].imshow(image)
            axs[0].axis("off")
            axs[0].set_title(title, fontsize=10)
            axs = axs[1:]
        axs[1].sharex(axs[0])
        plot_nearest_sequence(strip, axs, title=None if render else title)
        fig.tight_layout()
        with out:
            out.clear_output(wait=True)
            display(fig)
        plt.close(fig)
        shares = ", ".join(f"{k} {100 * v:.0f}%" for k, v in strip.label_shares().items())
        status.value = f"nearest-window labels: {shares}"
        return CrossoverView(motion=motion, weights=W, strip=strip, image=image, title=title)

    for c in (coarse, fine, level, seed, weight):
        c.observe(lambda change: update(), names="value")
    box = w.VBox([w.HBox([coarse, fine]), w.HBox([level, weight]), seed, status, out])
    return box, update


def _strip_from(
    motion: Motion, references: tuple[list[str], list[str], list[np.ndarray]], window: int
) -> NearestSequenceStrip:
    """:func:`nearest_sequence_strip` against already computed reference features."""
    names, labels, feats = references
    strip = nearest_sequence_strip(motion, dict(zip(names, feats, strict=True)), window)
    return NearestSequenceStrip(
        names=strip.names,
        labels=tuple(labels),
        index=strip.index,
        start=strip.start,
        distance=strip.distance,
        window=strip.window,
        fps=strip.fps,
    )
