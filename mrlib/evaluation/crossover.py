"""Condition control: which label drives which temporal resolution, and how to check it.

A model trained with style mixing (paper Sec. 4.3) can take one label ``A`` at the coarse
levels ``1..i`` and another label ``B`` at the fine levels ``i+1..L``
(``mrlib.generate(model, mrlib.Condition.crossover(A, B, i))``). The paper
claims the result combines A's coarse motion with B's fine detail. This module measures
that claim:

- :func:`crossover_evidence`: distances of a crossover sample's *low-pass* content and of
  its *high-frequency residual* to A and to B (four numbers);
- :func:`crossover_conditions` / :func:`crossover_blend`: the ``Condition`` of a
  crossover at level ``i`` (checked against the model), plain or blended.

Whether single-label samples are faithful to their label in the first place (nearest
training sequence of every window, condition fidelity, coverage per clip) is measured
by ``mrlib.evaluation.fidelity``, whose names are importable from here too. Pictures are in
``mrlib.viz.plots`` (``plot_crossover_evidence``), the interactive view in
``mrlib.viz.widgets.interactive_crossover``.

**Bands.** The split into "coarse" and "fine" content follows the model's own pyramid:
level ``i`` runs at ``fps_i = fps * T_i / T_L`` (``mrlib.model.pyramid.level_fps``), so it can
only represent frequencies below its Nyquist frequency ``fps_i / 2``; everything above
that must come from levels ``i+1..L``. The default cutoff of the low-pass filter is
therefore the Nyquist frequency of the crossover level. We filter the *final* output
rather than compare the level-``i`` output itself: the level-``i`` output of a
crossover sample is made by label A alone, so comparing it with A would be true by
construction; what the claim needs is that A's coarse content *survives* the fine levels
run under B. The filter is a zero-phase Butterworth filter (:func:`lowpass`), steep
enough that the two bands barely overlap.

**Features and distances.** Per-frame features are the local joint rotations in 6D
(``mrlib.metrics.windows.metric_features(motion, contacts=False)``, ``D = 138``): the root's
global orientation and path are left out, as in every mrlib metric, and the binary
contact labels are left out of the band split (a low-pass of a 0/1 step is not
"coarse motion"). The low-pass band is compared by the nearest-neighbour distance of
each frame (or ``window``) to the reference frames, averaged
(``mrlib.metrics.windows.nearest_windows``), so a difference of timing or phase between the
sample and the reference does not count. The residual band is compared by its
per-channel RMS over time (a ``(D,)`` profile, timing-free by construction): a
per-frame nearest neighbour of two noise-like residuals measures their energies more
than their shape (whichever reference has the weaker residual is "nearest" to
everything), while the profile tells which joints carry how much fine detail. By
default both bands are compared with pure samples of A and of B from the same model
(see :func:`crossover_evidence`).

**Reading the evidence.** Only both halves together, on a model whose single-label
samples are faithful, count: the fine levels of a nearly untrained model already make
the residual whatever their weights are, so the residual alone can look "from B" by
chance. What the ``tutorial`` preset reaches on four Bandai walks, and what its
variants reach, is in ``docs/results.md`` (``python bench/condition_control.py``).

Dimension letters (``mrlib`` glossary): T frames, D feature channels, B samples,
N windows, L levels, K labels.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mrlib.errors import MotionValueError, check_count
from mrlib.metrics.bands import check_cutoff, check_split_level, rms_profile, split_bands
from mrlib.metrics.windows import metric_features, model_references, nearest_windows
from mrlib.sampling.conditions import Condition
from mrlib.sampling.sampler import Sampler, raw_sampler

__all__ = [
    "band_distances",
    "check_crossover_level",
    "crossover_cutoff",
    "crossover_conditions",
    "crossover_blend",
    "CrossoverEvidence",
    "CrossoverOptions",
    "crossover_evidence",
    "evidence_table",
]


def check_crossover_level(model: Any, level: int) -> int:
    """``level`` if it is a valid crossover level of ``model`` (``1..L-1``), else a
    ``MotionValueError`` saying why."""
    L = model.num_levels
    return check_split_level(level, L, "crossover level", f"levels 1..i coarse, i+1..{L} fine")


def crossover_cutoff(model: Any, level: int, length: int) -> float:
    """Nyquist frequency (Hz) of level ``level`` (1-based) for a clip of ``length``
    frames: ``fps_i / 2`` with ``fps_i = fps * T_i / T_L`` (``mrlib.model.pyramid.level_fps``)."""
    from mrlib.model.pyramid import level_fps, pyramid_lengths

    level = check_crossover_level(model, level)
    mc = model.config.model
    lengths = pyramid_lengths(
        int(length), mc.num_levels, mc.scale_factor, min_length=(mc.kernel_size - 1) // 2 + 1
    )
    return level_fps(model.fps, lengths)[level - 1] / 2


def crossover_conditions(
    model: Any, coarse_label: str | int, fine_label: str | int, level: int
) -> Condition:
    """``Condition.crossover(coarse_label, fine_label, level)`` (levels ``1..level``
    coarse, ``level+1..L`` fine) for ``generate``, its level and labels checked against
    ``model``."""
    level = check_crossover_level(model, level)
    model.label_index(coarse_label), model.label_index(fine_label)  # validate both
    return Condition.crossover(coarse_label, fine_label, level)


# ---------------------------------------------------------------------------------------
# Crossover evidence
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CrossoverEvidence:
    """Where a coarse-A / fine-B sample's two bands come from (A = ``coarse_label``).

    ``low_to_coarse`` / ``low_to_fine``: mean per-frame nearest-neighbour distance of
    the crossover samples' low-pass band to A's / B's references (module docstring);
    ``high_to_coarse`` / ``high_to_fine``: distance of their residual's RMS profile to
    A's / B's. ``per_sample (B, 4)`` holds the four numbers per sample, in field order.
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


def _nn_distance(x: np.ndarray, refs: Sequence[np.ndarray], window: int) -> float:
    """Mean over the windows of ``x (T, D)`` of the distance to the nearest window among
    ``refs`` (windows never straddle two references). For one reference this is
    ``mrlib.metrics.diversity.local_diversity(x, refs[0], window)``."""
    per_ref = [nearest_windows(x, r, window)[0] for r in refs]
    return float(np.min(per_ref, axis=0).mean())


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
    window = check_count("window", window)
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


@dataclass(frozen=True)
class CrossoverOptions:
    """How :func:`crossover_evidence` splits and compares the bands.

    Attributes:
        cutoff: low-pass half-power frequency in Hz; None: the Nyquist frequency of the
            crossover level (:func:`crossover_cutoff`).
        window: window of the low-band nearest-neighbour distance in frames (1: per frame).
        reference: what the bands are compared with: ``"samples"`` (pure-label samples
            of the model) or ``"clips"`` (its training clips).
        sampler: how the samples are drawn (a ``mrlib.Sampler``); None: the paper's
            sampler without the foot-contact clean-up (``raw_sampler()``: one draw, no clean-up).
    """

    cutoff: float | None = None
    window: int = 1
    reference: str = "samples"
    sampler: Sampler | None = None


def crossover_evidence(
    model: Any,
    coarse_label: str | int,
    fine_label: str | int,
    level: int,
    num_samples: int = 8,
    seed: int = 0,
    *,
    length: int | None = None,
    options: CrossoverOptions | None = None,
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

    The references are, with ``options.reference="samples"`` (default), ``num_samples`` pure-A
    and pure-B samples of the same length (seed ``seed + REFERENCE_SEED_OFFSET``, so no
    noise is shared with the crossover); with ``"clips"``, the training clips of A and
    B. Pure samples answer the question inside the model; training clips also measure
    how far the model is from the data, and their residual band carries far more energy
    than generated motion does, which then swamps the comparison.

    Args:
        model: a ``mrlib.sampling.generation.GenerativeModel``.
        coarse_label: label A (name or index); fine_label: label B.
        level: the crossover level ``i``, ``1 <= i <= L - 1``.
        num_samples: ``B`` samples of each kind (seeded; a sample does not depend on B).
        seed: noise seed of the crossover samples.
        length: frames per sample; default the longer of A's and B's first training clip.
        options: the cutoff, the low band's window and the references
            (:class:`CrossoverOptions`; its defaults when None).
    Returns:
        :class:`CrossoverEvidence`.
    """
    from mrlib.sampling.generation import generate

    opts = options or CrossoverOptions()
    sampler = raw_sampler(opts.sampler)
    cutoff, reference = opts.cutoff, opts.reference
    num_samples = check_count("num_samples", num_samples)
    window = check_count("window", opts.window)
    if reference not in ("samples", "clips"):
        raise MotionValueError(f"reference must be 'samples' or 'clips', got {reference!r}")
    conds = crossover_conditions(model, coarse_label, fine_label, level)
    a, b = model.label_index(coarse_label), model.label_index(fine_label)
    if a == b:
        raise MotionValueError("coarse and fine label are the same; nothing to compare")
    if length is None:
        length = max(int(model.lengths[model.clip_labels.index(k), -1]) for k in (a, b))
    length = check_count("length", length)
    if length < window:
        raise MotionValueError(f"length {length} is shorter than the window {window}")
    cutoff = crossover_cutoff(model, level, length) if cutoff is None else float(cutoff)
    check_cutoff(model.fps, cutoff)

    def samples(seed_: int, condition: Any) -> list[np.ndarray]:
        ms = generate(model, condition, length=length, seed=seed_, num=num_samples,
                      sampler=sampler)  # fmt: skip
        return [metric_features(m, contacts=False) for m in ms]

    if reference == "samples":
        refs = {k: samples(seed + REFERENCE_SEED_OFFSET, k) for k in (a, b)}
    else:
        _, clip_labels, feats = model_references(model, contacts=False)
        refs = {
            k: [f for f, lab in zip(feats, clip_labels, strict=True) if lab == model.labels[k]]
            for k in (a, b)
        }
    split = {k: _split_refs(refs[k], model.fps, cutoff, window) for k in (a, b)}
    rows, energy = [], []
    for x in samples(seed, conds):
        bands = split_bands(x, model.fps, cutoff)
        energy.append(np.linalg.norm(rms_profile(bands[1])))
        rows.append(_band_distances(bands, split[a], split[b], window))
    per = np.asarray(rows)  # (B, 4)
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


def crossover_blend(
    model: Any, coarse_label: str | int, fine_label: str | int, level: int, weight: float
) -> Condition:
    """``Condition.blend(coarse, fine, w)`` for ``generate``: weight 0 of the fine label
    at levels ``1..level`` and ``weight`` at ``level+1..L`` (1: a plain crossover, 0: pure
    coarse)."""
    level = check_crossover_level(model, level)
    if not (np.isfinite(weight) and 0.0 <= weight <= 1.0):
        raise MotionValueError(f"blend weight must be in [0, 1], got {weight}")
    L = model.num_levels
    return Condition.blend(coarse_label, fine_label, [0.0] * level + [float(weight)] * (L - level))
