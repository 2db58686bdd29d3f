"""The first run on a machine says that it compiles (`softras.cli.announce_compilation`).

numba compiles the kernels on a cache miss (a fresh clone, an edited
kernel) for minutes; the command line prints one line when that starts,
once per process, and nothing when every kernel comes from the cache.
Each test runs in a fresh interpreter, since the notice is installed once
per process.
"""

from __future__ import annotations

import subprocess
import sys

from softras import cli
from softras.kernels import prepare

_PROGRAM = r"""
import io, sys
import numba
from softras import cli

class Terminal(io.StringIO):
    def isatty(self):
        return True

out = Terminal()
cli.announce_compilation(out)
cli.announce_compilation(out)                # installed once

@numba.njit(cache=False)
def f(x):
    return x + 1

@numba.njit(cache=False)
def g(x):
    return x * 2

assert f(1) == 2 and g(2) == 4 and f(2.5) == 3.5   # three compilations
sys.stdout.write(out.getvalue())
"""


def _run(program: str) -> str:
    done = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_one_line_on_the_first_compilation_only():
    assert _run(_PROGRAM) == cli.COMPILE_NOTICE + "\n"


def test_nothing_when_nothing_compiles():
    program = _PROGRAM.split("@numba.njit")[0] + "sys.stdout.write(out.getvalue())\n"
    assert _run(program) == ""


def test_nothing_on_a_stream_that_is_not_a_terminal():
    program = _PROGRAM.replace("def isatty(self):\n        return True", "def isatty(self):\n        return False")
    assert _run(program) == ""


def test_a_background_preparation_is_said_once_instead():
    """A render that leaves the kernels to a background process says so, and
    the stages' own compilations after it add nothing."""
    program = _PROGRAM.replace("cli.announce_compilation(out)                # installed once",
                               "from softras.kernels import prepare\nprepare.announce(prepare.NOTICE)")
    assert "prepare.announce(prepare.NOTICE)" in program
    assert _run(program) == prepare.NOTICE + "\n"
