"""numba's compile, faster, the same code (softras.pipeline.numba_fixes): the
fixes are installed, each copies what numba's deepcopy would, and a kernel
that inlines and runs a parallel loop compiles to the same machine code with
and without them."""

from __future__ import annotations

import copy
import json
import os
import subprocess
import sys

from numba.core import inline_closurecall, ir_utils

from softras.pipeline import numba_fixes

# In a new process on an empty numba cache: Gouraud's and flat shading's
# lighting loops compiled anew (a parallel loop, so copy propagation runs,
# and Blinn-Phong inlined: `_lit_point` and libm's pow), called on
# lit_spheres' first lit draw; prints their machine code (addresses in
# symbol names masked), their results and how often each fix was used.
PROGRAM = r"""
import json, re, sys
import numpy as np
from softras.pipeline import numba_fixes, vertex
from softras.kernels import light
from softras.scene import load_scene

used = {"blocks": 0, "tables": 0}
copy_table = numba_fixes._copy_table
def counted_table(x):
    table = copy_table(x)
    used["tables"] += table is not None
    return table
numba_fixes._copy_table = counted_table
block_copy = numba_fixes._InlinerCopy.deepcopy
def counted_block(self, x, memo=None):
    used["blocks"] += 1
    return block_copy(self, x, memo)
numba_fixes._InlinerCopy.deepcopy = counted_block

scene = load_scene(sys.argv[1])
draw = next(d for d in scene.draws if d.material.shading != "unlit")
table, lighting = light.scene_lighting(scene, draw.material)
world = np.ascontiguousarray(vertex.world_positions(draw.mesh.positions, draw.world))
normals = np.ascontiguousarray(vertex.world_normals(draw.mesh.normals, draw.world, unit=False))
base = np.ones((len(world), 4))
vertex_lighting, face_lighting = light._make_lighting_loops("tests/test_numba_fixes.py")
lit = np.empty_like(base)
vertex_lighting(base, world, normals, table, tuple(lighting), lit)
faces = np.ascontiguousarray(draw.mesh.indices, np.int64)
flat = np.empty((len(faces), 4))
face_lighting(world, faces, base, table, tuple(lighting), flat)
code = {}
for kernel in (vertex_lighting, face_lighting):
    for signature, result in kernel.overloads.items():
        code[kernel.__name__] = re.sub(r"0x[0-9a-f]+", "0x?", result.library.get_asm_str())
print(json.dumps({"code": code, "lit": lit.tobytes().hex(), "flat": flat.tobytes().hex(), "used": used}))
"""


def compiled(tmp_path, fixes: bool) -> dict:
    """PROGRAM's output in a new process, with the fixes or without."""
    cache = tmp_path / ("on" if fixes else "off")
    cache.mkdir()
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), SOFTRAS_NUMBA_FIXES="1" if fixes else "0")
    scene = os.path.join(os.path.dirname(__file__), "..", "scenes", "lit_spheres.json")
    done = subprocess.run([sys.executable, "-c", PROGRAM, scene], capture_output=True, text=True, timeout=600,
                          env=env)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.splitlines()[-1])


def test_the_fixes_are_installed_on_this_numba():
    assert numba_fixes.install()
    assert isinstance(inline_closurecall.copy, numba_fixes._InlinerCopy)
    assert isinstance(ir_utils.copy, numba_fixes._PassesCopy)
    assert numba_fixes.install()            # once: a second call changes nothing
    assert getattr(inline_closurecall.InlineWorker.inline_ir, "__wrapped__", None) is not None
    assert getattr(inline_closurecall.InlineWorker.inline_ir.__wrapped__, "_softras", False) is False


def test_a_table_of_copies_is_copied_as_deepcopy_copies_it():
    table = {3: {("a", "b"), ("c", "d")}, 7: set()}
    fast = numba_fixes._PassesCopy().deepcopy(table)
    assert fast == copy.deepcopy(table) and fast is not table
    assert all(fast[key] is not table[key] for key in table)
    fast[3].add(("e", "f"))
    assert ("e", "f") not in table[3]
    for other in ({3: [("a", "b")]}, {3: {("a", 1)}}, {3: {"ab"}}, [{("a", "b")}]):
        assert numba_fixes._copy_table(other) is None
        assert numba_fixes._PassesCopy().deepcopy(other) == copy.deepcopy(other)


def test_one_inlining_copies_the_scope_once():
    """Blocks copied under one memo share one copy of their scope, as the
    original blocks share theirs; a new inlining copies it again."""
    from numba.core import ir

    scope = ir.Scope(None, ir.Loc("f", 1))
    blocks = [ir.Block(scope, ir.Loc("f", 1)) for _ in range(3)]
    shared = numba_fixes._InlinerCopy()
    shared.memo = {}
    first = [shared.deepcopy(block) for block in blocks]
    assert len({id(block.scope) for block in first}) == 1 and first[0].scope is not scope
    shared.memo = {}
    again = shared.deepcopy(blocks[0])
    assert again.scope is not first[0].scope


def test_kernels_compile_to_the_same_code_with_and_without_the_fixes(tmp_path):
    fast, plain = compiled(tmp_path, True), compiled(tmp_path, False)
    assert fast["used"]["blocks"] > 0 and fast["used"]["tables"] > 0, fast["used"]
    assert plain["used"] == {"blocks": 0, "tables": 0}
    assert sorted(fast["code"]) == ["face_lighting", "vertex_lighting"]
    for name, code in fast["code"].items():
        assert code == plain["code"][name], f"{name}: the fixes changed the machine code"
    assert fast["lit"] == plain["lit"] and fast["flat"] == plain["flat"]
