"""A short, derandomized run of the scene-loader fuzzer (scripts/fuzz_loader.py).

Property: a mutated conformance scene (tree or byte mutations, broken texture
files) either loads or raises a one-line SceneError -- never another
exception.  300 examples here; ``python3 scripts/fuzz_loader.py --minutes 10``
runs the long version (with a per-example alarm and a memory limit).
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

from conftest import REPO, load_script

fuzz_loader = load_script("fuzz_loader")


def test_mutated_scenes_load_or_raise_scene_error(tmp_path):
    files = fuzz_loader.broken_files(tmp_path)
    os.symlink(REPO / "scenes" / "textures", tmp_path / "textures")
    test = fuzz_loader.make_test(fuzz_loader.seed_scenes(), tmp_path, files, stats=None, example_alarm_s=None)
    settings(max_examples=300, derandomize=True, database=None, deadline=None,
             suppress_health_check=list(HealthCheck))(test)()


def test_broken_texture_files_are_scene_errors(tmp_path):
    """Each fixture of the fuzzer, named as a texture image, is refused with its place."""
    files = fuzz_loader.broken_files(tmp_path)
    base = {"softras_scene": 1, "width": 4, "height": 4}
    for name in files:
        data = dict(base, textures={"t": {"image": name}})
        if name == "valid.png":
            fuzz_loader.scene_from_dict(data, base_dir=str(tmp_path))
            continue
        try:
            fuzz_loader.scene_from_dict(data, base_dir=str(tmp_path))
        except fuzz_loader.SceneError as error:
            assert str(error).startswith("textures.t.image: "), str(error)
        else:
            raise AssertionError(f"{name!r} loaded")
