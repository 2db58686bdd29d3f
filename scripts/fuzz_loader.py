"""Fuzz the scene loader: mutated scenes must load or raise SceneError, nothing else.

The property (bad input never costs data): for any input, ``softras.load_scene`` either returns a
``Scene`` or raises ``SceneError`` with a one-line message -- never another
exception, never a hang, never a huge allocation.  Inputs are the conformance
scenes (``scenes/*.json``) mutated by hypothesis:

* tree mutations of the parsed JSON: delete a key, add an unknown key,
  replace any value by a random JSON value (wrong types, NaN, +-inf, 1e308,
  10**40, 5e-324, -0.0, long strings, nested lists), replace a number by an
  extreme one, wrap a value in a list, drop or repeat list items, point a
  texture ``image`` at a broken file (truncated PNG, text named .png, empty
  file, a PNG header claiming 10^5 x 10^5 pixels, a folder named .png);
* byte mutations of the JSON text (delete, insert and overwrite runs of random
  bytes, invalid UTF-8), loaded from a file.

``tests/test_fuzz_loader.py`` runs a short derandomized version in CI.  Run
the long version from the repository root::

    python3 scripts/fuzz_loader.py --minutes 10 [--seed N]

It prints how many examples ran, how many loaded, the SceneError places seen
most often, and stops at the first failure with a minimal example (hypothesis
shrinks it).  Each example runs under a 30 s alarm (a hang is a failure) and
the process under a 6 GiB address-space limit (a huge allocation is a
MemoryError, a failure).
"""

from __future__ import annotations

import argparse
import collections
import copy
import json
import math
import os
import signal
import struct
import sys
import tempfile
import time
import zlib
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from softras.scene import Scene, SceneError, load_scene, scene_from_dict  # noqa: E402

SCENES = REPO / "scenes"

# --------------------------------------------------------------------------- inputs


def seed_scenes() -> list[dict]:
    """The conformance scenes as dicts, sorted by file name (deterministic)."""
    return [json.loads(path.read_text()) for path in sorted(SCENES.glob("*.json"))]


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def broken_files(folder: Path) -> list[str]:
    """Write texture files of every kind of brokenness into ``folder``; return their names."""
    from PIL import Image

    Image.new("RGBA", (4, 4), (10, 20, 30, 255)).save(folder / "valid.png")
    whole = (folder / "valid.png").read_bytes()
    (folder / "truncated.png").write_bytes(whole[: len(whole) // 2])
    (folder / "text.png").write_text("this is not a picture\n")
    (folder / "empty.png").write_bytes(b"")
    # A valid PNG header claiming 100000 x 100000 RGBA pixels (40 GB decoded), no data.
    header = struct.pack(">IIBBBBB", 100_000, 100_000, 8, 6, 0, 0, 0)
    (folder / "bomb.png").write_bytes(b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", header)
                                      + _png_chunk(b"IEND", b""))
    (folder / "folder.png").mkdir(exist_ok=True)
    return ["valid.png", "truncated.png", "text.png", "empty.png", "bomb.png", "folder.png",
            "missing.png", "", "/", "../" * 40 + "x.png", "\u00e9\u0000.png"]


EXTREME_NUMBERS = [0, -0.0, 1, -1, 0.5, 2 ** 31, -2 ** 31, 2 ** 63, 10 ** 40, -10 ** 40, 1e308, -1e308,
                   5e-324, 1e-300, float("nan"), float("inf"), float("-inf"), 16384, 16385, 4096 * 4096,
                   4 * 1024 * 1024 + 1, 1e7, True, False]

json_scalars = st.one_of(
    st.none(), st.booleans(), st.integers(min_value=-10 ** 40, max_value=10 ** 40),
    st.floats(allow_nan=True, allow_infinity=True), st.sampled_from(EXTREME_NUMBERS),
    st.text(max_size=20), st.sampled_from(["", "none", "less", "repeat", "phong", "fan", "grid",
                                           "perspective", "lines", "x" * 10_000]))
json_values = st.recursive(json_scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=5), st.dictionaries(st.text(max_size=8), inner, max_size=4)), max_leaves=12)


def _paths(tree, prefix=()):
    """Every (path) to a value in a JSON tree, the root excluded, in a stable order."""
    out = []
    if isinstance(tree, dict):
        for key in tree:
            out.append(prefix + (key,))
            out.extend(_paths(tree[key], prefix + (key,)))
    elif isinstance(tree, list):
        for i, item in enumerate(tree):
            out.append(prefix + (i,))
            out.extend(_paths(item, prefix + (i,)))
    return out


def _parent(tree, path):
    for key in path[:-1]:
        tree = tree[key]
    return tree


def mutate_tree(data: st.DataObject, scene: dict, files: list[str]) -> dict:
    """Apply 1-4 random tree mutations to a copy of ``scene``."""
    scene = copy.deepcopy(scene)
    for _ in range(data.draw(st.integers(1, 4), label="mutations")):
        paths = _paths(scene)
        if not paths:
            break
        path = paths[data.draw(st.integers(0, len(paths) - 1), label="at")]
        parent, key = _parent(scene, path), path[-1]
        op = data.draw(st.sampled_from(["delete", "replace", "unknown_key", "extreme", "wrap",
                                        "drop_items", "repeat_items", "image"]), label="op")
        value = parent[key]
        if op == "delete":
            del parent[key]
        elif op == "replace":
            parent[key] = data.draw(json_values, label="value")
        elif op == "unknown_key":
            target = value if isinstance(value, dict) else parent if isinstance(parent, dict) else None
            if target is not None:
                target[data.draw(st.text(min_size=1, max_size=8), label="key")] = data.draw(json_values)
        elif op == "extreme":
            parent[key] = data.draw(st.sampled_from(EXTREME_NUMBERS), label="number")
        elif op == "wrap":
            parent[key] = [value]
        elif op in ("drop_items", "repeat_items") and isinstance(value, list) and value:
            k = data.draw(st.integers(0, len(value) - 1), label="item")
            if op == "drop_items":
                del value[k]
            else:
                value.insert(k, copy.deepcopy(value[k]))
        elif op == "image":
            textures = scene.get("textures")
            if isinstance(textures, dict) and textures:
                name = data.draw(st.sampled_from(sorted(textures, key=str)), label="texture")
                textures[name] = {"image": data.draw(st.sampled_from(files), label="file")}
    return scene


def mutate_bytes(data: st.DataObject, text: bytes) -> bytes:
    """Apply 1-3 byte-level mutations to JSON text."""
    buf = bytearray(text)
    for _ in range(data.draw(st.integers(1, 3), label="byte mutations")):
        pos = data.draw(st.integers(0, len(buf)), label="pos")
        op = data.draw(st.sampled_from(["delete", "insert", "overwrite", "truncate"]), label="byte op")
        chunk = data.draw(st.one_of(st.binary(min_size=1, max_size=8),
                                    st.sampled_from([b"{", b"}", b"[", b"]", b",", b":", b'"', b"\\", b"NaN",
                                                     b"Infinity", b"-", b"1e999", b"\xff\xfe", b"\x00",
                                                     b"[" * 100_000])), label="bytes")
        if op == "delete":
            del buf[pos:pos + len(chunk)]
        elif op == "insert":
            buf[pos:pos] = chunk
        elif op == "overwrite":
            buf[pos:pos + len(chunk)] = chunk
        else:
            del buf[pos:]
    return bytes(buf)


# --------------------------------------------------------------------------- the property


def check_load(source, stats: collections.Counter | None = None, **kwargs) -> None:
    """Load ``source``; anything but a Scene or a one-line SceneError is a failure."""
    try:
        if isinstance(source, dict):
            result = scene_from_dict(source, **kwargs)
        else:
            result = load_scene(source)
    except SceneError as error:
        message = str(error)
        assert message and "\n" not in message, f"SceneError message is not one line: {message!r}"
        if stats is not None:
            stats["error " + error.place.split("[")[0].split(".")[0]] += 1
        return
    assert isinstance(result, Scene), type(result)
    if stats is not None:
        stats["loaded"] += 1


def make_test(seeds: list[dict], folder: Path, files: list[str], stats: collections.Counter | None,
              example_alarm_s: int | None):
    """The hypothesis test function (given seeds and fixture files in ``folder``)."""

    @given(data=st.data())
    def fuzz(data):
        scene = seeds[data.draw(st.integers(0, len(seeds) - 1), label="seed scene")]
        if example_alarm_s:
            signal.alarm(example_alarm_s)       # a hang raises in the test: a failure
        try:
            if data.draw(st.booleans(), label="bytes?"):
                text = json.dumps(mutate_tree(data, scene, files)).encode()
                path = folder / "fuzzed.json"
                path.write_bytes(mutate_bytes(data, text))
                check_load(str(path), stats)
            else:
                check_load(mutate_tree(data, scene, files), stats, base_dir=str(folder))
        finally:
            if example_alarm_s:
                signal.alarm(0)

    return fuzz


class Hang(Exception):
    """An example ran past its alarm."""


def _on_alarm(signum, frame):
    raise Hang("example ran longer than its alarm")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=10.0, help="how long to fuzz (default 10)")
    parser.add_argument("--seed", type=int, default=0, help="hypothesis seed (default 0)")
    parser.add_argument("--memory-gib", type=float, default=6.0, help="address-space limit (default 6)")
    args = parser.parse_args(argv)
    try:
        import resource
        limit = int(args.memory_gib * 2 ** 30)
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    except (ImportError, ValueError, OSError):
        print("warning: could not limit the address space", file=sys.stderr)
    signal.signal(signal.SIGALRM, _on_alarm)

    seeds = seed_scenes()
    stats: collections.Counter = collections.Counter()
    deadline = time.monotonic() + 60 * args.minutes
    rounds = 0
    failures: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        files = broken_files(folder)
        # Copy the seed scenes' texture folder so valid image paths resolve too.
        os.symlink(SCENES / "textures", folder / "textures")
        while time.monotonic() < deadline:
            test = make_test(seeds, folder, files, stats, example_alarm_s=30)
            test = settings(max_examples=2000, deadline=None, database=None, derandomize=False,
                            suppress_health_check=list(HealthCheck), print_blob=True)(test)
            test = _seeded(test, args.seed + rounds)
            start = time.monotonic()
            try:
                test()                               # raises (with the minimal example) on a failure
            except Exception as error:               # report it and go on fuzzing
                failures.append(f"round {rounds}: {type(error).__name__}: {error}")
                print(f"FAILURE {failures[-1]}", flush=True)
            rounds += 1
            total = stats["loaded"] + sum(v for k, v in stats.items() if k.startswith("error"))
            print(f"round {rounds}: {total} examples in all, {stats['loaded']} loaded "
                  f"({time.monotonic() - start:.0f} s)", flush=True)
    total = stats["loaded"] + sum(v for k, v in stats.items() if k.startswith("error"))
    print(f"\n{total} examples in {args.minutes:g} min: {stats['loaded']} loaded, "
          f"{total - stats['loaded']} SceneError, {len(failures)} failures (other exception, hang, "
          f"MemoryError or a message on several lines)")
    for key, count in stats.most_common(15):
        print(f"  {count:7d}  {key}")
    for failure in failures:
        print(failure)
    return 1 if failures else 0


def _seeded(test, seed: int):
    from hypothesis import seed as hypothesis_seed
    return hypothesis_seed(seed)(test)


if __name__ == "__main__":
    sys.exit(main())
