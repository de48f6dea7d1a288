"""The public API: the package's names, the house rules of its layout, and the names
that moved (they still resolve, with a DeprecationWarning)."""

import ast
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


def test_no_private_name_is_imported_across_modules():
    for name, tree in _modules().items():
        for module, names in _imports(tree, name):
            if not module.startswith("mrlib"):
                continue
            private = [n for n in names if n.startswith("_") and not n.startswith("__")]
            assert not private, f"{name} imports private {private} from {module}"


def test_matplotlib_only_in_the_drawing_modules():
    allowed = {"mrlib.viz.plots", "mrlib.viz.render", "mrlib.viz.widgets"}
    for name, tree in _modules().items():
        uses = [m for m, _ in _imports(tree, name) if m.split(".")[0] == "matplotlib"]
        assert not uses or name in allowed, f"{name} imports matplotlib"


def test_top_level_imports_form_no_cycle():
    """Module-level imports between mrlib modules point one way (imports inside
    functions, made at call time, are not counted)."""
    mods = _modules()
    graph = {}
    for name, tree in mods.items():
        deps = set()
        for node in tree.body:
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("mrlib"):
                for a in node.names:
                    full = f"{node.module}.{a.name}"
                    deps.add(full if full in mods else node.module)
            elif isinstance(node, ast.Import):
                deps |= {a.name for a in node.names if a.name in mods}
        graph[name] = {d for d in deps if d in mods and d != name}
    # a package's __init__ re-exports its submodules: only edges into a package count
    state: dict[str, int] = {}

    def visit(n: str, path: list[str]) -> None:
        state[n] = 1
        for d in graph[n]:
            if d.startswith(n + "."):
                continue  # a package importing its own submodules
            if state.get(d) == 1:
                raise AssertionError("import cycle: " + " -> ".join(path + [n, d]))
            if state.get(d) is None:
                visit(d, path + [n])
        state[n] = 2

    for n in graph:
        if n not in state:
            visit(n, [])


def test_long_modules_say_why():
    """A module over 650 lines states at its top why it is long."""
    for path in sorted(PACKAGE.rglob("*.py")):
        text = path.read_text()
        if len(text.splitlines()) > 650:
            doc = ast.get_docstring(ast.parse(text)) or ""
            assert " long" in doc, f"{path.name}: {len(text.splitlines())} lines, no reason given"
