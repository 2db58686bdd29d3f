"""The layout is the architecture: imports only go down, and there are no circles.

softras's layers, bottom to top (docs/architecture.md):

    softras.scene  <-  softras.pipeline  <-  softras.kernels  <-  softras.renderer
                   <-  softras.verification  <-  softras.cli, softras.bench, softras (the package)

and glref, beside them, builds on softras.scene alone.  A module may import
its own layer and the ones below it.  Every import statement counts, the
ones inside functions too (a lazy import is still a dependency).  The test
reads the sources with `ast`; it imports nothing of softras.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("softras", "glref")

# layer -> the layers its modules may import
ALLOWED = {
    "scene": {"scene"},
    "pipeline": {"scene", "pipeline"},
    "kernels": {"scene", "pipeline", "kernels"},
    "renderer": {"scene", "pipeline", "kernels", "renderer", "glref"},
    "verification": {"scene", "pipeline", "kernels", "renderer", "glref", "verification"},
    "top": {"scene", "pipeline", "kernels", "renderer", "glref", "verification", "top"},
    "glref": {"scene", "glref"},
}


def layer(module: str) -> str:
    """The layer of a dotted module name of softras or glref."""
    parts = module.split(".")
    if parts[0] == "glref":
        return "glref"
    if len(parts) > 1 and parts[1] in ("scene", "pipeline", "kernels", "renderer", "verification"):
        return parts[1]
    return "top"            # softras itself, softras.cli, softras.bench, softras.__main__


def modules(root: Path = ROOT) -> dict[str, Path]:
    """Dotted module name -> source file, for every module of softras and glref."""
    found = {}
    for package in PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            parts = list(path.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            found[".".join(parts)] = path
    return found


def imports(name: str, source: str, known: set[str]) -> list[tuple[str, int]]:
    """(imported module, line) for every import statement of softras or glref
    in a module's source.  ``from package import name`` is an import of the
    submodule where ``package.name`` is a module, of the package otherwise."""
    is_package = name in known and (name + ".__init__") not in known and any(k.startswith(name + ".") for k in known)
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:                      # relative: resolve against this module's package
                anchor = name.split(".") if is_package else name.split(".")[:-1]
                anchor = anchor[:len(anchor) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base
                       for alias in node.names]
        else:
            continue
        for target in targets:
            if target.split(".")[0] in PACKAGES:
                while target not in known and "." in target:      # softras.scene.model.Scene -> the module
                    target = target.rsplit(".", 1)[0]
                found.append((target, node.lineno))
    return found


def graph(sources: dict[str, str]) -> dict[str, list[tuple[str, int]]]:
    known = set(sources)
    return {name: [(t, line) for t, line in imports(name, text, known) if t != name]
            for name, text in sources.items()}


def upward_imports(edges) -> list[str]:
    return [f"{name} (layer {layer(name)}) imports {target} (layer {layer(target)}) at line {line}"
            for name, targets in edges.items() for target, line in targets
            if layer(target) not in ALLOWED[layer(name)]]


def circles(edges) -> list[list[str]]:
    """Every strongly connected component with more than one module (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w, _ in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


@pytest.fixture(scope="module")
def edges():
    return graph({name: path.read_text() for name, path in modules().items()})


def test_every_layer_has_its_modules(edges):
    layers = {layer(name) for name in edges}
    assert layers == set(ALLOWED), layers


def test_imports_only_go_down(edges):
    assert upward_imports(edges) == []


def test_no_import_circles(edges):
    assert circles(edges) == []


def test_glref_needs_only_the_scene_layer(edges):
    outside = {t for name, targets in edges.items() if layer(name) == "glref"
               for t, _ in targets if layer(t) not in ("scene", "glref")}
    assert outside == set()


def test_the_checks_fail_on_planted_imports():
    """The checker itself: an upward import, a lazy one inside a function,
    a relative one and a circle, each in made-up sources, are all found."""
    sources = {
        "softras": "",
        "softras.scene": "",
        "softras.scene.model": "def f():\n    from softras.pipeline import setup\n",   # lazy, upward
        "softras.pipeline": "",
        "softras.pipeline.setup": "from . import clip\n",                                # relative, fine
        "softras.pipeline.clip": "from softras.pipeline import setup\n",                 # circle with setup
        "softras.kernels": "",
        "softras.kernels.draw": "import softras.verification.verifier\n",               # upward
        "softras.renderer": "",
        "softras.verification": "",
        "softras.verification.verifier": "from softras.kernels import draw\n",
        "glref": "from softras.pipeline import clip\n",                                 # glref above scene
    }
    edges = graph(sources)
    found = upward_imports(edges)
    assert any(s.startswith("softras.scene.model (layer scene) imports softras.pipeline.setup") for s in found)
    assert any(s.startswith("softras.kernels.draw (layer kernels) imports softras.verification.verifier")
               for s in found)
    assert any(s.startswith("glref (layer glref) imports softras.pipeline.clip") for s in found)
    assert len(found) == 3
    assert sorted(circles(edges)) == [["softras.kernels.draw", "softras.verification.verifier"],
                                      ["softras.pipeline.clip", "softras.pipeline.setup"]]


MAX_LINES = 600


def long_modules_without_a_reason(sources: dict[str, str]) -> list[str]:
    """Modules over MAX_LINES lines whose docstring does not say why they are one module."""
    found = []
    for name, text in sources.items():
        lines = text.count("\n")
        docstring = ast.get_docstring(ast.parse(text)) or ""
        if lines > MAX_LINES and "Why one module" not in docstring:
            found.append(f"{name}: {lines} lines")
    return found


def test_long_modules_say_why_they_are_one_module():
    sources = {name: path.read_text() for name, path in modules().items()}
    assert long_modules_without_a_reason(sources) == []
    assert long_modules_without_a_reason({"softras.big": '"""A big module."""\n' + "x = 1\n" * 601}) == \
        ["softras.big: 602 lines"]
