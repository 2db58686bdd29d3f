"""The tests that the documentation names exist.

README.md, docs/*.md and the docstrings and comments of softras/ and glref/
name tests as evidence: a test file (``tests/test_x.py``, optionally
``::test_name``), a test module (``test_x``, ``test_x.py``) or a test
function (``test_name``).  Each must exist, so a claim "pinned by a test"
cannot point at nothing (clip.py once cited a test of its compiled clipper
that was never written).  README's list of findings "each pinned by a test"
must name a test in every item.
"""

from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TESTS = REPO / "tests"

# A path under tests/ (a file, optionally ::function) or a bare test module / function name.
PATH = re.compile(r"(?<![\w/])tests/((?:[\w-]+/)*[\w-]+\.py)(?:::(\w+))?")
NAME = re.compile(r"(?<![\w/.])(test_\w+)(\.py)?\b")


@functools.lru_cache(maxsize=1)
def documents() -> dict[str, str]:
    """{path relative to the repository: text} of every file whose claims are checked."""
    files = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md")),
             *sorted((REPO / "softras").rglob("*.py")), *sorted((REPO / "glref").rglob("*.py"))]
    return {str(f.relative_to(REPO)): f.read_text(encoding="utf-8") for f in files}


@functools.lru_cache(maxsize=1)
def defined_tests() -> dict[str, set[str]]:
    """{test file relative to tests/: the names of the test functions it defines}.

    The test files of the example projects (examples/*/tests/) count too, under
    a path relative to tests/ (``../examples/...``): docs/pytest_plugin.md
    shows their tests."""
    found = {}
    for path in [*TESTS.rglob("test_*.py"), *(REPO / "examples").glob("*/tests/test_*.py")]:
        tree = ast.parse(path.read_text(encoding="utf-8"))
        key = str(path.relative_to(TESTS)) if TESTS in path.parents else "../" + str(path.relative_to(REPO))
        found[key] = {node.name for node in ast.walk(tree)
                      if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
                      and node.name.startswith("test_")}
    return found


def references(text: str) -> tuple[list, list]:
    """(paths [(file under tests/, function or None)], bare names [(name, is a file)])."""
    paths = [(m.group(1), m.group(2)) for m in PATH.finditer(text)]
    without_paths = PATH.sub(" ", text)
    names = [(m.group(1), bool(m.group(2))) for m in NAME.finditer(without_paths)]
    return paths, names


def missing_references(text: str, functions: dict[str, set[str]]) -> list[str]:
    """The references in text to tests that do not exist."""
    modules = {Path(f).stem for f in functions}
    every_function = set().union(*functions.values())
    missing = []
    paths, names = references(text)
    for file, function in paths:
        if file not in functions:
            missing.append(f"tests/{file}")
        elif function and function not in functions[file]:
            missing.append(f"tests/{file}::{function}")
    for name, is_file in names:
        if (name not in modules) if is_file else (name not in modules and name not in every_function):
            missing.append(name + (".py" if is_file else ""))
    return missing


def test_named_tests_exist():
    functions = defined_tests()
    missing, count = {}, 0
    for name, text in documents().items():
        paths, names = references(text)
        count += len(paths) + len(names)
        gone = missing_references(text, functions)
        if gone:
            missing[name] = gone
    assert not missing, f"named tests that do not exist: {missing}"
    assert count > 40, f"only {count} references found: is the pattern still right?"


def test_every_finding_in_the_readme_names_its_test():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    start = readme.index("each pinned by a test")
    section = readme[start:readme.index("\n## ", start)]
    items = re.split(r"\n- ", section)[1:]
    assert len(items) >= 8
    for item in items:
        paths, names = references(item)
        assert paths or names, f"a finding without its test: {item[:80]!r}"


def test_the_checker_catches_a_missing_test():
    """The checker itself: a made-up file, function and module are reported."""
    functions = defined_tests()
    text = ("see tests/test_nothing_here.py, tests/test_fastpath.py::test_no_such_thing, "
            "`test_unwritten_clipper_equivalence` and test_absent.py; but tests/test_fastpath.py, "
            "tests/stages/test_clip.py::test_compiled_clipper_equals_clip_polygon, test_scenes and "
            "`_depth_test_lane` are fine")
    assert missing_references(text, functions) == [
        "tests/test_nothing_here.py", "tests/test_fastpath.py::test_no_such_thing",
        "test_unwritten_clipper_equivalence", "test_absent.py"]
