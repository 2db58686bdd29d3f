"""The CI recipe runs here: .github/workflows/conformance.yml cannot rot.

The workflow file is parsed (PyYAML, a test extra) and its jobs are run on
this machine the way GitHub Actions would run them: jobs in the order of
``needs``, every combination of a job's matrix, ``${{ }}`` expressions
substituted (matrix, inputs, github, env), ``if:`` conditions evaluated,
each ``run:`` step through ``bash --noprofile --norc -eo pipefail`` (the
workflow's ``shell: bash``) with the workflow's, job's and step's ``env``.
What cannot run here is replaced, and only that:

- ``uses:`` steps are emulated: ``actions/checkout`` makes the job's folder
  (the repository's top-level entries linked, ``golden/`` copied because a job
  writes it), ``actions/upload-artifact`` / ``actions/download-artifact``
  copy folders through a local artifact store with v4's rules (a name once,
  a missing path fails the step unless ``if-no-files-found`` says otherwise,
  ``pattern`` downloads each artifact into ``path/<name>/``). Any other action
  fails the test (teach the emulation first);
- ``apt-get`` steps are skipped (they install system packages: the static
  test checks the packages they name are installed on this machine) and
  ``pip install`` steps too (they would replace the Python environment that
  runs these tests): instead ``softras`` is this checkout's code, through
  ``PYTHONPATH`` and a ``softras`` script first on ``PATH``.

Every other ``run:`` step must be a plain ``softras`` command, and is run.
The workflow's ``CONFORMANCE_ARGS`` (its ``conformance_args`` dispatch input)
keeps the local run to a few cheap scenes.
"""

from __future__ import annotations

import fnmatch
import itertools
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest
import yaml

from softras.verification.golden import default_scenes

from conftest import REPO

WORKFLOW = REPO / ".github" / "workflows" / "conformance.yml"
ACTIONS = ("actions/checkout", "actions/upload-artifact", "actions/download-artifact")
# A few cheap scenes of scenes/ (each well under a second warm, on llvmpipe and softpipe).
CHEAP = ["culling_back", "extreme_1x1", "fill_rule_grid", "orthographic_camera", "tiny_triangles"]
CHEAP_ARGS = " ".join(f"-k {name}" for name in CHEAP)
STEP_TIMEOUT = 1200


class WorkflowError(Exception):
    """The workflow uses something this emulation does not know."""


def load_workflow(path: Path = WORKFLOW) -> dict:
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    if True in data:   # YAML 1.1 reads the key `on` as true
        data["on"] = data.pop(True)
    return data


# ---------------------------------------------------------------------------
# Expressions


EXPRESSION = re.compile(r"\$\{\{\s*(.*?)\s*\}\}")


def _value(token: str, context: dict):
    token = token.strip()
    if token.startswith("'") and token.endswith("'"):
        return token[1:-1]
    if token in ("true", "false"):
        return token == "true"
    if re.fullmatch(r"\d+", token):
        return int(token)
    if token == "always()":
        return True
    if token in ("success()", "failure()"):
        return (token == "failure()") == context["failed"]
    head, _, rest = token.partition(".")
    if head not in ("matrix", "inputs", "github", "env") or not rest or rest not in context[head]:
        raise WorkflowError(f"unknown expression {token!r}")
    return context[head][rest]


def evaluate(expression: str, context: dict):
    """The few expression forms the workflow may use: names, literals, ==, !=, !, && and ||."""
    if "||" in expression:
        return any(evaluate(part, context) for part in expression.split("||"))
    if "&&" in expression:
        return all(evaluate(part, context) for part in expression.split("&&"))
    expression = expression.strip()
    if expression.startswith("!") and not expression.startswith("!="):
        return not evaluate(expression[1:], context)
    for operator in ("==", "!="):
        if operator in expression:
            left, right = expression.split(operator, 1)
            equal = str(_value(left, context)) == str(_value(right, context))
            return equal if operator == "==" else not equal
    return _value(expression, context)


def substitute(text, context: dict) -> str:
    def text_of(value) -> str:
        return str(value).lower() if isinstance(value, bool) else str(value)
    return EXPRESSION.sub(lambda match: text_of(evaluate(match.group(1), context)), str(text))


def condition(text, context: dict) -> bool:
    """A job's or step's ``if:`` (with or without ``${{ }}``); none = ``success()``."""
    if text is None:
        return not context["failed"]
    text = str(text).strip()
    match = EXPRESSION.fullmatch(text)
    expression = match.group(1) if match else text
    result = bool(evaluate(expression, context))
    if not any(status in expression for status in ("always()", "failure()", "success()")):
        result = result and not context["failed"]        # GitHub adds success() when none is named
    return result


# ---------------------------------------------------------------------------
# Steps


def step_kind(step: dict) -> str:
    """``uses``, ``apt`` or ``pip`` (not run here, see the module's docstring), or ``softras``."""
    if "uses" in step:
        return "uses"
    command = str(step.get("run", "")).strip()
    if "\n" in command:
        raise WorkflowError(f"step {step.get('name')!r}: one command per step, not a script")
    if command.startswith("apt-get "):
        return "apt"
    if command.startswith("python -m pip install "):
        return "pip"
    if command.startswith("softras "):
        return "softras"
    raise WorkflowError(f"step {step.get('name')!r}: {command!r} is not apt-get, pip install or softras")


def apt_packages(command: str) -> list[str]:
    words = shlex.split(command.split("apt-get install", 1)[1])
    return [word for word in words if not word.startswith("-") and word != "&&"]


def matrix_combinations(job: dict) -> list[dict]:
    matrix = (job.get("strategy") or {}).get("matrix")
    if not matrix:
        return [{}]
    if set(matrix) & {"include", "exclude"}:
        raise WorkflowError("matrix include / exclude: teach the emulation first")
    keys = list(matrix)
    return [dict(zip(keys, values)) for values in itertools.product(*(matrix[key] for key in keys))]


@dataclass
class JobRun:
    job: str
    matrix: dict
    ok: bool = True
    skipped: bool = False
    steps: list = field(default_factory=list)     # (name, kind, status, output tail)

    def describe(self) -> str:
        lines = [f"job {self.job} {self.matrix}: {'ok' if self.ok else 'FAILED'}"]
        lines += [f"  {name} [{kind}]: {status}\n{tail}" for name, kind, status, tail in self.steps]
        return "\n".join(lines)


class LocalRunner:
    """Runs a workflow's jobs on this machine (see the module's docstring)."""

    def __init__(self, workflow: dict, root: Path, *, event: str = "push", inputs: dict | None = None,
                 artifacts: Path | None = None):
        self.workflow = workflow
        self.root = root
        self.artifacts = artifacts or root / "artifacts"
        self.artifacts.mkdir(parents=True, exist_ok=True)
        self.bin = root / "bin"
        self.bin.mkdir(exist_ok=True)
        shim = self.bin / "softras"
        shim.write_text(f'#!/bin/sh\nexec {shlex.quote(sys.executable)} -m softras "$@"\n')
        shim.chmod(0o755)
        self.github = {"event_name": event, "sha": "0" * 40, "run_id": "1", "ref": "refs/heads/main"}
        inputs = dict(inputs or {})
        for name, spec in (((workflow["on"] or {}).get("workflow_dispatch") or {}).get("inputs") or {}).items():
            inputs.setdefault(name, spec.get("default", "") if event == "workflow_dispatch" else "")
        self.inputs = inputs
        self.count = 0

    def context(self, matrix: dict, env: dict, failed: bool) -> dict:
        return {"matrix": matrix, "inputs": self.inputs, "github": self.github, "env": env, "failed": failed}

    def run(self, jobs: list[str] | None = None, *, stop_on_failure: bool = False) -> list[JobRun]:
        """Run the jobs (all, or those named) in the order of ``needs``; every matrix combination."""
        todo = dict(self.workflow["jobs"])
        order, done = [], set()
        while todo:
            ready = [name for name, job in todo.items() if set(_needs(job)) <= done]
            if not ready:
                raise WorkflowError(f"circular or unknown needs among {sorted(todo)}")
            for name in ready:
                order.append(name)
                done.add(name)
                del todo[name]
        runs, outcome = [], {}
        for name in order:
            if jobs is not None and name not in jobs:
                continue
            job = self.workflow["jobs"][name]
            needed_failed = any(not outcome.get(need, True) for need in _needs(job))
            workflow_env = {key: substitute(value, self.context({}, {}, False))
                            for key, value in (self.workflow.get("env") or {}).items()}
            outcome[name] = True
            for matrix in matrix_combinations(job):
                context = self.context(matrix, workflow_env, needed_failed)
                if not condition(job.get("if"), context):
                    runs.append(JobRun(name, matrix, skipped=True))
                    continue
                run = self.run_job(name, job, matrix, workflow_env)
                runs.append(run)
                outcome[name] = outcome[name] and run.ok
                if stop_on_failure and not run.ok:
                    return runs
        return runs

    def run_job(self, name: str, job: dict, matrix: dict, workflow_env: dict) -> JobRun:
        self.count += 1
        work = self.root / f"job-{self.count}-{name}"
        work.mkdir()
        env = dict(workflow_env)
        context = self.context(matrix, env, False)
        env.update({key: substitute(value, context) for key, value in (job.get("env") or {}).items()})
        shell = ((self.workflow.get("defaults") or {}).get("run") or {}).get("shell")
        if shell != "bash":
            raise WorkflowError(f"defaults.run.shell is {shell!r}: the emulation runs bash")
        run = JobRun(name, matrix)
        for number, step in enumerate(job["steps"]):
            title = step.get("name") or step.get("uses") or step.get("run")
            context = self.context(matrix, env, not run.ok)
            if not condition(step.get("if"), context):
                run.steps.append((title, step_kind(step), "not run", ""))
                continue
            step_env = env | {key: substitute(value, context) for key, value in (step.get("env") or {}).items()}
            kind = step_kind(step)
            if kind == "uses":
                status, tail = self.action(step, work, context)
            elif kind in ("apt", "pip"):
                status, tail = "skipped here", ""
            else:
                status, tail = self.command(substitute(step["run"], context), work, step_env, number)
            run.steps.append((title, kind, status, tail))
            if status not in ("ok", "skipped here"):
                run.ok = False
        return run

    def command(self, command: str, work: Path, env: dict, number: int) -> tuple[str, str]:
        script = work.parent / f"{work.name}-step{number}.sh"
        script.write_text(command + "\n")
        # (Without NUMBA_CACHE_DIR: numba files a cache there by the source
        # folder's path as imported, and a job imports softras through its
        # folder of links, so each job compiled every kernel again, ten
        # minutes of a suite run with it set; without it numba's cache is
        # the checkout's __pycache__, shared through the links, docs/speed.md,
        # "Measuring a cold suite".  scripts/mutate.py does the same.)
        full = {key: value for key, value in os.environ.items() if key not in ("GALLIUM_DRIVER", "NUMBA_CACHE_DIR")}
        full |= env
        full["PATH"] = f"{self.bin}{os.pathsep}{os.environ.get('PATH', '')}"
        full["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))
        began = time.monotonic()
        done = subprocess.run(["bash", "--noprofile", "--norc", "-eo", "pipefail", str(script)], cwd=work,
                              env=full, capture_output=True, text=True, timeout=STEP_TIMEOUT)
        tail = f"$ {command}  ({time.monotonic() - began:.1f} s)\n" + (done.stdout + done.stderr)[-3000:]
        return ("ok" if done.returncode == 0 else f"exit {done.returncode}"), tail

    def action(self, step: dict, work: Path, context: dict) -> tuple[str, str]:
        action, _, version = step["uses"].partition("@")
        options = {key: substitute(value, context) for key, value in (step.get("with") or {}).items()}
        if action == "actions/checkout":
            for entry in REPO.iterdir():
                if entry.name in (".git",) or entry.name.startswith("."):
                    continue
                if entry.name == "golden":
                    shutil.copytree(entry, work / entry.name)     # the golden job writes it
                else:
                    (work / entry.name).symlink_to(entry)
            return "ok", ""
        if action == "actions/upload-artifact":
            name, source = options["name"], work / options["path"]
            if (self.artifacts / name).exists():
                return "failed", f"upload-artifact: an artifact named {name} exists already"
            if not source.exists():
                if options.get("if-no-files-found", "warn") == "error":
                    return "failed", f"upload-artifact: no files at {options['path']}"
                return "ok", f"upload-artifact: no files at {options['path']}"
            shutil.copytree(source, self.artifacts / name)
            return "ok", ""
        if action == "actions/download-artifact":
            target = work / options.get("path", ".")
            if "name" in options:
                names = [options["name"]] if (self.artifacts / options["name"]).exists() else []
            else:
                names = sorted(path.name for path in self.artifacts.iterdir()
                               if fnmatch.fnmatchcase(path.name, options.get("pattern", "*")))
            if not names:
                return "failed", f"download-artifact: no artifact matches {options}"
            merge = str(options.get("merge-multiple", "false")).lower() == "true"
            for name in names:
                into = target if "name" in options or merge else target / name
                shutil.copytree(self.artifacts / name, into, dirs_exist_ok=True)
            return "ok", ""
        raise WorkflowError(f"the action {step['uses']} is not emulated here")


def _needs(job: dict) -> list[str]:
    needs = job.get("needs") or []
    return [needs] if isinstance(needs, str) else list(needs)


def softras_commands(workflow: dict) -> list[tuple[str, dict, str]]:
    """(job, matrix, command with expressions substituted) for every softras step of every combination."""
    found = []
    runner_context = {"inputs": {"conformance_args": "", "golden": True},
                      "github": {"event_name": "workflow_dispatch", "sha": "0" * 40, "run_id": "1",
                                 "ref": "refs/heads/main"}, "env": {}, "failed": False}
    for name, job in workflow["jobs"].items():
        for matrix in matrix_combinations(job):
            for step in job["steps"]:
                if step_kind(step) == "softras":
                    found.append((name, matrix, substitute(step["run"], runner_context | {"matrix": matrix})))
    return found


# ---------------------------------------------------------------------------
# The workflow's shape, without running it


def test_the_workflow_is_the_documented_recipe():
    workflow = load_workflow()
    assert {"push", "pull_request", "workflow_dispatch"} <= set(workflow["on"])
    assert set(workflow["on"]["workflow_dispatch"]["inputs"]) == {"conformance_args", "golden"}
    assert workflow["env"]["CONFORMANCE_ARGS"] == "${{ inputs.conformance_args }}"
    jobs = workflow["jobs"]
    assert set(jobs) == {"shard", "merge", "golden"}
    matrix = jobs["shard"]["strategy"]["matrix"]
    assert matrix["driver"] == ["llvmpipe", "softpipe"]
    assert jobs["shard"]["env"]["GALLIUM_DRIVER"] == "${{ matrix.driver }}"
    assert jobs["merge"]["needs"] == "shard" and jobs["merge"]["strategy"]["matrix"]["driver"] == matrix["driver"]
    assert "workflow_dispatch" in jobs["golden"]["if"]
    commands = softras_commands(workflow)
    shards = [command for job, _, command in commands if job == "shard" and "--shard" in command]
    counts = {re.search(r"--shard (\d+)/(\d+)", command).group(2) for command in shards}
    assert counts == {str(len(matrix["shard"]))} and matrix["shard"] == list(range(1, len(matrix["shard"]) + 1))
    assert len(shards) == len(matrix["shard"]) * len(matrix["driver"])
    assert any("--merge" in command for job, _, command in commands if job == "merge")
    assert any(command.startswith("softras golden --update") for job, _, command in commands if job == "golden")


def test_every_step_is_an_emulated_action_or_a_plain_command():
    workflow = load_workflow()
    for job in workflow["jobs"].values():
        assert job.get("container", "").startswith("python:3.11")       # Python 3.11, Debian's Mesa
        for step in job["steps"]:
            kind = step_kind(step)                                      # raises on anything else
            if kind == "uses":
                action, _, version = step["uses"].partition("@")
                assert action in ACTIONS and re.fullmatch(r"v\d+", version), step["uses"]
            if kind == "pip":
                assert step["run"].split()[-1] in (".", "'.[test]'"), step["run"]


def test_every_softras_command_parses():
    from softras.cli import build_parser

    parser = build_parser()
    for job, matrix, command in softras_commands(load_workflow()):
        words = [word for word in shlex.split(command.replace("$CONFORMANCE_ARGS", ""))]
        words = [word if "*" not in word else word.replace("*", "1") for word in words]
        try:
            parser.parse_args(words[1:])
        except SystemExit:
            pytest.fail(f"job {job} {matrix}: softras rejects {command!r}")


def test_the_apt_packages_are_the_ones_this_machine_runs_on():
    if shutil.which("dpkg-query") is None:
        pytest.skip("dpkg-query: not a Debian machine, the package names cannot be checked here")
    workflow = load_workflow()
    packages = {package for job in workflow["jobs"].values() for step in job["steps"]
                if step_kind(step) == "apt" for package in apt_packages(step["run"])}
    assert {"libegl1", "libegl-mesa0", "libgl1-mesa-dri"} <= packages
    for package in sorted(packages):
        done = subprocess.run(["dpkg-query", "-W", "-f", "${Status}", package], capture_output=True, text=True)
        assert "install ok installed" in done.stdout, f"{package}: not installed here ({done.stderr.strip()})"


def test_expressions():
    context = {"matrix": {"shard": 2}, "inputs": {"golden": False, "x": "-k a"}, "github": {"event_name": "push"},
               "env": {}, "failed": False}
    assert substitute("--shard ${{ matrix.shard }}/4 ${{ inputs.x }}", context) == "--shard 2/4 -k a"
    assert condition("github.event_name == 'workflow_dispatch' && inputs.golden", context) is False
    assert condition("always()", context | {"failed": True}) is True
    assert condition(None, context | {"failed": True}) is False
    with pytest.raises(WorkflowError):
        substitute("${{ secrets.TOKEN }}", context)


# ---------------------------------------------------------------------------
# Running it: the merge job on synthetic shards (no GL), the whole workflow (GL)


def _synthetic_shard_artifacts(folder: Path) -> Path:
    from test_merge import write_shard

    for driver, renderer in (("llvmpipe", "llvmpipe (LLVM 15.0.6, 256 bits), OpenGL 4.5"),
                             ("softpipe", "softpipe, OpenGL 3.3")):
        for index in range(1, 5):
            write_shard(folder / f"report-{driver}-{index}", index, 4, gl=renderer)
    return folder


def test_the_merge_job_runs_on_shard_artifacts(tmp_path):
    artifacts = _synthetic_shard_artifacts(tmp_path / "artifacts")
    runner = LocalRunner(load_workflow(), tmp_path, artifacts=artifacts)
    runs = runner.run(["merge"])
    assert [run.matrix["driver"] for run in runs] == ["llvmpipe", "softpipe"]
    assert all(run.ok for run in runs), "\n".join(run.describe() for run in runs)
    for driver in ("llvmpipe", "softpipe"):
        data = json.loads((artifacts / f"report-{driver}" / "results.json").read_text())
        assert data["gl_renderer"].startswith(driver) and data["summary"]["total"] == 7


@pytest.mark.parametrize("job, old, new", [
    ("merge", "--merge shards/report-", "--merge shards/reports-"),      # a wrong folder name
    ("merge", "--report report-${{ matrix.driver }}", "--reportt report-${{ matrix.driver }}"),
    pytest.param("shard", "--shard ${{ matrix.shard }}/4", "--shard ${{ matrix.shard }}/0",
                 marks=pytest.mark.gl),                                    # its `softras info` step needs GL
])
def test_a_broken_step_fails_the_local_run(tmp_path, job, old, new):
    workflow = load_workflow()
    step = next(step for step in workflow["jobs"][job]["steps"] if old in str(step.get("run", "")))
    step["run"] = step["run"].replace(old, new)
    artifacts = _synthetic_shard_artifacts(tmp_path / "artifacts")
    runs = LocalRunner(workflow, tmp_path, artifacts=artifacts).run([job], stop_on_failure=True)
    assert not runs[-1].ok
    failed = [(name, status) for name, kind, status, _ in runs[-1].steps if status not in ("ok", "skipped here")]
    assert failed and failed[0] == (step["name"], "exit 2"), runs[-1].describe()


@pytest.mark.gl
def test_the_whole_workflow_runs_here(tmp_path):
    start = time.time() - 1

    def written_into_checkout() -> list[str]:
        skip = {".git", "__pycache__", ".pytest_cache", ".hypothesis"}
        return [str(path) for path in REPO.rglob("*") if not skip & set(path.relative_to(REPO).parts)
                and not path.is_symlink() and path.is_file() and path.stat().st_mtime > start]

    runner = LocalRunner(load_workflow(), tmp_path, event="workflow_dispatch",
                         inputs={"conformance_args": CHEAP_ARGS, "golden": True})
    runs = runner.run()
    report = "\n".join(run.describe() for run in runs)
    print(report)
    assert all(run.ok and not run.skipped for run in runs), report
    assert [run.job for run in runs].count("shard") == 8 and [run.job for run in runs].count("merge") == 2
    artifacts = runner.artifacts
    for driver in ("llvmpipe", "softpipe"):
        data = json.loads((artifacts / f"report-{driver}" / "results.json").read_text())
        assert [scene["name"] for scene in data["scenes"]] == CHEAP
        assert driver in data["gl_renderer"]
        assert [item["shard"] for item in data["merged"]["reports"]] == ["1/4", "2/4", "3/4", "4/4"]
        for scene in data["scenes"]:
            for relative in scene["images"].values():
                assert (artifacts / f"report-{driver}" / relative).is_file()
    golden = artifacts / f"golden-{'0' * 40}"
    manifest = json.loads((golden / "manifest.json").read_text())
    assert "GL_RENDERER" in manifest["provenance"]
    assert len(manifest["images"]) == len(default_scenes(REPO / "scenes"))     # JSON and glTF scenes
    assert written_into_checkout() == []
