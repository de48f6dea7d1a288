"""The notebooks' claims are checks: ``mrlib.claims.check`` passes what holds and fails
what does not, every notebook checks its prose, the generated list of claims
(``docs/notebook-claims.md``) is current, no figure of the prose goes unprinted and
unexplained, and a planted false claim fails its notebook."""

from __future__ import annotations

import ast
import json
import os
import sys
from pathlib import Path

import pytest

from mrlib.claims import ClaimFailed, check

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))
sys.path.insert(0, str(ROOT / "tools"))
import notebook_claims  # noqa: E402


def test_check_prints_what_holds_and_raises_on_what_does_not(capsys, monkeypatch):
    monkeypatch.delenv("MRLIB_QUICK", raising=False)
    check("two is more than one", 2 > 1, shows="2 > 1")
    assert "✓ two is more than one: 2 > 1" in capsys.readouterr().out
    with pytest.raises(ClaimFailed, match="one is more than two"):
        check("one is more than two", 1 > 2)
    import numpy as np

    check("numpy booleans count", np.float64(3.0) > 1)
    with pytest.raises(TypeError):
        check("a number is not a verdict", 3.0)
    with pytest.raises(TypeError):
        check("", True)


def test_check_of_a_trained_model_waits_for_the_full_budget(capsys, monkeypatch):
    monkeypatch.setenv("MRLIB_QUICK", "1")
    called = []
    check("the model learned", lambda: called.append(1) or False)
    assert not called  # not even evaluated
    assert "not checked at the quick budget" in capsys.readouterr().out
    with pytest.raises(ClaimFailed):
        check("a definition holds at any budget", False, quick=True)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name[:2])
def test_every_notebook_checks_its_claims(path):
    found = notebook_claims.claims(path)
    assert len(found) >= 3, f"{path.name}: {len(found)} checked claims"
    assert any(c.quick for c in found), f"{path.name}: nothing checked at make test's budget"


def test_the_list_of_claims_is_current_and_every_figure_is_printed_or_explained(capsys):
    code = notebook_claims.main(["--check"])
    assert code == 0, capsys.readouterr().out


def test_the_number_checker_sees_an_unprinted_figure(tmp_path):
    nb = {
        "cells": [
            {
                "cell_type": "markdown",
                "metadata": {},
                "source": "Coverage is 97.5 % and 12 of 14 hold (Eq. 17).",
            },
            {
                "cell_type": "code",
                "metadata": {},
                "source": "print(97.5)",
                "outputs": [{"output_type": "stream", "name": "stdout", "text": "97.5\n"}],
            },
        ],
        "metadata": {},
    }
    path = tmp_path / "99_x.ipynb"
    path.write_text(json.dumps(nb))
    assert sorted(n.number for n in notebook_claims.numbers(path)) == ["12", "14"]
    nb["cells"][0]["metadata"] = {"mrlib": {"numbers": {"12": "a citation", "14": "a citation"}}}
    path.write_text(json.dumps(nb))
    assert all(n.why for n in notebook_claims.numbers(path))


def _offset(lines: list[str], line: int, col: int) -> int:
    """The character offset of an ast position (its column counts UTF-8 bytes)."""
    return sum(len(x) for x in lines[: line - 1]) + len(lines[line - 1].encode()[:col].decode())


def _plant(source: str) -> str | None:
    """The cell's source with its first quick ``check``'s verdict negated, or None."""
    tree = ast.parse(notebook_claims._python(source))
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Call)
            and getattr(node.func, "id", None) == "check"
            and len(node.args) > 1
        ):
            if any(k.arg == "quick" and getattr(k.value, "value", False) for k in node.keywords):
                holds = node.args[1]
                lines = source.splitlines(keepends=True)
                start = _offset(lines, holds.lineno, holds.col_offset)
                end = _offset(lines, holds.end_lineno, holds.end_col_offset)
                return source[:start] + f"not ({source[start:end]})" + source[end:]
    return None


def test_a_planted_false_claim_fails_its_notebook():
    """Notebook 01 with one claim's verdict turned around stops at that claim."""
    import nbformat
    from nbclient import NotebookClient
    from nbclient.exceptions import CellExecutionError

    nb = nbformat.read(NOTEBOOKS[0], as_version=4)
    planted = None
    for i, cell in enumerate(nb.cells):
        if cell.cell_type == "code" and (new := _plant(cell.source)) is not None:
            cell.source, planted = new, i
            break
    assert planted is not None, "notebook 01 has no quick check to plant a false claim in"
    nb.cells = nb.cells[: planted + 1]  # nothing after the claim needs to run
    env = {"MRLIB_QUICK": "1", "MRLIB_PROGRESS": "off"}
    old = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    try:
        client = NotebookClient(
            nb,
            timeout=600,
            kernel_name="python3",
            resources={"metadata": {"path": str(NOTEBOOKS[0].parent)}},
        )
        with pytest.raises(CellExecutionError, match="ClaimFailed"):
            client.execute()
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
