"""The committed notebooks carry the outputs of their current code (so a reader on GitHub
sees every figure without running), within the size we commit, and open as the kernel
``make env`` installs. ``make notebooks`` (``tools/run_notebooks.py``) produces them;
``make test`` also executes every notebook afresh under nbmake."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))
sys.path.insert(0, str(ROOT / "tools"))
from run_notebooks import MAX_BYTES, code_hash  # noqa: E402


def test_there_are_six_lessons():
    assert [p.name[:2] for p in NOTEBOOKS] == ["01", "02", "03", "04", "05", "06"]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name[:2])
def test_committed_outputs_come_from_the_committed_code(path):
    nb = json.loads(path.read_text())
    meta = nb["metadata"].get("mrlib", {})
    assert meta.get("source_sha256") == code_hash(nb), (
        f"{path.name}: its code changed since its outputs were made; run `make notebooks`"
    )
    code = [c for c in nb["cells"] if c["cell_type"] == "code"]
    assert all(c.get("execution_count") for c in code), f"{path.name}: a cell did not run"
    images = [o for c in code for o in c.get("outputs", []) if "image/png" in o.get("data", {})]
    assert images, f"{path.name}: no figure among its outputs"
    errors = [o for c in code for o in c.get("outputs", []) if o.get("output_type") == "error"]
    assert not errors, f"{path.name}: committed with an error output"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name[:2])
def test_committed_notebooks_stay_small(path):
    assert path.stat().st_size <= MAX_BYTES


def test_code_hash_sees_code_edits_and_ignores_markdown():
    nb = {
        "cells": [
            {"cell_type": "markdown", "source": ["# title"]},
            {"cell_type": "code", "source": ["x = 1\n", "print(x)"]},
        ]
    }
    h = code_hash(nb)
    nb["cells"][0]["source"] = ["# another title"]
    assert code_hash(nb) == h
    nb["cells"][1]["source"] = ["x = 2\n", "print(x)"]
    assert code_hash(nb) != h
