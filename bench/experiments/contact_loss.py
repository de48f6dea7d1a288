"""``bench/heldout.py`` with the contact consistency term kept off the contact labels
(docs/notes/2026-12-07-contact-rate.md, "Where the labels are pushed down").

    python bench/experiments/contact_loss.py --seeds 1
    python bench/experiments/contact_loss.py --split dev --seeds 0,1

The paper's term (Eq. 14, ``mrlib.model.losses.contact_consistency_loss``) is
``|v|^2 sig(c)``: its gradient moves both the foot (slower where labelled in contact) and
the label (lower where the foot moves). Here the label is detached in that term, so the
term plants feet and the labels learn from the critics and the reconstruction only. Every
argument is ``bench/heldout.py``'s; the models are trained into
``outputs/contact_loss/models`` (the config is the preset's, so mrlib's model cache would
hand back the models of the paper's term).
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))  # bench/: heldout.py, common.py


def main(argv=None) -> int:
    import mrlib.training.objective as objective
    import mrlib.training.trainer as trainer

    runs = ROOT / "outputs" / "contact_loss" / "models"
    trainer.models_root = lambda cache_dir=None: runs  # not mrlib's model cache

    paper = objective.contact_consistency_loss

    def label_detached(foot_velocity, contacts, weights):
        return paper(foot_velocity, contacts.detach(), weights)

    objective.contact_consistency_loss = label_detached
    import heldout

    print("contact consistency term: labels detached (feet only)", flush=True)
    return heldout.main(argv)


if __name__ == "__main__":
    raise SystemExit(main())
