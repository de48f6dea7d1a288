"""docs/architecture.md against the tree: every module and name it gives exists, each part
of the paper it lists is found in one place, and its equation numbers are the paper's."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "architecture.md"
PAPER = ROOT.parent / "shared" / "paper"


def _definitions() -> dict[str, dict[str, ast.AST]]:
    """Top-level classes, functions and assignments of every mrlib module, by module file."""
    out = {}
    for path in sorted((ROOT / "mrlib").rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        names: dict[str, ast.AST] = {}
        for node in tree.body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                names[node.name] = node
            elif isinstance(node, (ast.Assign, ast.AnnAssign)):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                for t in targets:
                    if isinstance(t, ast.Name):
                        names[t.id] = node
        out[path.relative_to(ROOT).as_posix()] = names
    return out


DEFS = _definitions()


def _module_file(dotted: str) -> str | None:
    """``model.generator`` / ``mrlib.model.generator`` -> its file, if it exists."""
    parts = dotted.removeprefix("mrlib.").split(".")
    for candidate in (
        "mrlib/" + "/".join(parts) + ".py",
        "mrlib/" + "/".join(parts) + "/__init__.py",
    ):
        if candidate in DEFS:
            return candidate
    return None


def _resolves(dotted: str) -> bool:
    """A module, or a module's top-level name, or a class's method, of mrlib."""
    parts = dotted.removeprefix("mrlib.").split(".")
    for cut in range(len(parts), 0, -1):
        f = _module_file(".".join(parts[:cut]))
        if f is None:
            continue
        rest = parts[cut:]
        if not rest:
            return True
        node = DEFS[f].get(rest[0])
        if node is None:
            return False
        if len(rest) == 1:
            return True
        if isinstance(node, ast.ClassDef) and len(rest) == 2:
            return any(getattr(n, "name", None) == rest[1] for n in node.body)
        return False
    return False


PACKAGES = sorted(
    p.name for p in (ROOT / "mrlib").iterdir() if p.is_dir() and (p / "__init__.py").exists()
) + [p.stem for p in (ROOT / "mrlib").glob("*.py") if p.stem != "__init__"]


def _named_in_doc() -> list[str]:
    """Backticked dotted names that start with an mrlib package, and file paths."""
    text = DOC.read_text(encoding="utf-8")
    out = []
    for token in re.findall(r"`([^`\s]+)`", text):
        token = token.rstrip("()")
        if token.endswith(".py") or token.endswith("/"):
            out.append(token)
            continue
        head = token.removeprefix("mrlib.").split(".")[0]
        if "." in token and head in PACKAGES and re.fullmatch(r"[\w.]+", token):
            out.append(token)
    return out


def test_every_module_and_name_the_floor_plan_gives_exists():
    named = _named_in_doc()
    assert len(named) > 40, named  # the plan names the tree, not a handful of things
    missing = []
    for token in named:
        if token.endswith(".py") or token.endswith("/"):
            path = ROOT / (token if token.startswith("mrlib/") else f"mrlib/{token}")
            ok = path.exists() or (ROOT / token).exists()
        else:
            ok = _resolves(token)
        if not ok:
            missing.append(token)
    assert not missing, f"docs/architecture.md names what the tree does not have: {missing}"


def _lookups() -> list[tuple[str, str, str]]:
    """Rows ``| what | `file` | `name` |`` of the "Find the paper in the tree" table."""
    text = DOC.read_text(encoding="utf-8")
    section = text.split("## Find the paper in the tree", 1)[1].split("\n## ", 1)[0]
    rows = []
    for line in section.splitlines():
        m = re.match(r"\|\s*([^|`]+?)\s*\|\s*`([^`]+)`\s*\|\s*`([^`]+)`", line)
        if m:
            rows.append((m[1], m[2], m[3]))
    return rows


def test_each_part_of_the_paper_is_found_in_one_guess():
    rows = _lookups()
    wanted = {"generator at level i", "the loss", "crossover", "coverage"}
    assert wanted <= {r[0].split(" (")[0].split(",")[0] for r in rows}, rows
    for what, file, name in rows:
        assert file in DEFS, f"{what}: {file} does not exist"
        top = name.split(".")[0]
        assert top in DEFS[file], f"{what}: {file} does not define {top}"
        assert _resolves(file.removesuffix(".py").replace("/", ".") + "." + name), name
        # one guess: no other module defines the same name
        others = [f for f, names in DEFS.items() if f != file and top in names]
        assert not others, f"{what}: {top} is also defined in {others}"


def _equation_numbers(tex: str) -> dict[str, int]:
    """``{label: number}`` of the LaTeX source: one number per ``equation``, one per line
    of an ``align`` (``\\\\`` separated), none for ``\\nonumber`` / ``\\notag`` or starred
    environments."""
    numbers, n = {}, 0
    for m in re.finditer(r"\\begin\{(equation|align)\}(.*?)\\end\{\1\}", tex, re.S):
        lines = [m[2]] if m[1] == "equation" else m[2].split("\\\\")
        for line in lines:
            if "\\nonumber" in line or "\\notag" in line:
                continue
            n += 1
            for label in re.findall(r"\\label\{([^}]+)\}", line):
                numbers[label] = n
    return numbers


def test_equation_numbers_are_the_papers():
    sources = sorted(PAPER.glob("*")) if PAPER.exists() else []
    if not sources:
        pytest.skip("the paper's LaTeX (../shared/paper) is not beside this checkout")
    tex = "\n".join(p.read_text(encoding="utf-8", errors="replace") for p in sources)
    eq = _equation_numbers(tex)
    loss, wgan, rec = eq["eq:loss"], eq["eq:wgan"], eq["eq:recloss"]
    doc = DOC.read_text(encoding="utf-8")
    assert f"Eq. {loss}" in doc and f"Eq. {wgan}" in doc and f"Eq. {rec}" in doc
    objective = (ROOT / "mrlib" / "training" / "objective.py").read_text(encoding="utf-8")
    assert f"Eq. {loss}" in objective and f"Eq. {rec}" in objective
    # no stale number for the loss anywhere in the library
    for path in (ROOT / "mrlib").rglob("*.py"):
        text = path.read_text(encoding="utf-8")
        assert not re.search(r"Eq\. 6\b[^-]*\b(loss|objective|sum)", text), path
