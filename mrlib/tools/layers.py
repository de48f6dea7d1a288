"""The package graph of mrlib, and the check that its imports point one way.

``python -m mrlib.tools.layers`` prints every package (a folder under ``mrlib/``, or a
top-level module) with its layer and the packages it imports, then checks, counting
imports inside functions as well as those at the top of a module:

* every import of another mrlib package points to a lower layer (:data:`LAYERS`);
* no module imports another in a loop, within a package or across packages;
* the drawing libraries (:data:`DRAWING`) are imported only by ``mrlib.viz``, and
  imports inside functions of anything outside mrlib are only of the optional heavy
  dependencies named in :data:`OPTIONAL` (or of the standard library).

It reads the source (``ast``), imports nothing of mrlib, and exits with 1 on a
violation, listing each with its file and line. ``tests/test_api.py`` runs it.
"""

from __future__ import annotations

import argparse
import ast
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

__all__ = ["LAYERS", "OPTIONAL", "DRAWING", "Import", "imports", "check", "main"]

# Bottom up: a package may import from its own layer's package and any package below.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("errors", "threads", "progress", "claims"),  # errors, threads, progress bars, claims
    ("representation",),  # skeleton, rotations, Motion, SMPL body, features, contacts
    ("io",),  # files in and out
    ("datasets",),  # the Bandai Namco clips, synthetic clips
    ("metrics",),  # measures of motion: the paper's metrics, plausibility, bands
    ("model",),  # config and presets, pyramid, generator, critic, losses, checkpoints
    ("sampling",),  # conditions, generation, clean-up, restyle, constraints
    ("training",),  # the training set, the objective, the training loop
    ("evaluation",),
    ("speech",),
    ("viz",),  # the only package that draws
    ("app", "tools", "__main__"),  # command line and demo; checks of the package
)

# Third-party packages that may be imported inside functions, so that ``import mrlib``
# stays light and works without them (extras in pyproject.toml).
OPTIONAL = frozenset(
    {
        "matplotlib",
        "pyvista",
        "vtk",
        "imageio",
        "ipywidgets",
        "IPython",
        "trame",
        "trame_vtk",
        "soundfile",
        "transformers",
        "espeakng_loader",
        "pygltflib",
        "smplx",
        "pooch",
        "requests",
        "tqdm",
        "scipy",
        "platformdirs",  # through pooch
        "huggingface_hub",  # through transformers
        "traitlets",  # through ipywidgets
    }
)
DRAWING = frozenset({"matplotlib", "pyvista", "vtk", "ipywidgets", "IPython", "trame"})


@dataclass(frozen=True)
class Import:
    """One import statement's target, as seen in ``source`` (a dotted module name)."""

    source: str
    target: str  # dotted module name, resolved for relative imports
    line: int
    in_function: bool


def module_name(root: Path, path: Path) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _resolve(root: Path, source: str, is_pkg: bool, node: ast.ImportFrom) -> list[str]:
    if node.level:
        base = source.split(".")
        base = base[: len(base) - node.level + (1 if is_pkg else 0)]
        mod = ".".join(base + ([node.module] if node.module else []))
    else:
        mod = node.module or ""
    out = []
    for alias in node.names:  # `from mrlib.x import y`: y may be a submodule
        sub = f"{mod}.{alias.name}"
        rel = Path(*sub.split("."))
        if (root.parent / rel).with_suffix(".py").exists() or (root.parent / rel).is_dir():
            out.append(sub)
        else:
            out.append(mod)
    return out


def imports(root: Path) -> Iterator[Import]:
    """Every import in the package at ``root`` (module level and inside functions)."""
    for path in sorted(root.rglob("*.py")):
        source = module_name(root, path)
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        top = {id(n) for n in tree.body}
        # statements under `if TYPE_CHECKING:` / try at module level count as top level
        for n in tree.body:
            if isinstance(n, (ast.If, ast.Try)):
                top |= {id(c) for c in ast.walk(n)}
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                targets = _resolve(root, source, path.name == "__init__.py", node)
            else:
                continue
            for t in dict.fromkeys(targets):
                yield Import(source, t, node.lineno, id(node) not in top)


def package_of(module: str) -> str:
    """``mrlib.sampling.constraints.path`` -> ``sampling``; ``mrlib.errors`` -> ``errors``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def layer_of(package: str) -> int | None:
    for i, names in enumerate(LAYERS):
        if package in names:
            return i
    return None


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One cycle per strongly connected component with more than one node (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def strong(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(max(10_000, sys.getrecursionlimit()))
    for v in sorted(graph):
        if v not in index:
            strong(v)
    return out


def check(root: Path) -> tuple[dict[str, set[str]], list[str]]:
    """The package graph ``{package: packages it imports}`` and the violations found."""
    stdlib = set(sys.stdlib_module_names)
    all_imports = list(imports(root))
    modules = {module_name(root, p) for p in root.rglob("*.py")}
    packages: dict[str, set[str]] = {}
    module_graph: dict[str, set[str]] = {}
    problems = []
    for imp in all_imports:
        src_pkg = package_of(imp.source)
        where = f"{imp.source.replace('.', '/')}.py:{imp.line}"
        head = imp.target.split(".")[0]
        if head == "mrlib":
            tgt = imp.target
            while tgt not in modules and "." in tgt:
                tgt = tgt.rsplit(".", 1)[0]
            if tgt == "mrlib" or imp.source == "mrlib":
                continue  # the package's face hands names on; nothing imports it back
            if tgt != imp.source:
                # a package's __init__ runs on any import of its submodules: an import of
                # mrlib.a.b depends on mrlib.a too, except from inside mrlib.a itself
                module_graph.setdefault(imp.source, set()).add(tgt)
            tgt_pkg = package_of(tgt)
            packages.setdefault(src_pkg, set())
            if tgt_pkg and tgt_pkg != src_pkg:
                packages[src_pkg].add(tgt_pkg)
                ls, lt = layer_of(src_pkg), layer_of(tgt_pkg)
                if ls is None or lt is None:
                    problems.append(f"{where}: package {src_pkg or tgt_pkg!r} is in no layer")
                elif lt > ls:
                    problems.append(
                        f"{where}: {src_pkg} (layer {ls + 1}) imports {tgt} (layer {lt + 1})"
                        + (" inside a function" if imp.in_function else "")
                    )
        else:
            if head in DRAWING and src_pkg != "viz":
                problems.append(f"{where}: imports {head}; only mrlib.viz draws")
            if imp.in_function and head not in OPTIONAL and head not in stdlib:
                problems.append(
                    f"{where}: imports {head} inside a function; only the optional "
                    "dependencies in mrlib.tools.layers.OPTIONAL may be"
                )
    for cycle in _cycles(module_graph):
        problems.append("import cycle among modules: " + ", ".join(cycle))
    for cycle in _cycles(packages):
        problems.append("import cycle among packages: " + ", ".join(cycle))
    return packages, problems


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mrlib.tools.layers", description=__doc__)
    parser.add_argument(
        "--root", type=Path, default=Path(__file__).resolve().parents[1], help="package folder"
    )
    args = parser.parse_args(argv)
    graph, problems = check(args.root)
    print("layer  package         imports")
    for i, names in reversed(list(enumerate(LAYERS))):
        for name in names:
            deps = sorted(graph.get(name, ()), key=lambda p: (-(layer_of(p) or 0), p))
            print(f"{i + 1:>5}  {name:<15} {', '.join(deps) or '-'}")
    unknown = sorted(set(graph) - {n for names in LAYERS for n in names} - {""})
    for name in unknown:
        print(f"    ?  {name:<15} {', '.join(sorted(graph[name]))}")
    if problems:
        print(f"\n{len(problems)} problem(s):")
        for p in problems:
            print("  " + p)
        return 1
    print("\nno upward import, no cycle (imports inside functions included)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
