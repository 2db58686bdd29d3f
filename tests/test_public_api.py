"""The public interface outlives the layout: the API names, every CLI command
and flag, and the pictures of the scene files.

COMMANDS is the command line as it was before the code moved into packages
(read from ``softras.cli.build_parser`` at that commit); a flag renamed or
dropped fails here.  Golden images of every scene are checked by
tests/test_golden.py, and byte equality of the stages and the kernels by
tests/test_fastpath.py.
"""

from __future__ import annotations

import argparse

import numpy as np

import softras
from softras.cli import build_parser

COMMANDS = {
    '': ['-h', '--help', '--gl-device'],
    'bench': ['--full', '--help', '--json', '--max-side', '--max-triangles', '--plot', '--quick', '--runs', '-h'],
    'compare': ['--flip-map', '--help', '--json', '--max-bad-fraction', '--min-ssim', '--out-dir', '--output', '--precision', '--samples', '--ssim-map', '--threshold', '-h', '-o'],
    'conformance': ['--baseline', '--help', '--jobs', '--max-memory', '--profile', '--report', '--resume', '--retries', '--shard', '--timeout', '-h', '-j', '-k'],
    'demo': ['--help', '--json', '--max-bad-fraction', '--min-ssim', '--out-dir', '--precision', '--samples', '--scene', '--threshold', '-h'],
    'explain': ['--help', '--json', '--pixel', '--precision', '--samples', '-h'],
    'golden': ['--golden-dir', '--help', '--out-dir', '--update', '-h'],
    'info': ['--help', '--json', '-h'],
    'render': ['--backend', '--filter', '--framebuffer', '--help', '--output', '--pattern', '--precision', '--samples', '--seed', '--texture-filter', '-h', '-o'],
    'verify': ['--capabilities', '--help', '--json', '--out-dir', '--profile', '-h'],
}


def command_line() -> dict[str, list[str]]:
    """{command: sorted option strings}, "" for the top-level options."""
    found = {}
    for action in build_parser()._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                found[name] = sorted(s for a in sub._actions for s in a.option_strings)
        elif action.option_strings:
            found.setdefault("", []).extend(action.option_strings)
    return found


def test_every_command_and_flag_is_still_there():
    found = command_line()
    missing = {name: sorted(set(flags) - set(found.get(name, [])))
               for name, flags in COMMANDS.items() if set(flags) - set(found.get(name, []))}
    assert missing == {}


def test_the_python_api():
    assert set(softras.__all__) >= {"load_scene", "render", "compare", "verify", "Scene", "SceneError"}
    scene = softras.load_scene({"softras_scene": 1, "width": 4, "height": 4,
                                "nodes": [{"mesh": {"positions": [[-1, -1, 0], [3, -1, 0], [-1, 3, 0]]}}]})
    image = softras.render(scene)
    assert image.shape == (4, 4, 4) and image.dtype == np.uint8
    assert softras.compare(image, image).passed


def test_pyproject_ships_every_package_and_the_demo_scene():
    """A wheel holds only the packages pyproject.toml names (an explicit
    list: glref.shaders and softras.scenes map to folders outside the
    packages), so a package folder missing there would install a softras
    that cannot import; the demo scene ships as softras.scenes/demo.json."""
    import tomllib
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    config = tomllib.loads((repo / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]
    folders = {".".join(init.parent.relative_to(repo).parts)
               for top in ("softras", "glref") for init in (repo / top).rglob("__init__.py")}
    listed = set(config["packages"])
    assert folders <= listed, sorted(folders - listed)
    mapped = {name: repo / folder for name, folder in config["package-dir"].items()}
    assert listed - folders == set(mapped), sorted(listed - folders - set(mapped))
    for name, patterns in config["package-data"].items():
        for pattern in patterns:
            assert list(mapped[name].glob(pattern)), (name, pattern)
    assert "demo.json" in config["package-data"]["softras.scenes"]
    assert mapped["softras.scenes"] / "demo.json" == repo / "scenes" / "demo.json"
