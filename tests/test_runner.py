"""Tests for the conformance runner (softras.verification.runner) and ``softras conformance``'s
crash isolation, time limits, retries, baselines, interruption and resume.

Faults are injected with the test-only SOFTRAS_TEST_FAULT variable, read in
the workers only (crash with SIGSEGV, hang, raise inside the render, exit with
status 3, crash on the first attempt only; a hanging worker leaves its pid in
SOFTRAS_TEST_FAULT_DIR so a test can kill it from outside, as the kernel's
out-of-memory killer would). Scenes are tiny triangles written to tmp_path,
named for their fault. Tests that start workers (and so render with glref)
carry the ``gl`` marker; the rest run without GL.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest

from softras.verification import runner
from softras.cli import build_parser, main
from softras.verification.conformance import CRASH, FAIL, FLAKY, NOT_SUPPORTED, PASS, TIMEOUT, WARN, SceneResult

from conftest import REPO

PIXELS = {"projection": "orthographic", "left": 0, "right": 16, "bottom": 0, "top": 12, "near": -1, "far": 1}


def triangle() -> dict:
    """A 16x12 vertex-coloured triangle (softras and llvmpipe agree exactly)."""
    return {"softras_scene": 1, "width": 16, "height": 12, "background": [0, 0, 0, 1], "camera": PIXELS,
            "nodes": [{"name": "triangle",
                       "mesh": {"positions": [[1.3, 1.2, 0], [14.6, 2.1, 0], [6.2, 10.7, 0]],
                                "colors": [[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1]]}}]}


def write_scenes(folder: Path, names) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for name in names:
        path = folder / f"{name}.json"
        path.write_text(json.dumps(triangle()), encoding="utf-8")
        paths.append(path)
    return paths


@pytest.fixture
def faults(monkeypatch, tmp_path):
    """``faults("crash:a,hang:b")`` sets SOFTRAS_TEST_FAULT for the workers; returns the marker folder."""
    folder = tmp_path / "fault-markers"
    folder.mkdir()
    monkeypatch.setenv(runner.FAULT_DIR_ENV, str(folder))

    def set_faults(spec: str) -> Path:
        monkeypatch.setenv(runner.FAULT_ENV, spec)
        return folder

    return set_faults


@pytest.fixture
def watchdog():
    """Fail a run that does not end (a supervisor bug) instead of hanging the suite: SIGALRM after 120 s."""
    def expire(signum, frame):
        raise TimeoutError("the run did not end within the test's 120 s watchdog")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(120)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


def result(name: str, verdict: str, reason: str = "why", seconds: float = 0.1, **kw) -> SceneResult:
    return SceneResult(name=name, path=f"{name}.json", verdict=verdict, reasons=[reason], seconds=seconds, **kw)


def by_name(results) -> dict:
    return {r.name: r for r in (results.values() if isinstance(results, dict) else results)}


# ---------------------------------------------------------------------------
# Pure parts: attempts, faults, sizes, memory, baselines


def test_attempts_with_one_verdict_keep_it_and_a_changed_verdict_is_flaky():
    assert runner.combine_attempts([result("a", PASS)]).attempts == []          # one attempt: as it is
    same = runner.combine_attempts([result("a", CRASH, "died"), result("a", CRASH, "died again")])
    assert same.verdict == CRASH and same.failed() and [a["verdict"] for a in same.attempts] == [CRASH, CRASH]
    assert same.reasons[0] == "died again" and same.reasons[-1] == "the same verdict in all 2 attempts"
    assert same.seconds == pytest.approx(0.2)
    flaky = runner.combine_attempts([result("a", CRASH, "died"), result("a", PASS, "identical to GL")])
    assert flaky.verdict == FLAKY and not flaky.failed()                     # conformed once: not a failure
    assert flaky.reasons == ["verdict changed between attempts: CRASH, PASS", "attempt 1: CRASH: died",
                             "attempt 2: PASS: identical to GL"]
    assert flaky.attempts[0] == {"attempt": 1, "verdict": CRASH, "reasons": ["died"], "seconds": 0.1}
    never = runner.combine_attempts([result("a", CRASH), result("a", TIMEOUT), result("a", FAIL)])
    assert never.verdict == FLAKY and never.failed()                         # never conformed: fails the run


def test_fault_specification():
    assert runner.parse_faults("crash:a, hang:b,,raise:c") == {"a": "crash", "b": "hang", "c": "raise"}
    assert runner.parse_faults("") == {}
    for bad in ("explode:a", "crash", "crash:"):
        with pytest.raises(ValueError, match=runner.FAULT_ENV):
            runner.parse_faults(bad)


def test_sizes():
    assert runner.parse_size("8G") == runner.parse_size("8GiB") == 8 * 2**30
    assert runner.parse_size("512m") == 512 * 2**20 and runner.parse_size("1.5G") == 3 * 2**29
    assert runner.parse_size("1000") == 1000
    assert runner.parse_size("50%") == runner.default_max_memory()
    for bad in ("", "G", "-1G", "12Q", "0", "nan", "inf"):
        with pytest.raises(runner.RunnerError, match="--max-memory"):
            runner.parse_size(bad)
    assert runner.format_size(1.5 * 2**30) == "1.5 GiB" and runner.format_size(340 * 2**20) == "340 MiB"


# Peak resident memory a check added to a warm worker (scripts/runner_memory.py,
# llvmpipe): (width, height, samples, triangles, texels) -> MiB.
MEASURED_MIB = {(256, 256, 1, 128, 0): 21, (512, 512, 1, 128, 0): 81, (1024, 1024, 1, 128, 0): 308,
                (2048, 2048, 1, 128, 0): 1206, (512, 512, 4, 128, 0): 135, (1024, 1024, 4, 128, 0): 530,
                (256, 256, 1, 20_000, 0): 90, (256, 256, 1, 180_000, 0): 360,
                (256, 256, 1, 128, 1024**2): 31, (256, 256, 1, 128, 4096**2): 235}


@pytest.mark.parametrize("case", sorted(MEASURED_MIB))
def test_memory_estimate_is_at_least_the_measured_peak(case):
    width, height, samples, triangles, texels = case
    estimate = runner.estimate_bytes({"pixels": width * height, "samples": samples, "primitives": triangles,
                                      "texels": texels})
    assert MEASURED_MIB[case] * 2**20 <= estimate <= 2 * MEASURED_MIB[case] * 2**20


def test_a_scene_over_the_memory_budget_is_refused_up_front(tmp_path):
    big = dict(triangle(), width=8192, height=8192, samples=4)
    (tmp_path / "huge.json").write_text(json.dumps(big), encoding="utf-8")
    start = time.perf_counter()
    seen = []
    outcome = runner.run([tmp_path / "huge.json"], max_memory=2 * 2**30, on_result=seen.append)
    assert time.perf_counter() - start < 5                  # no worker was started for it
    refused = outcome.results[str(tmp_path / "huge.json")]
    assert refused.verdict == NOT_SUPPORTED and not refused.failed() and seen == [refused]
    assert "refused up front" in refused.reasons[0] and "8192x8192, 4 samples" in refused.reasons[0]
    assert "over --max-memory 2.0 GiB" in refused.reasons[0]
    assert refused.figures["estimated_bytes"] > 30 * 2**30


BASELINE = """\
# llvmpipe: known issues
line_star,Fail          # Mesa's spelling
msaa_fan , not supported
texture_npot,QUALITY_WARNING
sometimes,Flake
crashy,CRASH
"""


def test_baseline_file_format():
    baseline = runner.parse_baseline(BASELINE, "llvmpipe.txt")
    assert baseline.expected == {"line_star": FAIL, "msaa_fan": NOT_SUPPORTED, "texture_npot": WARN,
                                 "sometimes": FLAKY, "crashy": CRASH}
    for text, message in [("a,FAIL\nb", "llvmpipe.txt:2: expected 'scene,VERDICT'"),
                          ("a,PASS", "llvmpipe.txt:1: 'PASS' is not an expected non-passing verdict"),
                          ("a,FAIL,x", "llvmpipe.txt:1: expected"), (",FAIL", "llvmpipe.txt:1: expected"),
                          ("a,FAIL\n\na,CRASH", "llvmpipe.txt:3: scene a is listed twice")]:
        with pytest.raises(runner.RunnerError, match=message):
            runner.parse_baseline(text, "llvmpipe.txt")


def test_baseline_comparison_and_exit_status():
    baseline = runner.parse_baseline(BASELINE)
    matching = [result("line_star", FAIL), result("msaa_fan", NOT_SUPPORTED), result("texture_npot", WARN),
                result("sometimes", PASS), result("crashy", CRASH), result("other", PASS), result("meh", WARN)]
    check = runner.compare_baseline(matching, baseline)
    assert check.matches and runner.exit_status(matching, check) == runner.EXIT_OK
    assert runner.exit_status(matching) == runner.EXIT_FAILED               # without a baseline: failures fail
    changed = [result("line_star", PASS), result("msaa_fan", NOT_SUPPORTED), result("texture_npot", FAIL),
               result("sometimes", CRASH), result("crashy", TIMEOUT), result("other", CRASH),
               runner.combine_attempts([result("meh", CRASH), result("meh", PASS)])]
    check = runner.compare_baseline(changed, baseline)
    assert check.new_failures == [("texture_npot", WARN, FAIL), ("crashy", CRASH, TIMEOUT), ("other", PASS, CRASH)]
    assert check.unexpected == [("line_star", FAIL, PASS)]                # an unexpected pass
    assert runner.exit_status(changed, check) == runner.EXIT_FAILED
    assert "baseline: unexpected: line_star: expected FAIL, got PASS" in check.lines()
    assert "baseline: new failure: other: expected PASS, got CRASH" in check.lines()
    assert runner.exit_status(changed, check, interrupted=True) == runner.EXIT_INTERRUPTED
    # A report's failures.csv is a baseline its own results match.
    again = runner.parse_baseline(runner.failures_csv(changed, "title"))
    assert runner.compare_baseline(changed, again).matches
    assert "other" in again.expected and "msaa_fan" in again.expected and "sometimes" in again.expected


def test_sigterm_interrupts_like_ctrl_c():
    previous = signal.getsignal(signal.SIGTERM)
    with pytest.raises(KeyboardInterrupt):
        with runner.interrupts():
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)
    assert signal.getsignal(signal.SIGTERM) == previous


def test_default_timeout_of_the_command_is_the_runners():
    args = build_parser().parse_args(["conformance"])
    assert args.timeout == runner.DEFAULT_TIMEOUT and args.retries == 0 and args.max_memory is None


# ---------------------------------------------------------------------------
# The report written as scenes finish, and what --resume reads back (no GL)


def picture(seed: int) -> np.ndarray:
    image = np.random.default_rng(seed).integers(0, 255, size=(12, 16, 4), dtype=np.uint8)
    image[..., 3] = 255
    return image


def test_partial_report_is_valid_and_resumable(tmp_path):
    paths = [str(tmp_path / f"{name}.json") for name in ("a", "b", "c")]
    for path in paths:
        Path(path).write_text(json.dumps(triangle()), encoding="utf-8")
    options = runner.run_options(paths, profile="auto", timeout=10.0, retries=1, max_memory=2**30)
    report = tmp_path / "report"
    writer = runner.ReportWriter(report, paths, {"gl_renderer": "test GL", "options": options})
    writer.write()
    assert json.loads((report / "results.json").read_text())["pending"] == paths
    first = runner.combine_attempts([SceneResult(name="a", path=paths[0], verdict=CRASH, reasons=["died"]),
                                     SceneResult(name="a", path=paths[0], verdict=PASS, reasons=["same"],
                                                 images={"soft": picture(1), "gl": picture(2)})])
    writer.add(first)
    writer.add(SceneResult(name="b", path=paths[1], verdict=TIMEOUT, reasons=["no verdict within 10 s"]))
    writer.write(interrupted=True)
    data = json.loads((report / "results.json").read_text())
    assert data["complete"] is False and data["interrupted"] is True and data["pending"] == paths[2:]
    assert data["summary"]["flaky"] == 1 and data["summary"]["timeout"] == 1 and data["summary"]["total"] == 2
    assert not [p for p in report.iterdir() if p.name.startswith(".")]    # no temporary file left
    suite = ElementTree.parse(report / "junit.xml").getroot()
    assert suite.get("tests") == "2" and suite.get("errors") == "1" and suite.get("failures") == "0"
    cases = {case.get("name"): case for case in suite.iter("testcase")}
    assert cases["b"].find("error").get("type") == "timeout"
    flaky = cases["a"].find("flakyError")                                  # surefire: passed on a rerun
    assert flaky is not None and flaky.get("message") == "attempt 1: CRASH: died" and cases["a"].find("error") is None
    assert "incomplete (interrupted): 1 scene not run yet" in (report / "index.html").read_text()
    assert (report / "failures.csv").read_text().splitlines()[1:] == ["a,FLAKY", "b,TIMEOUT"]

    done, previous = runner.load_resume(report, paths, options)
    assert list(done) == paths[:2] and previous["gl_renderer"] == "test GL"
    assert done[paths[0]].verdict == FLAKY and done[paths[0]].attempts == first.attempts
    assert np.array_equal(done[paths[0]].images["soft"], picture(1))       # pictures read back
    for change, message in [({"retries": 0}, "that run used --retries 1, this one 0"),
                            ({"profile": "spec"}, "--profile auto, this one spec"),
                            ({"timeout": 5.0}, "--timeout 10.0, this one 5.0"),
                            ({"scenes": options["scenes"][:2]}, "that run checked 3 scenes, this one 2")]:
        with pytest.raises(runner.RunnerError, match=message):
            runner.load_resume(report, paths, options | change)
    with pytest.raises(runner.RunnerError, match="no results.json there"):
        runner.load_resume(tmp_path, paths, options)
    (tmp_path / "results.json").write_text("{not json")
    with pytest.raises(runner.RunnerError, match="cannot read results.json"):
        runner.load_resume(tmp_path, paths, options)
    (tmp_path / "results.json").write_text('{"softras_conformance": 1, "scenes": []}')
    with pytest.raises(runner.RunnerError, match="not a resumable run"):
        runner.load_resume(tmp_path, paths, options)


def test_bad_runner_input_is_status_2_and_writes_nothing(tmp_path, capsys):
    folder = tmp_path / "scenes"
    write_scenes(folder, ["a"])
    report = tmp_path / "report"
    (tmp_path / "bad.txt").write_text("a,MAYBE\n")
    (tmp_path / "not-a-report").mkdir()
    cases = [["--baseline", str(tmp_path / "missing.txt"), "--report", str(report)],
             ["--baseline", str(tmp_path / "bad.txt"), "--report", str(report)],
             ["--resume", str(tmp_path / "not-a-report")],
             ["--resume", str(tmp_path / "nowhere")],
             ["--resume", str(tmp_path / "not-a-report"), "--report", str(report)],
             ["--timeout", "-1", "--report", str(report)], ["--retries", "-2", "--report", str(report)],
             ["--max-memory", "lots", "--report", str(report)]]
    for args in cases:
        assert main(["conformance", str(folder), *args]) == 2, args
        err = capsys.readouterr().err.splitlines()
        assert len(err) == 1 and err[0].startswith("softras: error: "), (args, err)
    assert not report.exists() and not (tmp_path / "nowhere").exists()
    assert list((tmp_path / "not-a-report").iterdir()) == []


# ---------------------------------------------------------------------------
# Workers: crashes, hangs, kills, retries (GL)


def kill_when_hanging(markers: Path, name: str, timeout: float = 120.0) -> threading.Thread:
    """Kill the worker hanging on scene ``name`` with SIGKILL from outside, once it says where it is."""
    def killer():
        pid_file = markers / f"{name}.pid"
        end = time.monotonic() + timeout
        while not pid_file.exists() and time.monotonic() < end:
            time.sleep(0.05)
        time.sleep(0.1)
        os.kill(int(pid_file.read_text()), signal.SIGKILL)

    thread = threading.Thread(target=killer, daemon=True)
    thread.start()
    return thread


@pytest.mark.gl
def test_crashes_hangs_and_kills_cost_only_their_scene(tmp_path, faults, watchdog):
    """-j 2: each fault gives its scene CRASH / TIMEOUT / FAIL, workers restart, every other scene passes."""
    markers = faults("crash:b_crash,hang:c_hang,raise:d_raise,exit:e_exit,hang:f_killed")
    names = ["a_pass", "b_crash", "c_hang", "d_raise", "e_exit", "f_killed", "g_pass", "h_pass"]
    paths = write_scenes(tmp_path / "scenes", names)
    killer = kill_when_hanging(markers, "f_killed")
    finished = []
    outcome = runner.run(paths, jobs=2, timeout=5, on_result=finished.append)
    killer.join(1)
    results = by_name(outcome.results)
    assert not outcome.interrupted and outcome.pending == [] and sorted(r.name for r in finished) == names
    assert {name: r.verdict for name, r in results.items()} == {
        "a_pass": PASS, "b_crash": CRASH, "c_hang": TIMEOUT, "d_raise": FAIL, "e_exit": CRASH, "f_killed": CRASH,
        "g_pass": PASS, "h_pass": PASS}
    crash = results["b_crash"].reasons
    assert crash[0] == "the worker process died during the check: killed by signal SIGSEGV (Segmentation fault)"
    assert "| SOFTRAS_TEST_FAULT: crash on scene b_crash" in crash                # its last output ...
    assert any("Fatal Python error: Segmentation fault" in line for line in crash)  # ... with faulthandler's
    assert "| [softras worker" in crash[2] and "b_crash (attempt 1)" in crash[2]
    hang = results["c_hang"]
    assert hang.reasons[0] == "no verdict within 5 s (--timeout): the worker was killed"
    assert 5 <= hang.seconds < 9 and "| SOFTRAS_TEST_FAULT: hang on scene c_hang" in hang.reasons
    assert results["d_raise"].reasons[0].startswith("error: RuntimeError: SOFTRAS_TEST_FAULT: injected error")
    assert results["e_exit"].reasons[0] == "the worker process died during the check: exit status 3"
    assert results["f_killed"].reasons[0].startswith("the worker process died during the check: killed by signal "
                                                     "SIGKILL (Killed); the kernel's out-of-memory killer")
    for name in ("a_pass", "g_pass", "h_pass"):
        assert results[name].reasons == ["identical to GL"] and results[name].images["gl"].shape == (12, 16, 4)


@pytest.mark.gl
def test_retries_find_the_flaky_scene_and_keep_the_steady_ones(tmp_path, faults, watchdog):
    faults("flaky:a_flaky,crash:b_crash,raise:c_fail")
    paths = write_scenes(tmp_path / "scenes", ["a_flaky", "b_crash", "c_fail", "d_pass"])
    retried = []
    outcome = runner.run(paths, jobs=1, timeout=60, retries=2, on_retry=lambda r, n: retried.append((r.name, n)))
    results = by_name(outcome.results)
    flaky = results["a_flaky"]
    assert flaky.verdict == FLAKY and not flaky.failed()
    assert [a["verdict"] for a in flaky.attempts] == [CRASH, PASS]              # stops at the first pass
    assert flaky.reasons[0] == "verdict changed between attempts: CRASH, PASS"
    assert results["b_crash"].verdict == CRASH and len(results["b_crash"].attempts) == 3
    assert results["c_fail"].verdict == FAIL and [a["verdict"] for a in results["c_fail"].attempts] == [FAIL] * 3
    assert results["d_pass"].verdict == PASS and results["d_pass"].attempts == []    # never retried
    assert sorted(retried) == [("a_flaky", 1), ("b_crash", 1), ("b_crash", 2), ("c_fail", 1), ("c_fail", 2)]


# ---------------------------------------------------------------------------
# The command: baselines, interruption and resume (GL)


@pytest.mark.gl
def test_cli_baseline_match_and_mismatch(tmp_path, faults, capsys, watchdog):
    faults("crash:b_crash")
    folder = tmp_path / "scenes"
    write_scenes(folder, ["a_pass", "b_crash"])
    known = tmp_path / "known.txt"
    known.write_text("# llvmpipe\nb_crash,CRASH\n")
    report = tmp_path / "report"
    assert main(["conformance", str(folder), "--baseline", str(known), "--report", str(report)]) == 0
    out = capsys.readouterr().out
    assert f"baseline {known}: results match it" in out and "1 pass, 0 quality warning, 0 fail" in out
    data = json.loads((report / "results.json").read_text())
    assert data["baseline"]["matches"] is True and data["complete"] is True
    assert (report / "failures.csv").read_text().splitlines()[1:] == ["b_crash,CRASH"]

    stale = tmp_path / "stale.txt"
    stale.write_text("a_pass,FAIL\n")           # it passes now, and b_crash is not listed
    assert main(["conformance", str(folder), "--baseline", str(stale), "--report", str(report)]) == 1
    out = capsys.readouterr().out
    assert "baseline: new failure: b_crash: expected PASS, got CRASH" in out
    assert "baseline: unexpected: a_pass: expected FAIL, got PASS" in out
    assert f"baseline {stale}: 1 new failure, 1 unexpected verdict" in out
    data = json.loads((report / "results.json").read_text())["baseline"]
    assert data["new_failures"] == [{"scene": "b_crash", "expected": PASS, "got": CRASH}]
    assert data["unexpected"] == [{"scene": "a_pass", "expected": FAIL, "got": PASS}]


def comparable(data: dict) -> list[dict]:
    """results.json's scenes without what changes from run to run (times)."""
    scenes = []
    for scene in data["scenes"]:
        scene = dict(scene, seconds=None)
        scene["figures"] = {k: v for k, v in scene["figures"].items() if not k.endswith("_seconds")}
        scenes.append(scene)
    return scenes


@pytest.mark.gl
def test_sigint_leaves_a_partial_report_and_resume_completes_it(tmp_path, watchdog):
    """Ctrl-C during a hang: exit 130 and a valid partial report; --resume = an uninterrupted run."""
    folder = tmp_path / "scenes"
    write_scenes(folder, ["a", "b", "c_hang", "d"])
    report = tmp_path / "report"
    env = dict(os.environ, SOFTRAS_TEST_FAULT="hang:c_hang", PYTHONPATH=str(REPO))
    command = [sys.executable, "-m", "softras", "conformance", str(folder), "--timeout", "120"]
    # SIGINT's default action for the child, as a terminal gives it: a shell that starts a job in
    # the background (nohup, `&` without job control, some CI runners) sets it to ignored, and
    # POSIX keeps an ignored signal ignored across exec.
    process = subprocess.Popen(command + ["--report", str(report)], cwd=REPO, env=env,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        end = time.monotonic() + 120
        while time.monotonic() < end:    # until a and b are in the report
            try:
                if len(json.loads((report / "results.json").read_text())["scenes"]) == 2:
                    break
            except (OSError, ValueError, KeyError):
                pass
            time.sleep(0.2)
        time.sleep(0.5)                  # c_hang is running
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    finally:
        process.kill()
    assert process.returncode == 130, err[-2000:]
    assert "interrupted: 2 of 4 scenes finished, 2 not run; resume with: softras conformance" in out
    partial = json.loads((report / "results.json").read_text())
    assert partial["complete"] is False and partial["interrupted"] is True
    assert [s["name"] for s in partial["scenes"]] == ["a", "b"]
    assert [Path(p).name for p in partial["pending"]] == ["c_hang.json", "d.json"]
    assert ElementTree.parse(report / "junit.xml").getroot().get("tests") == "2"
    assert "incomplete (interrupted): 2 scenes not run yet" in (report / "index.html").read_text()
    before = (report / "a" / "gl.png").stat().st_mtime_ns

    assert main(["conformance", str(folder), "--timeout", "120", "--resume", str(report)]) == 0
    resumed = json.loads((report / "results.json").read_text())
    assert resumed["complete"] is True and resumed["pending"] == []
    assert (report / "a" / "gl.png").stat().st_mtime_ns == before          # finished scenes not redone
    reference = tmp_path / "reference"
    assert main(["conformance", str(folder), "--timeout", "120", "--report", str(reference)]) == 0
    assert comparable(resumed) == comparable(json.loads((reference / "results.json").read_text()))
    assert resumed["summary"] | {"seconds": 0} == json.loads((reference / "results.json").read_text())["summary"] | {
        "seconds": 0}
