"""The conformance scenes on two GL implementations (docs/verification.md).

- this process's GL (llvmpipe here) under the spec profile: every scene
  within the bounds; on the implementation softras reproduces, all PASS;
- Mesa's softpipe (GALLIUM_DRIVER=softpipe, an independent GL 3.3 core
  rasterizer installed wherever llvmpipe is), in a child process through the
  command line, profile auto (= spec there): no FAIL, NOT SUPPORTED only for
  what the context lacks.

Nothing here special-cases softpipe: it gets the same bounds as any GL, from
its own capability record (4 sub-pixel bits, 1 sample).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import glref
from softras.verification import conformance, verifier
from softras.scene import scene_files

from conftest import REPO, SCENES

pytestmark = pytest.mark.gl


def test_spec_profile_on_this_gl():
    results = conformance.run([Path(p) for p in scene_files([SCENES])], profile="spec")
    failed = {r.name: r.reasons for r in results if r.verdict == verifier.FAIL}
    assert not failed
    if verifier.reproduces(glref.info()):
        assert {r.name: r.verdict for r in results if r.verdict != verifier.PASS} == {}


def test_softpipe_gives_no_failure(tmp_path):
    env = dict(os.environ, GALLIUM_DRIVER="softpipe")
    env.pop("SOFTRAS_GL_DEVICE", None)
    report = tmp_path / "report"
    run = subprocess.run([sys.executable, "-m", "softras", "conformance", "--report", str(report)],
                         cwd=REPO, env=env, capture_output=True, text=True, timeout=1200)
    results = json.loads((report / "results.json").read_text())
    failed = {s["name"]: s["reasons"] for s in results["scenes"] if s["verdict"] == verifier.FAIL}
    assert not failed, run.stdout[-4000:]
    assert run.returncode == 0, run.stderr[-2000:]
    gl = results["gl"]
    assert results["profile"].startswith("auto: spec") or verifier.reproduces(gl)
    for scene in results["scenes"]:
        if scene["verdict"] == verifier.NOT_SUPPORTED:
            assert "cannot draw" in scene["reasons"][0]
    assert results["summary"]["total"] == len(scene_files([SCENES]))
