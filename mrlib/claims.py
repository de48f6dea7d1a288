"""Claims a notebook's prose makes, checked by the run that prints its outputs.

A notebook that says "condition fidelity stays above 90 %" follows the sentence with::

    from mrlib.claims import check
    check("condition fidelity stays above 90 %", fid.overall > 0.9, shows=f"{fid.overall:.1%}")

which prints one line (``✓ condition fidelity stays above 90 %: 98.6 %``) when the claim
holds, and raises :class:`ClaimFailed` (failing the notebook, under ``make notebooks`` and
under ``make test``'s nbmake run alike) when it does not. So a committed notebook cannot
carry a sentence its own outputs refute: when a new budget, dataset or change of code
breaks a claim, the run stops at the claim, and the sentence changes (not the threshold).

Most claims are about a *trained* model and hold only at the budget a notebook is meant to
run at. ``make test`` runs the notebooks with ``MRLIB_QUICK=1`` (a few iterations: the
plumbing only), where such a check prints that it was not checked, and why. Claims that
hold at any budget (shapes, definitions, calibration motions, counts) pass ``quick=True``
and are checked there too.

``tools/notebook_claims.py`` lists every ``check`` of every notebook in
``docs/notebook-claims.md``.
"""

from __future__ import annotations

import os
from collections.abc import Callable

__all__ = ["check", "ClaimFailed", "quick_budget"]


class ClaimFailed(AssertionError):
    """A claim of a notebook's prose that its own run refutes."""


def quick_budget() -> bool:
    """Whether this run is the smoke-test budget of ``make test`` (``MRLIB_QUICK=1``)."""
    return os.environ.get("MRLIB_QUICK") == "1"


def check(
    claim: str,
    holds: bool | Callable[[], bool],
    *,
    shows: str = "",
    quick: bool = False,
) -> None:
    """Assert one claim of the prose and print it with the figure that supports it.

    ``claim`` is the sentence (or its gist) as the prose says it; ``holds`` whether the run
    bears it out (a bool, or a function returning one, evaluated only when checked);
    ``shows`` the measured figure printed beside it. With ``quick=False`` (the default) the
    claim is about what the notebook's budget trains, and under ``MRLIB_QUICK=1`` it is
    reported as not checked. Returns nothing (a check is a notebook cell's last line,
    and leaves no ``True`` behind); raises :class:`ClaimFailed` when checked and refuted.
    """
    if not isinstance(claim, str) or not claim.strip():
        raise TypeError("check(claim, holds): claim must be the sentence being checked")
    tail = f": {shows}" if shows else ""
    if not quick and quick_budget():
        print(f"- not checked at the quick budget (MRLIB_QUICK=1): {claim}{tail}", flush=True)
        return
    ok = holds() if callable(holds) else holds
    if not isinstance(ok, bool):
        try:  # numpy / torch booleans
            ok = bool(ok.item()) if hasattr(ok, "item") else ok
        except (TypeError, ValueError):
            pass
    if not isinstance(ok, bool):
        raise TypeError(f"check({claim!r}): holds must be a bool, got {type(ok).__name__}")
    if not ok:
        raise ClaimFailed(f"the run refutes a claim of the text: {claim}{tail}")
    print(f"✓ {claim}{tail}", flush=True)
