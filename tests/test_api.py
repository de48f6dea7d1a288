"""The public API: the package's names and the house rules of its layout."""

import ast
import importlib
from pathlib import Path

import mrlib

PACKAGE = Path(mrlib.__file__).parent


def _modules() -> dict[str, ast.Module]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        name = ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        out[name.removesuffix(".__init__")] = ast.parse(path.read_text())
    return out


def _imports(tree: ast.Module, name: str) -> list[tuple[str, list[str]]]:
    """``(module, [names])`` of every import in a module, relative ones resolved."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, []) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            out.append((node.module, [a.name for a in node.names]))
    return out


def test_every_public_name_resolves():
    for name in mrlib.__all__:
        assert getattr(mrlib, name) is not None, name


def test_the_public_api_is_small_and_each_subpackage_says_what_it_hands_on():
    assert len(mrlib.__all__) <= 21  # generate's two value types included: Condition, Sampler
    assert callable(mrlib.train) and callable(mrlib.restyle) and callable(mrlib.generate)
    for sub in ("representation", "metrics", "model", "training", "sampling", "evaluation"):
        pkg = importlib.import_module(f"mrlib.{sub}")
        assert pkg.__doc__ and pkg.__all__, sub
        assert all(getattr(pkg, n, None) is not None for n in pkg.__all__), sub


def test_no_private_name_is_imported_across_modules():
    for name, tree in _modules().items():
        for module, names in _imports(tree, name):
            if not module.startswith("mrlib"):
                continue
            private = [n for n in names if n.startswith("_") and not n.startswith("__")]
            assert not private, f"{name} imports private {private} from {module}"


def test_matplotlib_only_in_the_drawing_modules():
    allowed = {
        "mrlib.viz.plots",
        "mrlib.viz.control_plots",
        "mrlib.viz.render",
        "mrlib.viz.widgets",
        "mrlib.viz.widget_kit",
        "mrlib.viz.constraint_views",
    }
    for name, tree in _modules().items():
        uses = [m for m, _ in _imports(tree, name) if m.split(".")[0] == "matplotlib"]
        assert not uses or name in allowed, f"{name} imports matplotlib"


def test_imports_point_down_with_no_cycle():
    """``python -m mrlib.tools.layers``: every import (inside functions too) points to a
    lower layer, no module imports another in a loop, only mrlib.viz draws."""
    from mrlib.tools import layers

    graph, problems = layers.check(PACKAGE)
    assert not problems, "\n".join(problems)
    assert graph["representation"] <= {"errors"}
    assert "viz" not in set().union(*(deps for pkg, deps in graph.items() if pkg != "app"))


def test_the_layer_check_finds_an_upward_import_and_a_cycle(tmp_path):
    """The paired negative: a copy of two packages with an import pointing up inside a
    function, and two modules importing each other, is reported."""
    from mrlib.tools import layers

    root = tmp_path / "mrlib"
    (root / "representation").mkdir(parents=True)
    (root / "viz").mkdir()
    for d in (root, root / "representation", root / "viz"):
        (d / "__init__.py").write_text("")
    (root / "representation" / "a.py").write_text(
        "def f():\n    from mrlib.viz.p import g\n    return g\n"
    )
    (root / "viz" / "p.py").write_text("from mrlib.viz import q\n\ndef g():\n    pass\n")
    (root / "viz" / "q.py").write_text("from mrlib.viz import p\n")
    _, problems = layers.check(root)
    assert any("representation (layer 2) imports mrlib.viz.p" in p for p in problems)
    assert any("cycle among modules: mrlib.viz.p, mrlib.viz.q" in p for p in problems)


def test_no_module_is_over_500_lines():
    """A module a reader can hold: split along a seam rather than grow past 500 lines."""
    long = [
        f"{path.relative_to(PACKAGE)}: {n}"
        for path in sorted(PACKAGE.rglob("*.py"))
        if (n := len(path.read_text().splitlines())) > 500
    ]
    assert not long, long


def _parameter_counts() -> list[tuple[int, str]]:
    """Parameters of every function and method of mrlib (``self`` / ``cls`` aside)."""
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                a = node.args
                names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
                n = len(names) - (names[:1] in (["self"], ["cls"]))
                out.append((n, f"{path.relative_to(PACKAGE)}:{node.lineno} {node.name}"))
    return out


def test_few_functions_take_more_than_eight_parameters():
    """Knobs that travel together are one options value (``Sampler``, ``PlantOptions``,
    ``RetargetOptions``, ``EvaluationSettings``, ...), not eight more keywords."""
    many = sorted(row for row in _parameter_counts() if row[0] > 8)
    assert len(many) <= 8, many
    assert max(n for n, _ in _parameter_counts()) <= 10, many
