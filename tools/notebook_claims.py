"""The claims of the notebooks, and the numbers of their prose that no output prints.

    python tools/notebook_claims.py            # write docs/notebook-claims.md
    python tools/notebook_claims.py --check    # exit 1 when that file is stale or a number
                                               # of the prose is neither printed nor explained

A *claim* is a ``check("...", ...)`` call of a code cell (``mrlib.claims.check``): the
generated list gives each one with its notebook, cell and budget. A *number of the prose*
is a figure in a markdown cell (inline code, LaTeX, links and references such as "Eq. 11",
"Sec. 4.3", "Table 1", "notebook 02" or "level 3" left out). It must appear among the same
notebook's outputs or in its code (a parameter the reader sees), or the markdown cell's
metadata must say why it is there: ``{"mrlib": {"numbers": {"24": "SMPL's joint count"}}}``.
"""

from __future__ import annotations

import argparse
import ast
import json
import re
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = ROOT / "notebooks"
DOC = ROOT / "docs" / "notebook-claims.md"

_NUMBER = re.compile(r"(?<![\w.\-/])[-−]?\d+(?:[.,]\d+)*")
_SKIP = [
    re.compile(r"`[^`]*`"),  # inline code: names and parameters
    re.compile(r"\$\$.*?\$\$|\$[^$]*\$", re.S),  # LaTeX
    re.compile(r"\]\([^)]*\)"),  # link targets
    re.compile(r"<[^>]+>"),  # html tags
    re.compile(
        r"\b(?:Eqs?\.|Equations?|Sec\.|Secs\.|Section|section|Sections|sections|Table|Tables|"
        r"Fig\.|Figs\.|Figure|notebooks?|cells?|levels?|block|blocks|panel|row|step|"
        r"Algorithm|Appendix|CC BY(?:-NC)?|SMPL(?:-X)?|Dataset|dataset-|H\d+)\s*"
        r"\d+(?:\.\d+)*(?:\s*(?:[-–,]|and|to|\.\.)\s*\d+(?:\.\d+)*)*"
    ),
    re.compile(r"^#+\s*\d+\.", re.M),  # "## 5. Title"
    re.compile(r"\b\d+D\b"),  # 3D, 6D
    re.compile(r"\b[A-Za-z]+\d+\w*"),  # identifiers: beat2, walk_sad_002, fp16
]


@dataclass(frozen=True)
class Claim:
    notebook: str
    cell: int
    text: str
    quick: bool


@dataclass(frozen=True)
class Number:
    notebook: str
    cell: int
    number: str
    context: str
    why: str | None


def _source(cell: dict) -> str:
    src = cell.get("source", "")
    return src if isinstance(src, str) else "".join(src)


def _python(src: str) -> str:
    """A code cell's source with IPython magics and shell lines commented out."""
    return "\n".join(
        "# " + ln if ln.lstrip().startswith(("%", "!")) else ln for ln in src.splitlines()
    )


def claims(path: Path) -> list[Claim]:
    """Every ``check(...)`` of the notebook's code cells, in order."""
    nb = json.loads(path.read_text(encoding="utf-8"))
    out = []
    for i, cell in enumerate(nb["cells"]):
        if cell["cell_type"] != "code":
            continue
        for node in ast.walk(ast.parse(_python(_source(cell)))):
            if not (
                isinstance(node, ast.Call)
                and getattr(node.func, "id", getattr(node.func, "attr", None)) == "check"
            ):
                continue
            text = node.args[0] if node.args else None
            if isinstance(text, ast.Constant) and isinstance(text.value, str):
                said = text.value
            elif isinstance(text, ast.JoinedStr):
                said = ast.unparse(text)[2:-1]
            else:
                said = ast.unparse(text) if text is not None else "?"
            quick = any(
                k.arg == "quick" and isinstance(k.value, ast.Constant) and k.value.value
                for k in node.keywords
            )
            out.append(Claim(path.name, i, " ".join(said.split()), quick))
    return out


def _outputs_text(nb: dict) -> str:
    parts = []
    for cell in nb["cells"]:
        if cell["cell_type"] != "code":
            continue
        parts.append(_source(cell))
        for o in cell.get("outputs", []):
            if "text" in o:
                parts.append(o["text"] if isinstance(o["text"], str) else "".join(o["text"]))
            for kind in ("text/plain", "text/markdown", "text/html"):
                t = o.get("data", {}).get(kind)
                if t:
                    parts.append(t if isinstance(t, str) else "".join(t))
    return "\n".join(parts)


def _forms(number: str) -> set[str]:
    """The ways an output may print a figure of the prose: 1,200 as 1200; 0.50 as 0.5."""
    n = number.replace("−", "-").replace(",", "")
    forms = {number, n}
    try:
        v = float(n)
    except ValueError:
        return forms
    forms |= {f"{v:g}", f"{v:.1f}", f"{v:.2f}", f"{v:.3f}", f"{v:.0f}"} if "." in n else {f"{v:g}"}
    return forms


def numbers(path: Path) -> list[Number]:
    """Figures of the notebook's markdown, with why each is there when no output or code
    of the notebook prints it (``why=None``: unexplained)."""
    nb = json.loads(path.read_text(encoding="utf-8"))
    printed = set(_NUMBER.findall(_outputs_text(nb).replace("−", "-")))
    printed |= {f.replace(",", "") for f in printed}
    out = []
    for i, cell in enumerate(nb["cells"]):
        if cell["cell_type"] != "markdown":
            continue
        text = _source(cell)
        for pat in _SKIP:
            text = pat.sub(" ", text)
        explained = cell.get("metadata", {}).get("mrlib", {}).get("numbers", {})
        for m in _NUMBER.finditer(text):
            num = m.group().replace("−", "-")
            if _forms(num) & printed:
                continue
            ctx = " ".join(text[max(0, m.start() - 40) : m.end() + 40].split())
            out.append(Number(path.name, i, num, ctx, explained.get(num)))
    return out


def render(paths: list[Path]) -> str:
    lines = [
        "# Notebook claims",
        "",
        "Generated by `python tools/notebook_claims.py` from the notebooks' `check(...)` cells",
        "(`mrlib.claims.check`): each claim of a notebook's prose, the cell that checks it, and",
        "whether `make test`'s quick budget (`MRLIB_QUICK=1`) checks it too (the rest hold only for",
        "a model trained at the notebook's own budget, and are checked by `make notebooks`). A claim",
        "that stops holding fails its notebook. Cells are counted from 0, as in the `.ipynb` file.",
        "",
    ]
    for path in paths:
        found = claims(path)
        lines += [f"## {path.name}", "", "| cell | claim | quick budget |", "|---|---|---|"]
        lines += [
            f"| {c.cell} | {c.text.replace('|', '/')} | {'checked' if c.quick else 'not checked'} |"
            for c in found
        ]
        lines.append("")
        told = [n for n in numbers(path) if n.why]
        if told:
            lines += ["Figures of the prose that no output prints, and why:", ""]
            lines += [f"- cell {n.cell}: {n.number}: {n.why}" for n in told]
            lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--check", action="store_true", help="fail when the list is stale or a number unexplained"
    )
    args = ap.parse_args(argv)
    paths = sorted(NOTEBOOKS.glob("[0-9][0-9]_*.ipynb"))
    bad = [n for p in paths for n in numbers(p) if not n.why]
    for n in bad:
        print(f"{n.notebook} cell {n.cell}: {n.number} is printed by no output: ...{n.context}...")
    text = render(paths)
    if args.check:
        stale = not DOC.exists() or DOC.read_text(encoding="utf-8") != text
        if stale:
            print(f"{DOC.relative_to(ROOT)} is stale: run python tools/notebook_claims.py")
        return 1 if stale or bad else 0
    DOC.write_text(text, encoding="utf-8")
    print(f"wrote {DOC.relative_to(ROOT)}: {sum(len(claims(p)) for p in paths)} claims")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
