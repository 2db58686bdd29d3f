"""Fixes to numba's compile time, the same code compiled faster.

Most of the time a cold kernel took to compile was numba's own Python, not
LLVM (docs/speed.md, "Twenty-seventh round"), and two deep copies in it
cost time that grows as the square of a function's size:

- **the inliner** (``inline="always"``, `numba.core.inline_closurecall`,
  ``InlineWorker.inline_ir``) copies a callee's IR block by block with one
  ``copy.deepcopy`` per block.  Every variable holds the function's scope,
  and the scope holds every variable, so each block's copy copies the whole
  scope again: blocks x variables (numba issue #8989, NVIDIA/numba-cuda
  #688).  Here the blocks of one inlining share one memo, so the scope is
  copied once and the copy has the structure of the original (one scope,
  as every block of a function shares);
- **copy propagation** (`numba.core.ir_utils.copy_propagate`, run by the
  parallel loops' passes) deep-copies its table of copies, a dict of sets
  of ``(name, name)`` tuples, on every step of a fixed-point iteration.
  Such a table is copied here as new sets of the same tuples: what
  ``deepcopy`` returns for it (a tuple of strings is its own deep copy).

Three more do work once that numba did again and again (docs/speed.md,
"Thirty-eighth round"):

- **the inliner's front end**: numba ran the untyped passes on a callee
  (bytecode to IR, and the inlining of the callee's own callees) at every
  call site it inlined.  `_run_untyped_passes_once` keeps the IR of each
  function (with the caller's flags) and hands each call site a copy of
  it under a new function identity, which ``inline_ir`` copies again
  before it changes anything, as it did before;
- **the unused copy**: ``inline_ir`` also deep-copies the callee's IR a
  second time, to return it unmutated, and both of numba's callers
  (`numba.core.untyped_passes.InlineInlinables`,
  `numba.core.typed_passes.InlineOverloads`) discard it: `_InlinerCopy`
  returns a block it copied in the same inlining as it is;
- **SSA reconstruction** (`numba.core.ssa`) fixes the variables assigned
  more than once one at a time, and for each rewrote every block of the
  function: `_run_ssa_indexed` notes the blocks that name each variable
  and `_rewrite_where_named` rewrites only those, the others kept as they
  are (a block that does not name the variable is one the rewrite leaves
  as it is).

One makes a comparison cheaper: numba's **compile flags**
(`numba.core.targetconfig.TargetConfig`) are part of the key of every
typed call it caches (``_OverloadFunctionTemplate._get_impl``), and each
hash and comparison built a dict of all 22 options through their
properties, ~8 % of a cold compile.  `_fast_values` builds the same dict
from the flags' own values and the options' defaults (what each option's
property returns) and `_fast_hash` returns the same hash (that of the
sorted option names, which is all numba's hashed), for the classes whose
options are all numba's generated properties; any other class keeps
numba's.

One skips a terminal set-up that changes nothing: numba builds a
coloured message for each overload it tries and rejects while typing a
call (`numba.core.errors.HighlightColorScheme._markup`), and each set up
colorama's stream wrappers and took them down again (54648 times in a
driver's compile, ~2.5 % of it), though the message is the same string
either way.  `_plain_markup` returns that string: the colour, the style,
the message and colorama's reset, through UTF-8 as numba's did.  (Only
where colorama is installed: without it numba's messages are plain.)

One types each call once: **call typing** (`numba.core.types.functions.
BaseFunction.get_call_type`, for every call of a builtin, an operator or
an ``@overload`` that type inference meets) tried the function's
templates in order on every call, though an inlined kernel makes the same
call thousands of times (``int64 + int64``): in a tile driver's compile
~18,000 calls of ~1,500 kinds, the repeats ~12 % of it.  `_call_types_once`
keeps what a call resolved to (its signature and the implementation key
numba records with it), keyed as numba keys the overloads it compiles
(``_OverloadFunctionTemplate._get_impl``: the typing context, the
argument types, the compile flags) and the function type, and on a repeat
returns that signature and records that key again, as numba's own would;
a call that fails is tried again every time.

And one does the same work with smaller sets: **liveness**
(`numba.core.analysis.compute_live_map`, run by every ``PostProcessor``
after a pass changed the IR) carried sets of variable names from block to
block until they stopped growing, which for a tile driver's thousands of
variables and hundreds of blocks took seconds per compile;
`_live_map_with_bitsets` carries the same sets as the bits of Python ints
through the same two fixed-point iterations and returns the same sets.

`install` swaps the name ``copy`` in the first two modules for an object
whose ``deepcopy`` does this and hands everything else to `copy.deepcopy`,
and wraps the functions of the others (the liveness as `numba.core.postproc`
calls it; numba's other callers keep numba's own).  It is called when
`softras.pipeline` is imported, before any of softras's kernels compiles,
and leaves numba as it is if its modules do not look as expected (then
compiles are slower, nothing else).  ``SOFTRAS_NUMBA_FIXES=0`` turns it
off, to measure it.  The compiled code is the same either way: every
variant's kernels compiled with and without gave the same assembly
(docs/speed.md), and tests/test_numba_fixes.py compares one parallel
loop's.
"""

from __future__ import annotations

import copy
import functools
import os
from collections import defaultdict


class _InlinerCopy:
    """The ``copy`` module as `numba.core.inline_closurecall` sees it: while
    an ``inline_ir`` call runs, ``deepcopy`` without a memo uses that call's
    one memo, and returns a block that it copied in that call as it is
    (``inline_ir``'s second copy, which its callers discard; ``made``: the
    ids of the copies) (`_inline_ir_sharing_one_memo`)."""

    memo: dict | None = None
    made: set | None = None

    def deepcopy(self, x, memo=None):
        if memo is not None or self.memo is None:
            return copy.deepcopy(x, memo)
        if self.made is not None and id(x) in self.made:
            return x
        y = copy.deepcopy(x, self.memo)
        if self.made is not None:
            self.made.add(id(y))
        return y

    def __getattr__(self, name):
        return getattr(copy, name)


def _copy_table(x):
    """``x`` copied as `copy.deepcopy` would, fast when ``x`` is a dict of
    sets of tuples of strings (copy propagation's table), else None."""
    if type(x) is not dict:
        return None
    for value in x.values():
        if type(value) is not set:
            return None
        for item in value:
            if type(item) is not tuple or not all(type(s) is str for s in item):
                return None
    return {key: set(value) for key, value in x.items()}


class _PassesCopy:
    """The ``copy`` module as `numba.core.ir_utils` sees it: ``deepcopy`` of
    a table of copies (`_copy_table`) without walking it."""

    def deepcopy(self, x, memo=None):
        table = _copy_table(x) if memo is None else None
        return copy.deepcopy(x, memo) if table is None else table

    def __getattr__(self, name):
        return getattr(copy, name)


_SSA_NAMES = ("_run_ssa", "_run_block_rewrite")


def install(inliner=None, passes=None, ssa=None, ir=None, analysis=None, config=None, errors=None,
            functions=None) -> bool:
    """Install the fixes (once) into numba's `numba.core.inline_closurecall`,
    `numba.core.ir_utils`, `numba.core.ssa`, `numba.core.analysis`,
    `numba.core.targetconfig`, `numba.core.errors` and
    `numba.core.types.functions` (or the modules given, for the tests;
    ``ir``: `numba.core.ir`, ``config``: targetconfig); False, and nothing
    changed, where they are off or the modules are not as expected (numba's
    errors without colorama, or function types or flags not as
    `_call_types_once` expects: that fix alone left out)."""
    if os.environ.get("SOFTRAS_NUMBA_FIXES", "1") == "0":
        return False
    from numba.core import analysis as numba_analysis, inline_closurecall, ir as numba_ir, ir_utils, ssa as numba_ssa
    from numba.core import errors as numba_errors, targetconfig
    from numba.core.types import functions as numba_functions

    inliner = inline_closurecall if inliner is None else inliner
    passes = ir_utils if passes is None else passes
    ssa = numba_ssa if ssa is None else ssa
    ir = numba_ir if ir is None else ir
    analysis = numba_analysis if analysis is None else analysis
    config = targetconfig if config is None else config
    errors = numba_errors if errors is None else errors
    functions = numba_functions if functions is None else functions
    target_config = getattr(config, "TargetConfig", None)
    worker = getattr(inliner, "InlineWorker", None)
    inline_ir = getattr(worker, "inline_ir", None)
    run_untyped = getattr(worker, "run_untyped_passes", None)
    if getattr(inline_ir, "_softras", False):
        return True
    if inline_ir is None or run_untyped is None or getattr(inliner, "copy", None) is not copy \
            or getattr(passes, "copy", None) is not copy or not hasattr(passes, "copy_propagate") \
            or not all(hasattr(ssa, name) for name in _SSA_NAMES) or not hasattr(ir, "Block") \
            or not hasattr(analysis, "compute_live_map") \
            or not all(callable(getattr(target_config, name, None)) for name in ("values", "__hash__")):
        return False
    shared = _InlinerCopy()

    @functools.wraps(inline_ir)
    def _inline_ir_sharing_one_memo(*args, **kwargs):
        outer = shared.memo, shared.made
        shared.memo, shared.made = {}, set()
        try:
            return inline_ir(*args, **kwargs)
        finally:
            shared.memo, shared.made = outer

    _inline_ir_sharing_one_memo._softras = True
    worker.inline_ir = _inline_ir_sharing_one_memo
    worker.run_untyped_passes = _run_untyped_passes_once(run_untyped)
    inliner.copy = shared
    passes.copy = _PassesCopy()
    ssa._run_ssa, ssa._run_block_rewrite = _ssa_where_named(ssa._run_ssa, ssa._run_block_rewrite, ir.Block)
    analysis.compute_live_map = _live_map_with_bitsets(analysis.compute_live_map)
    target_config.values = _fast_values(target_config.values)
    target_config.__hash__ = _fast_hash(target_config.__hash__)
    scheme = getattr(errors, "HighlightColorScheme", None)          # (only where colorama is installed)
    markup = getattr(scheme, "_markup", None)
    reset = getattr(getattr(errors, "Style", None), "RESET_ALL", None)
    if callable(markup) and isinstance(reset, str) and markup.__defaults__ is not None \
            and len(markup.__defaults__) == 2:
        scheme._markup = _plain_markup(markup, reset)
    function_type = getattr(functions, "BaseFunction", None)
    stack = getattr(config, "ConfigStack", None)
    if all(callable(getattr(function_type, name, None)) for name in ("get_call_type", "get_impl_key")) \
            and callable(getattr(stack, "top_or_none", None)) and not hasattr(function_type.get_call_type, "memo"):
        function_type.get_call_type = _call_types_once(function_type.get_call_type, stack)
    return True


def _call_types_once(get_call_type, stack):
    """``BaseFunction.get_call_type(self, context, args, kws)`` resolving each
    call once: the signature numba resolved for the function type ``self``
    in the typing context, with these argument types, under the compile
    flags on top of ``stack`` (`numba.core.targetconfig.ConfigStack`), and
    the implementation key numba recorded for it in ``self._impl_keys``
    (what lowering calls); on a repeat that signature is returned and that
    key recorded again (another compile's flags may have recorded
    another).  A call that raises is not kept, nor one whose types do not
    hash; the ``memo`` and the count of ``hits`` are the wrapper's
    attributes."""

    memo = {}

    @functools.wraps(get_call_type)
    def get_call_type_once(self, context, args, kws):
        try:
            key = (self, context, tuple(args), tuple(kws.items()), stack.top_or_none())
            found = memo.get(key)
        except TypeError:                       # (a type that does not hash: numba's own, every time)
            return get_call_type(self, context, args, kws)
        if found is not None:
            get_call_type_once.hits += 1
            signature, impl_key = found
            self._impl_keys[signature.args] = impl_key
            return signature
        signature = get_call_type(self, context, args, kws)
        if signature is not None:
            memo[key] = signature, self._impl_keys[signature.args]
        return signature

    get_call_type_once.memo = memo
    get_call_type_once.hits = 0
    return get_call_type_once


def _plain_markup(markup, reset: str):
    """``HighlightColorScheme._markup(msg, color=None, style=<bright>)``
    without colorama's stream set-up: the colour and style codes (those
    given), the message and ``reset``, encoded to UTF-8 and decoded as
    numba's (same defaults)."""

    @functools.wraps(markup)
    def plain_markup(self, msg, color=None, style=markup.__defaults__[1]):
        features = (color or "") + (style or "")
        return (features.encode("utf-8") + msg.encode("utf-8") + reset.encode("utf-8")).decode("utf-8")

    return plain_markup


@functools.cache
def _plain_options(cls) -> tuple | None:
    """((name, default), ...) of the options of the `TargetConfig` class
    ``cls``, when each option's attribute is the property numba generates
    for it (whose getter returns ``self._values.get(name, option.default)``); else
    None."""
    defaults = []
    for name, option in cls.options.items():
        attribute = next((klass.__dict__[name] for klass in cls.__mro__ if name in klass.__dict__), None)
        getter = getattr(attribute, "fget", None)
        if not isinstance(attribute, property) or not getattr(getter, "__qualname__", "").endswith(
                "make_prop.<locals>.getter"):
            return None
        defaults.append((name, option.default))
    return tuple(defaults)


def _fast_values(values):
    """``TargetConfig.values``: {option name: value}, from the flags'
    ``_values`` and the defaults where `_plain_options` knows them."""

    @functools.wraps(values)
    def fast_values(self):
        defaults = _plain_options(type(self))
        if defaults is None:
            return values(self)
        own = self._values
        return {name: own.get(name, default) for name, default in defaults}

    return fast_values


@functools.cache
def _names_hash(cls) -> int | None:
    """numba's hash of flags of the class ``cls``: that of its sorted option
    names (all that ``hash(tuple(sorted(self.values())))`` hashes: sorting a
    dict sorts its keys), where `_plain_options` knows the class; else None."""
    return None if _plain_options(cls) is None else hash(tuple(sorted(cls.options)))


def _fast_hash(hash_):
    """``TargetConfig.__hash__``: `_names_hash`, numba's where that is None."""

    @functools.wraps(hash_)
    def fast_hash(self):
        found = _names_hash(type(self))
        return hash_(self) if found is None else found

    return fast_hash


def _run_untyped_passes_once(run_untyped):
    """``InlineWorker.run_untyped_passes`` run once per function, caller's
    flags and pipeline in a process: the same IR, a copy for each call site
    (blocks copied shallowly, `numba.core.ir.FunctionIR.copy`; ``inline_ir``
    deep-copies them before it changes them) under a new function identity
    (the names of its inlined variables are made from it)."""
    frontends = {}

    @functools.wraps(run_untyped)
    def run_untyped_passes(self, func, enable_ssa=False):
        self.flags.enable_ssa = enable_ssa          # (as numba's sets it, on the caller's flags)
        key = (func, enable_ssa, self._compiler_pipeline, self.flags.summary())
        found = frontends.get(key)
        if found is None:
            found = frontends[key] = run_untyped(self, func, enable_ssa)
        ir = found.copy()
        ir.func_id = found.func_id.derive()
        return ir

    return run_untyped_passes


def _ssa_where_named(run_ssa, rewrite, block_type):
    """`numba.core.ssa`'s ``_run_ssa`` and ``_run_block_rewrite`` with the
    rewrite of one variable (``states["varname"]``) run only over the
    blocks whose statements name it (their ``list_vars``, which is what
    both rewrites look at), noted once per ``_run_ssa``: fixing one
    variable renames only that variable and adds phis of it, so the blocks
    that name each of the others stay the same.  The other blocks are
    returned as new blocks with the same statements, as the rewrite
    returns them."""
    index = {"names": None}

    @functools.wraps(run_ssa)
    def _run_ssa_indexed(blocks):
        names = defaultdict(set)
        for label, block in blocks.items():
            for stmt in block.body:
                for var in stmt.list_vars():
                    names[var.name].add(label)
        outer, index["names"] = index["names"], names
        try:
            return run_ssa(blocks)
        finally:
            index["names"] = outer

    @functools.wraps(rewrite)
    def _rewrite_where_named(blocks, states, handler):
        names = index["names"]
        if names is None or "varname" not in states:
            return rewrite(blocks, states, handler)
        named = names.get(states["varname"], ())
        rewritten = {}
        for label, block in blocks.items():
            if label in named:
                rewritten.update(rewrite({label: block}, states, handler))
            else:
                same = block_type(scope=block.scope, loc=block.loc)
                same.body = list(block.body)
                rewritten[label] = same
        return rewritten

    return _run_ssa_indexed, _rewrite_where_named


def _live_map_with_bitsets(compute_live_map):
    """`numba.core.analysis.compute_live_map` (the variables live at the
    entry of each block) with each set of names an int, a bit per name:
    the same fixed points (the reaching definitions and uses, in the CFG's
    topological order; then liveness pushed back to the predecessors, in
    reverse order), the same sets returned, in a dict over the same blocks
    in the same order."""

    @functools.wraps(compute_live_map)
    def compute_live_map_with_bitsets(cfg, blocks, var_use_map, var_def_map):
        bit: dict[str, int] = {}

        def mask(names) -> int:
            m = 0
            for name in names:
                b = bit.get(name)
                if b is None:
                    b = bit[name] = 1 << len(bit)
                m |= b
            return m

        topo_order = cfg.topo_order()
        offsets = [*blocks, *(offset for offset in topo_order if offset not in blocks)]
        uses = {offset: mask(var_use_map[offset]) for offset in offsets}
        defs = {offset: mask(var_def_map[offset]) for offset in offsets}
        successors = {offset: [out for out, _ in cfg.successors(offset)] for offset in topo_order}
        reach = defaultdict(int)
        changed = True
        while changed:
            changed = False
            for offset in topo_order:
                here = reach[offset] | defs[offset] | uses[offset]
                changed |= here != reach[offset]
                reach[offset] = here
                for out in successors[offset]:
                    grown = reach[out] | here
                    changed |= grown != reach[out]
                    reach[out] = grown
        live = {offset: uses[offset] for offset in blocks}
        predecessors = {offset: [inc for inc, _ in cfg.predecessors(offset)] for offset in topo_order}
        changed = True
        while changed:
            changed = False
            for offset in reversed(topo_order):
                here = live[offset]
                for inc in predecessors[offset]:
                    grown = live[inc] | (here & reach[inc] & ~defs[inc])
                    changed |= grown != live[inc]
                    live[inc] = grown
        names = list(bit)
        return {offset: {names[i] for i in _bits(m)} for offset, m in live.items()}

    return compute_live_map_with_bitsets


def _bits(m: int):
    """The indices of the set bits of ``m`` >= 0, lowest first."""
    while m:
        low = m & -m
        yield low.bit_length() - 1
        m ^= low
