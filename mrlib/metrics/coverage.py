"""Coverage, the paper's Eq. (17)-(18) (Section "Evaluation and Discussion", after
GANimator): the share of a training clip's windows of ``T_c`` frames whose nearest
window in a generated clip is closer than a threshold ``eps``, averaged over generated
clips; and condition fidelity, the same nearest-window search over the training clips
of every label.

Eq. (17): ``Cov(G(z), X) = 1/|W(X, T_c)| sum_{w in W(X, T_c)} [NN(w, G(z)) < eps]``,
``W(X, T_c)`` the windows of ``T_c`` frames of the training clip ``X`` and ``NN`` the
distance to the nearest window of the generated clip. Eq. (18): ``Cov(G, X) = E_z
Cov(G(z), X)``, the mean over generated clips. The paper measures distances with the
Frobenius norm of the local joint rotation matrices (``metric_features(kind="rotmat")``);
mrlib's default features, distances and windows are described in
``mrlib.metrics.windows``. ``T_c = 30``, ``eps = 2.0`` (GANimator's).

Dimension letters (``mrlib`` glossary): T frames, D feature channels, N windows.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from mrlib.errors import MotionValueError
from mrlib.metrics.windows import (
    as_features,
    as_sample_list,
    check_positive_int,
    check_windows,
    window_nn,
    windowed_pair,
)
from mrlib.representation.motion import Motion

__all__ = ["coverage", "coverage_profile", "condition_fidelity"]


def coverage_profile(
    generated: Any, reference: Any, window: int = 30, squared: bool = False
) -> np.ndarray:
    """Nearest-neighbour distance of every reference window in one generated clip: the
    ``NN(w, G(z))`` of Eq. (17).

    Args:
        generated: ``(T_g, D)`` features (or ``Motion``) of one generated clip.
        reference: ``(T_r, D)`` features of the training clip.
        window: window length in frames (the paper's ``T_c = 30``).

    Returns:
        ``(T_r - window + 1,)``: for each reference window (by first frame), the mean
        per-frame distance to the closest ``window``-frame window of ``generated``.
    """
    w, g, r = windowed_pair(generated, reference, window)
    return window_nn(r, g, w, squared)[0]


def coverage(
    generated: Any,
    reference: Any,
    window: int = 30,
    eps: float | Sequence[float] = 2.0,
    squared: bool = False,
) -> float | dict[float, float]:
    """Share of reference windows whose nearest generated window is closer than ``eps``
    (Eq. 17), the mean over generated clips (Eq. 18).

    Args:
        generated: one generated clip ``(T_g, D)`` or a list (any iterable) of clips;
            for a list the result is the mean over clips (the paper's ``E_z``).
        reference: ``(T_r, D)`` features of the training clip.
        window: window length ``T_c`` in frames (30 in the paper and GANimator).
        eps: coverage threshold on the mean per-frame distance (GANimator: 2.0), or
            several thresholds (the nearest-window distances are computed once for all).

    Returns:
        coverage in [0, 1]; for several thresholds, threshold -> coverage.
    """
    many = not isinstance(eps, (int, float, np.floating, np.integer))
    for e in eps if many else [eps]:
        if not (np.isfinite(e) and e > 0):
            raise MotionValueError(f"eps must be a positive number, got {e}")
    epss = [float(e) for e in (eps if many else [eps])]
    samples, _ = as_sample_list(generated)
    values: dict[float, list[float]] = {e: [] for e in epss}
    for g in samples:
        prof = coverage_profile(g, reference, window, squared)
        for e in epss:
            values[e].append(float((prof < e).mean()))
    if not any(values.values()):
        raise MotionValueError("coverage: no generated samples")
    out = {e: float(np.mean(v)) for e, v in values.items()}
    return out if many else out[epss[0]]


def condition_fidelity(
    generated_with_labels: Iterable[Any],
    references: Mapping[str, Any],
    window: int = 30,
    squared: bool = False,
) -> float:
    """Share of generated windows whose nearest training window belongs to the requested label.

    Args:
        generated_with_labels: ``(features (T_g, D), label)`` pairs, or ``Motion``
            objects with ``.label`` set.
        references: label -> ``(T_label, D)`` features of that label's training clip.
            Windows never straddle two training clips.
        window: window length in frames.

    Returns:
        share in [0, 1], pooled over all windows of all generated clips.
    """
    w = check_positive_int("window", window)
    if not references:
        raise MotionValueError("condition_fidelity: references is empty")
    labels = list(references)
    refs = [as_features(references[k], f"references[{k!r}]") for k in labels]
    check_windows(w, {f"references[{k!r}]": x for k, x in zip(labels, refs, strict=True)})
    hits, total = 0, 0
    for item in generated_with_labels:
        if isinstance(item, Motion):
            feats, label = item, item.label
        else:
            feats, label = item
        if label not in references:
            raise MotionValueError(f"condition_fidelity: label {label!r} has no reference clip")
        g = as_features(feats, f"generated ({label})")
        check_windows(w, {f"generated ({label})": g})
        nn = []
        for name, x in zip(labels, refs, strict=True):
            if x.shape[1] != g.shape[1]:
                raise MotionValueError(
                    f"generated has {g.shape[1]} channels but references[{name!r}] has {x.shape[1]}"
                )
            mu = x.mean(0)
            nn.append(window_nn(g - mu, x - mu, w, squared)[0])
        winner = np.argmin(np.stack(nn), axis=0)  # (N,) label index per window
        hits += int((winner == labels.index(label)).sum())
        total += len(winner)
    if total == 0:
        raise MotionValueError("condition_fidelity: no generated samples")
    return hits / total
