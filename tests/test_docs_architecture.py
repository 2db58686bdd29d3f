"""The docs name real code. docs/architecture.md: every dotted name in a code span
(``pipeline.setup.setup_triangles``, ``kernels.draw.render_samples``) and every
private one (``_tile``) resolves to an object of softras or glref, so the walk
cannot outlive a rename."""

from __future__ import annotations

import importlib
import pkgutil
import re
from pathlib import Path

import pytest

import glref
import softras

DOC = Path(__file__).resolve().parent.parent / "docs" / "architecture.md"
PREFIXES = ("softras.", "softras.scene.", "softras.pipeline.", "softras.kernels.", "softras.verification.", "")
FILE = re.compile(r"\.(py|png|json|md)$")


@pytest.fixture(scope="module")
def modules() -> dict:
    found = {m.name: importlib.import_module(m.name) for m in pkgutil.walk_packages(softras.__path__, "softras.")}
    found["softras"], found["glref"] = softras, glref
    return found


def names(text: str) -> list[str]:
    """The code spans that name code: dotted or private, not file names."""
    spans = re.findall(r"`([A-Za-z_][\w.]*)`", text)
    return sorted({s for s in spans if not FILE.search(s) and ("." in s or s.startswith("_"))})


def resolves(name: str, modules: dict) -> bool:
    for prefix in PREFIXES:
        parts = (prefix + name).split(".")
        for i in range(len(parts), 0, -1):
            module = modules.get(".".join(parts[:i]))
            if module is not None:
                obj = module
                for attribute in parts[i:]:
                    obj = getattr(obj, attribute, None)
                if obj is not None:
                    return True
                break
    return "." not in name and any(hasattr(module, name) for module in modules.values())


def test_every_named_function_exists(modules):
    found = names(DOC.read_text())
    assert len(found) > 40
    assert [name for name in found if not resolves(name, modules)] == []


def test_a_renamed_function_is_found(modules):
    text = "`pipeline.setup.setup_triangles`, `kernels.draw._no_such_kernel`, `_no_such_helper`, `floor.png`"
    assert [n for n in names(text) if not resolves(n, modules)] == ["_no_such_helper", "kernels.draw._no_such_kernel"]


def test_every_module_path_the_docs_name_exists(modules):
    """README.md and docs/*.md name modules and functions as ``softras.x.y``;
    after a move each must still resolve (the docs moved with the code)."""
    root = DOC.parent.parent
    missing = []
    for path in [root / "README.md", *sorted((root / "docs").glob("*.md"))]:
        for name in sorted(set(re.findall(r"`((?:softras|glref)\.[\w.]*\w)", path.read_text()))):
            if not resolves(name, modules):
                missing.append(f"{path.name}: {name}")
    assert missing == []
