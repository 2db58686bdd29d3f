"""numba's compile, faster, the same code (softras.pipeline.numba_fixes): the
fixes are installed, each copies what numba's deepcopy would, and a kernel
that inlines and runs a parallel loop compiles to the same machine code with
and without them, with less work (the tile drivers, line kernel and stage
loops that demo and line_star compile did too, docs/speed.md,
"Twenty-seventh round"; every variant's kernels, "Thirty-eighth round")."""

from __future__ import annotations

import copy
import json
import os
import subprocess
import sys
from types import SimpleNamespace

import pytest
from numba.core import analysis, inline_closurecall, ir_utils, ssa, types

from softras.pipeline import numba_fixes

# In a new process on an empty numba cache: Gouraud's lighting as a parallel
# loop over chunks compiled anew (so copy propagation runs, with Blinn-Phong
# inlined: `_light_points` and libm's pow; softras's own loop runs its
# chunks on `softras.kernels.pool`'s threads since the forty-sixth round,
# without numba's parallel passes), called on lit_spheres' first lit draw;
# prints its machine code (addresses in symbol names masked), its result,
# how often each fix was used and how much of numba's work was done: the
# callees' front ends run (bytecode read) and the statements SSA
# reconstruction's rewrites went through.
PROGRAM = r"""
import json, re, sys
import numba
import numpy as np
from softras.pipeline import numba_fixes
from numba.core import analysis, ssa, types, untyped_passes
from softras.kernels import light
from softras.scene import load_scene

used = {"blocks": 0, "tables": 0, "kept": 0}
work = {"front ends": 0, "ssa statements": 0, "liveness": 0, "liveness differing": 0}
copy_table = numba_fixes._copy_table
def counted_table(x):
    table = copy_table(x)
    used["tables"] += table is not None
    return table
numba_fixes._copy_table = counted_table
block_copy = numba_fixes._InlinerCopy.deepcopy
def counted_block(self, x, memo=None):
    used["blocks"] += 1
    y = block_copy(self, x, memo)
    used["kept"] += y is x
    return y
numba_fixes._InlinerCopy.deepcopy = counted_block
read_bytecode = untyped_passes.ExtractByteCode.run_pass
def counted_front_end(self, state):
    work["front ends"] += 1
    return read_bytecode(self, state)
untyped_passes.ExtractByteCode.run_pass = counted_front_end
block_pass = ssa._run_ssa_block_pass
def counted_statements(states, blk, handler):
    work["ssa statements"] += len(blk.body)
    return block_pass(states, blk, handler)
ssa._run_ssa_block_pass = counted_statements
live_map = analysis.compute_live_map                # (each liveness also computed by numba's own)
def compared_live_map(cfg, blocks, var_use_map, var_def_map):
    found = live_map(cfg, blocks, var_use_map, var_def_map)
    numbas = getattr(live_map, "__wrapped__", live_map)(cfg, blocks, var_use_map, var_def_map)
    work["liveness"] += 1
    work["liveness differing"] += found != numbas or list(found) != list(numbas)
    return found
analysis.compute_live_map = compared_live_map

scene = load_scene(sys.argv[1])
draw = next(d for d in scene.draws if d.material.shading != "unlit")
table, lighting = light.scene_lighting(scene, draw.material)
world = light.world_attributes(draw, np.empty((len(draw.mesh.positions), 6)))
base = np.ones((len(world), 4))
@numba.njit(error_model="numpy", parallel=True)
def vertex_lighting(base, world, lights, lighting, out):
    n = base.shape[0]
    for chunk in numba.prange((n + light.POINT_CHUNK - 1) // light.POINT_CHUNK):
        first = chunk * light.POINT_CHUNK
        light._light_points(base, world, first, min(n - first, light.POINT_CHUNK), lights, lighting, out,
                            np.empty((8, light.POINT_CHUNK)))
lit = np.empty_like(base)
vertex_lighting(base, world, table, tuple(lighting), lit)
(compiled,) = vertex_lighting.overloads.values()
# (Addresses masked; and the functions' identities in the symbol names,
# "B<n>v<k>": numba numbers every function it reads, and the fixes read
# fewer; with the sizes of the strings that hold those names.)
code = re.sub(r"0x[0-9a-f]+", "0x?", compiled.library.get_asm_str())
code = re.sub(r"B\d+v\d+", "Bv", code)
code = re.sub(r'(\.size\s+"\.const\.[^"]*"), \d+', r"\1, N", code)
used["calls"] = getattr(types.BaseFunction.get_call_type, "hits", 0)
print(json.dumps({"code": code, "lit": lit.tobytes().hex(), "used": used, "work": work}))
"""


def compiled(tmp_path) -> tuple[dict, dict]:
    """PROGRAM's output with the fixes and without: two new processes, side by side."""
    scene = os.path.join(os.path.dirname(__file__), "..", "scenes", "lit_spheres.json")
    runs = []
    for fixes in ("1", "0"):
        cache = tmp_path / f"fixes{fixes}"
        cache.mkdir()
        env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), SOFTRAS_NUMBA_FIXES=fixes)
        runs.append(subprocess.Popen([sys.executable, "-c", PROGRAM, scene], stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True, env=env))
    outputs = []
    for run in runs:
        out, err = run.communicate(timeout=600)
        assert run.returncode == 0, err[-3000:]
        outputs.append(json.loads(out.splitlines()[-1]))
    return outputs[0], outputs[1]


def test_the_fixes_are_installed_on_this_numba():
    assert numba_fixes.install()
    assert isinstance(inline_closurecall.copy, numba_fixes._InlinerCopy)
    assert isinstance(ir_utils.copy, numba_fixes._PassesCopy)
    assert numba_fixes.install()            # once: a second call changes nothing
    assert getattr(inline_closurecall.InlineWorker.inline_ir, "__wrapped__", None) is not None
    assert getattr(inline_closurecall.InlineWorker.inline_ir.__wrapped__, "_softras", False) is False
    for wrapped in (inline_closurecall.InlineWorker.run_untyped_passes, ssa._run_ssa, ssa._run_block_rewrite,
                    analysis.compute_live_map, types.BaseFunction.get_call_type):
        assert getattr(wrapped, "__wrapped__", None) is not None
        assert getattr(wrapped.__wrapped__, "__wrapped__", None) is None       # (wrapped once)


def test_numba_is_left_alone_where_it_is_not_as_expected():
    class Worker:
        def inline_ir(self):
            pass

        def run_untyped_passes(self):
            pass

    class Bare:
        def inline_ir(self):
            pass

    class Config:
        def values(self):
            return {}

    class Scheme:
        def _markup(self, msg, color=None, style="*"):
            return msg

    def modules(inliner=True, passes=True, ssa=True, ir=True, analysis=True, config=True, worker=Worker):
        """Stand-ins for numba's seven modules, as expected unless one is False."""
        return (SimpleNamespace(InlineWorker=worker, copy=copy) if inliner else SimpleNamespace(InlineWorker=worker),
                SimpleNamespace(copy=copy, copy_propagate=None) if passes else SimpleNamespace(copy_propagate=None),
                SimpleNamespace(_run_ssa=lambda blocks: blocks, _run_block_rewrite=lambda *args: None) if ssa
                else SimpleNamespace(_run_ssa=None),
                SimpleNamespace(Block=object) if ir else SimpleNamespace(),
                SimpleNamespace(compute_live_map=lambda *args: {}) if analysis else SimpleNamespace(),
                SimpleNamespace(TargetConfig=Config) if config else SimpleNamespace(),
                SimpleNamespace(HighlightColorScheme=Scheme, Style=SimpleNamespace(RESET_ALL="!")))

    for unexpected in (modules(inliner=False), modules(passes=False), modules(worker=Bare), modules(ssa=False),
                       modules(ir=False), modules(analysis=False), modules(config=False),
                       (SimpleNamespace(copy=copy), *modules()[1:])):
        before = [module.__dict__.copy() for module in unexpected]
        assert not numba_fixes.install(*unexpected)
        assert Worker.inline_ir.__name__ == "inline_ir" and not hasattr(Worker.run_untyped_passes, "__wrapped__")
        assert [module.__dict__ for module in unexpected] == before
    inliner, passes, ssa, ir, analysis, config, errors = modules()
    assert numba_fixes.install(inliner, passes, ssa, ir, analysis, config, errors)         # (as expected: installed)
    assert Worker.inline_ir._softras and isinstance(inliner.copy, numba_fixes._InlinerCopy)
    assert all(hasattr(f, "__wrapped__") for f in (Worker.run_untyped_passes, ssa._run_ssa, ssa._run_block_rewrite,
                                                   analysis.compute_live_map, Config.values, Config.__hash__,
                                                   Scheme._markup))
    assert Scheme()._markup("m", "<c>") == "<c>*m!"
    # (The stand-ins' flags have no stack: numba's own call typing was left as it is, not wrapped again.)
    assert not hasattr(types.BaseFunction.get_call_type.__wrapped__, "memo")
    fresh = type("Fresh", (), {"inline_ir": lambda self: None, "run_untyped_passes": lambda self: None})
    inliner, passes, ssa, ir, analysis, config, _ = modules(worker=fresh)
    assert numba_fixes.install(inliner, passes, ssa, ir, analysis, config, SimpleNamespace())   # (no colorama:
    assert fresh.inline_ir._softras                                                             # the others)

    class Function:
        def get_call_type(self, context, args, kws):
            pass

        def get_impl_key(self, sig):
            pass

    fresh = type("Fresh", (), {"inline_ir": lambda self: None, "run_untyped_passes": lambda self: None})
    inliner, passes, ssa, ir, analysis, config, errors = modules(worker=fresh)
    config.ConfigStack = SimpleNamespace(top_or_none=lambda: None)
    functions = SimpleNamespace(BaseFunction=Function)
    assert numba_fixes.install(inliner, passes, ssa, ir, analysis, config, errors, functions)
    assert Function.get_call_type.memo == {}


def test_a_call_is_typed_once_with_numbas_signature_and_key():
    """A call typed again returns the signature numba resolved and records
    its implementation key again; other flags, other argument types or
    another function are typed anew, and a call that fails fails each time."""
    import operator

    from numba.core import errors, targetconfig
    from numba.core.compiler import Flags
    from numba.core.registry import cpu_target

    context = cpu_target.typing_context
    context.refresh()
    get_call_type = types.BaseFunction.get_call_type
    add, mul = context.resolve_value_type(operator.add), context.resolve_value_type(operator.mul)
    args = (types.int64, types.float32)
    first = add.get_call_type(context, args, {})
    assert first == get_call_type.__wrapped__(add, context, args, {})        # numba's own signature
    key = add.get_impl_key(first)
    hits = get_call_type.hits
    add._impl_keys[first.args] = "another compile's"
    assert add.get_call_type(context, args, {}) is first and get_call_type.hits == hits + 1
    assert add.get_impl_key(first) == key
    kinds = len(get_call_type.memo)
    flags = Flags()
    flags.error_model = "numpy"
    with targetconfig.ConfigStack().enter(flags):
        assert add.get_call_type(context, args, {}) == first
    assert mul.get_call_type(context, args, {}) == get_call_type.__wrapped__(mul, context, args, {})
    add.get_call_type(context, (types.int32, types.int32), {})
    assert len(get_call_type.memo) == kinds + 3 and get_call_type.hits == hits + 1
    for _ in range(2):
        with pytest.raises(errors.TypingError):
            add.get_call_type(context, (types.none, types.unicode_type), {})
    assert len(get_call_type.memo) == kinds + 3


def test_error_messages_are_numbas_strings():
    """numba's coloured message strings, the same without colorama's stream
    set-up; without colorama numba's messages are plain, and there is
    nothing to fix."""
    from numba.core import errors

    if not hasattr(errors, "HighlightColorScheme"):
        assert errors.termcolor().errmsg("Cannot determine Numba type") == "Cannot determine Numba type"
        return
    markup = errors.HighlightColorScheme._markup
    assert markup.__wrapped__ is not markup
    scheme = errors.termcolor()
    for args in (("Cannot determine Numba type",), ("a", errors.Fore.RED), ("x\u00e9y", None, None),
                 ("", errors.Fore.BLUE, errors.Style.BRIGHT), ("line\nnext", None)):
        assert markup(scheme, *args) == markup.__wrapped__(scheme, *args), args


def test_compile_flags_give_numbas_values_hash_and_equality():
    """The flags' values, hash and comparisons as numba's own make them,
    for flags with nothing set, some options set (to defaults too) and
    copies; and numba's own for a class with an option of its own making."""
    from numba.core import targetconfig
    from numba.core.compiler import Flags

    values, hash_ = targetconfig.TargetConfig.values.__wrapped__, targetconfig.TargetConfig.__hash__.__wrapped__
    plain, some, default = Flags(), Flags(), Flags()
    some.nrt, some.error_model, some.enable_ssa = True, "numpy", False
    default.nrt = Flags.options["nrt"].default
    copied = Flags(some)
    for flags in (plain, some, default, copied):
        assert flags.values() == values(flags) and list(flags.values()) == list(values(flags))
        assert hash(flags) == hash_(flags)
    assert plain == default and plain != some and some == copied and hash(plain) == hash(some)

    class Odd(targetconfig.TargetConfig):
        level = targetconfig.Option(int, default=1, doc="")

    Odd.level = property(lambda self: 7)            # (not numba's property: numba's own values)
    assert numba_fixes._plain_options(Odd) is None and Odd().values() == {"level": 7} and hash(Odd()) == hash_(Odd())


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
    fast, plain = compiled(tmp_path)
    assert all(fast["used"][name] > 0 for name in ("blocks", "tables", "kept", "calls")), fast["used"]
    assert plain["used"] == {"blocks": 0, "tables": 0, "kept": 0, "calls": 0}
    assert fast["work"]["front ends"] < plain["work"]["front ends"], (fast["work"], plain["work"])
    assert fast["work"]["ssa statements"] < plain["work"]["ssa statements"], (fast["work"], plain["work"])
    assert fast["work"]["liveness"] > 0 and fast["work"]["liveness differing"] == 0, fast["work"]
    assert fast["code"] == plain["code"], "the fixes changed the machine code"
    assert fast["lit"] == plain["lit"]
