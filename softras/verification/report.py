"""The conformance report: an HTML page, results.json and JUnit XML.

:func:`write_report` writes into a folder::

    index.html          one page: a summary banner, a table of all scenes, then one
                        section per scene with its pictures side by side
    results.json        the run and every scene's verdict, reasons and figures
    junit.xml           one <testcase> per scene (CI systems read it)
    <scene>/*.png       soft, gl, diff, ssim, flip, ambiguity, where
    failures.csv        (written by softras.verification.runner) every scene that did not pass,
                        ``name,VERDICT``: a --baseline for the next run

Failing scenes come first, then quality warnings, then passes, each marked
with a coloured badge, so the page says at a glance which scene failed, where
(the "where" picture: red pixels differ beyond the tolerance outside the
ambiguity mask, cyan inside it) and why (the reasons, naming the stage).

Every file is written atomically (:mod:`softras.scene.imageio`); files of other
scenes already in the folder are left alone. :mod:`softras.verification.runner` writes a
scene's pictures as it finishes (:func:`write_scene_images`) and the three
summary files after each scene (:func:`write_summary`), so an interrupted
run leaves a valid report of what finished (``"complete": false`` and the
``pending`` scenes in results.json).
"""

from __future__ import annotations

import html
import json
import os
from pathlib import Path
from xml.etree import ElementTree

from softras.verification.conformance import (CONFORMING, CRASH, FAIL, FLAKY, NOT_SUPPORTED, PASS, TIMEOUT, VERDICT_NAMES,
                                 VERDICT_ORDER, WARN, SceneResult, counts)

__all__ = ["FORMAT", "IMAGE_CAPTIONS", "write_report", "write_scene_images", "write_summary", "results_json",
           "junit_xml", "index_html"]

#: Version of results.json (2: the runner's verdicts crash, timeout and flaky, each scene's
#: ``attempts``, and ``complete`` / ``pending`` / ``options`` of the run).
FORMAT = 2

#: The pictures of a scene, in the order shown, with their captions.
IMAGE_CAPTIONS = {
    "soft": "softras (precision gl)",
    "gl": "GL (glref)",
    "diff": "difference: blue within threshold, red to white beyond",
    "where": "strict: beyond tolerance, red outside the ambiguity mask, cyan inside; "
             "spec: outside the bounds, red in softras, magenta in GL",
    "bound_lo": "spec: lower bound of a conformant picture",
    "bound_hi": "spec: upper bound of a conformant picture",
    "ssim": "SSIM map: 1 - SSIM, black = same structure",
    "flip": "FLIP map: black = no visible difference",
    "ambiguity": "ambiguity mask: coverage cyan, depth magenta, sampling yellow",
}

_COLOURS = {FAIL: "#c62828", WARN: "#ef8f00", NOT_SUPPORTED: "#607d8b", PASS: "#2e7d32",
            CRASH: "#4a148c", TIMEOUT: "#880e4f", FLAKY: "#795548"}

_CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em; color: #222; background: #fafafa; }
.banner { padding: 0.8em 1.2em; border-radius: 6px; color: white; font-size: 1.3em; }
.badge { display: inline-block; padding: 0.1em 0.5em; border-radius: 4px; color: white;
         font-weight: bold; font-size: 0.85em; }
table.summary { border-collapse: collapse; margin: 1em 0; }
table.summary td, table.summary th { padding: 0.25em 0.7em; border-bottom: 1px solid #ddd;
                                     text-align: left; vertical-align: top; font-size: 0.9em; }
section { background: white; margin: 1.2em 0; padding: 0.8em 1.2em; border-radius: 6px;
          border-left: 8px solid #999; }
section.fail { border-left-color: #c62828; background: #fff5f5; }
section.crash { border-left-color: #4a148c; background: #fbf5ff; }
section.timeout { border-left-color: #880e4f; background: #fff5fa; }
section.flaky { border-left-color: #795548; background: #fbf8f6; }
section.warn { border-left-color: #ef8f00; background: #fffaf0; }
section.pass { border-left-color: #2e7d32; }
.pictures { display: flex; flex-wrap: wrap; gap: 0.6em; }
figure { margin: 0; }
figure img { image-rendering: pixelated; border: 1px solid #bbb; background: #888; }
figcaption { font-size: 0.75em; max-width: 16em; color: #555; }
ul.reasons li { margin: 0.2em 0; }
.figures { font-size: 0.8em; color: #444; font-family: monospace; }
"""


def _image_paths(result: SceneResult) -> dict:
    return {name: f"{result.name}/{name}.png" for name in IMAGE_CAPTIONS if name in result.images}


def results_json(results: list[SceneResult], meta: dict) -> str:
    """results.json: ``{"softras_conformance": 2, "summary": {...}, ..., "scenes": [...]}``.

    ``summary`` has ``pass``, ``quality_warning``, ``fail``, ``not_supported``,
    ``crash``, ``timeout``, ``flaky``, ``total`` and ``seconds``; ``gl`` (in
    ``meta``) the GL's capability record; each scene is
    :meth:`SceneResult.to_dict` plus ``images`` (paths relative to the report
    folder), in the order of the run. The runner's ``meta`` adds ``complete``,
    ``interrupted``, ``pending`` (scenes not finished), ``options`` (what
    ``--resume`` checks) and ``baseline`` (the comparison with ``--baseline``).
    """
    scenes = []
    for result in results:
        entry = result.to_dict()
        entry["images"] = _image_paths(result)
        scenes.append(entry)
    data = {"softras_conformance": FORMAT, "summary": counts(results) | {"seconds": meta.get("seconds")}}
    data.update({key: value for key, value in meta.items() if key != "seconds"})
    data["scenes"] = scenes
    return json.dumps(data, indent=2) + "\n"


def _junit_kind(verdict: str) -> str:
    """``failure`` for FAIL, ``error`` for CRASH and TIMEOUT (the check never finished)."""
    return "error" if verdict in (CRASH, TIMEOUT) else "failure"


def _final_verdict(result: SceneResult) -> str:
    """The verdict of a FLAKY scene's last attempt (FAIL without attempts), else the scene's."""
    if result.verdict != FLAKY:
        return result.verdict
    return result.attempts[-1]["verdict"] if result.attempts else FAIL


def _junit_attempts(case, attempts: list[dict], prefix: str) -> None:
    """Maven surefire's rerun elements: ``<flakyFailure>`` / ``<rerunError>`` ... for each failing attempt."""
    for attempt in attempts:
        if attempt["verdict"] in CONFORMING:
            continue
        tag = prefix + ("Error" if _junit_kind(attempt["verdict"]) == "error" else "Failure")
        reasons = attempt.get("reasons") or []
        element = ElementTree.SubElement(case, tag, {
            "message": f"attempt {attempt['attempt']}: {VERDICT_NAMES[attempt['verdict']]}"
                       + (f": {reasons[0]}" if reasons else ""), "type": attempt["verdict"]})
        ElementTree.SubElement(element, "stackTrace").text = "\n".join(reasons)


def junit_xml(results: list[SceneResult], meta: dict) -> str:
    """JUnit XML: one ``<testsuite name="softras conformance">``, one ``<testcase>`` per scene.

    FAIL -> ``<failure>`` with the reasons; CRASH and TIMEOUT -> ``<error>``
    (type ``crash`` / ``timeout``: the check never finished); NOT SUPPORTED ->
    ``<skipped>`` with the reason; QUALITY WARNING -> a passing test case with
    ``<properties><property name="verdict" value="quality_warning">`` and the
    reasons in ``<system-out>`` (JUnit has no warning state). FLAKY follows
    Maven surefire's format for reruns (``rerunFailingTestsCount``): a scene
    that conformed on a later attempt is a passing test case with one
    ``<flakyFailure>`` / ``<flakyError>`` per failing attempt (readers that do
    not know these elements see a pass); one that never conformed is a
    ``<failure>`` / ``<error>`` (its last attempt) with ``<rerunFailure>`` /
    ``<rerunError>`` for the earlier ones.
    """
    tally = counts(results)
    kinds = [_junit_kind(_final_verdict(result)) for result in results if result.failed()]
    suite = ElementTree.Element("testsuite", {
        "name": "softras conformance", "tests": str(tally["total"]), "failures": str(kinds.count("failure")),
        "errors": str(kinds.count("error")), "skipped": str(tally[NOT_SUPPORTED]),
        "time": f"{meta.get('seconds') or 0:.3f}"})
    for result in results:
        case = ElementTree.SubElement(suite, "testcase", {
            "classname": "conformance", "name": result.name, "file": result.path,
            "time": f"{result.seconds:.3f}"})
        properties = ElementTree.SubElement(case, "properties")
        ElementTree.SubElement(properties, "property", {"name": "verdict", "value": result.verdict})
        text = "\n".join(result.reasons)
        if result.verdict in (FAIL, CRASH, TIMEOUT) or (result.verdict == FLAKY and result.failed()):
            last = _final_verdict(result)
            failure = ElementTree.SubElement(case, _junit_kind(last), {
                "message": result.reasons[0] if result.reasons else "failed",
                "type": "conformance" if last == FAIL else last})
            failure.text = text
            if result.verdict == FLAKY:
                _junit_attempts(case, result.attempts[:-1], "rerun")
        elif result.verdict == FLAKY:
            _junit_attempts(case, result.attempts, "flaky")
            ElementTree.SubElement(case, "system-out").text = f"{VERDICT_NAMES[result.verdict]}: {text}"
        elif result.verdict == NOT_SUPPORTED:
            ElementTree.SubElement(case, "skipped", {"message": text or "not supported"})
        else:
            ElementTree.SubElement(case, "system-out").text = f"{VERDICT_NAMES[result.verdict]}: {text}"
    ElementTree.indent(suite)
    return '<?xml version="1.0" encoding="utf-8"?>\n' + ElementTree.tostring(suite, encoding="unicode") + "\n"


def _figures_text(figures: dict) -> str:
    keys = ("ssim", "max_diff", "bad_pixels", "bad_fraction", "flip_mean", "bad_outside_mask",
            "bad_inside_mask", "differing_pixels", "coverage_mismatch_pixels", "ssim_excused",
            "outside_image", "outside_reference", "allowance_255")
    parts = []
    for key in keys:
        if key in figures:
            value = figures[key]
            parts.append(f"{key} {value:.5g}" if isinstance(value, float) else f"{key} {value}")
    if isinstance(figures.get("ambiguous_pixels"), int):
        parts.append(f"ambiguous px {figures['ambiguous_pixels']}")
    elif "ambiguous_pixels" in figures:
        amb = figures["ambiguous_pixels"]
        parts.append("ambiguous px " + ", ".join(f"{k} {v}" for k, v in amb.items()))
    times = [f"{key.replace('_seconds', '')} {figures[key]:.2f} s" for key in
             ("soft_seconds", "gl_seconds", "ambiguity_seconds", "bounds_seconds") if key in figures]
    if times:
        parts.append("time " + ", ".join(times))
    return " · ".join(parts)


def _badge(verdict: str) -> str:
    return f'<span class="badge" style="background:{_COLOURS[verdict]}">{VERDICT_NAMES[verdict]}</span>'


def index_html(results: list[SceneResult], meta: dict) -> str:
    """The report page (self-contained HTML, pictures referenced by relative path)."""
    esc = html.escape
    tally = counts(results)
    ordered = sorted(results, key=lambda r: (VERDICT_ORDER[r.verdict], r.name))
    failed = sum(result.failed() for result in results)
    worst = FAIL if failed else WARN if tally[WARN] or tally[FLAKY] else PASS
    tested = tally["total"] - tally[NOT_SUPPORTED]
    flaky = f", {tally[FLAKY]} flaky" if tally[FLAKY] else ""
    headline = {FAIL: f"{failed} of {tally['total']} scenes FAILED",
                WARN: f"all {tested} scenes tested conform, {tally[WARN]} with quality warnings{flaky}",
                PASS: f"all {tested} scenes tested pass"}[worst]
    extra = "".join(f", {tally[verdict]} {VERDICT_NAMES[verdict].lower()}" for verdict in (CRASH, TIMEOUT, FLAKY)
                    if tally[verdict])
    seconds = meta.get("seconds")
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
           "<title>softras conformance</title>", f"<style>{_CSS}</style></head><body>",
           "<h1>softras conformance report</h1>",
           f'<div class="banner" style="background:{_COLOURS[worst]}">{esc(headline)}: '
           f'{tally[PASS]} pass, {tally[WARN]} quality warning, {tally[FAIL]} fail, '
           f'{tally[NOT_SUPPORTED]} not supported{extra}'
           + (f" &middot; {seconds:.1f} s" if seconds is not None else "") + "</div>"]
    if meta.get("complete") is False:
        pending = meta.get("pending") or []
        why = "interrupted" if meta.get("interrupted") else "still running"
        out.append(f'<p class="banner" style="background:#455a64">incomplete ({why}): {len(pending)} scene'
                   f'{"s" if len(pending) != 1 else ""} not run yet; '
                   f"<code>softras conformance ... --resume DIR</code> finishes it</p>")
    details = [f"GL: {esc(str(meta.get('gl_renderer')))}", f"profile: {esc(str(meta.get('profile')))}",
               f"jobs: {esc(str(meta.get('jobs')))}"]
    if meta.get("shard"):
        details.append(f"shard {esc(str(meta['shard']))}")
    merged = meta.get("merged") or {}
    if merged.get("reports"):
        parts = [f"{esc(str(item.get('shard') or item.get('folder')))}: {item.get('scenes')} scenes, "
                 f"{float(item.get('seconds') or 0):.1f} s" for item in merged["reports"]]
        details.append(f"merged from {len(parts)} report{'s' if len(parts) != 1 else ''} ("
                       + "; ".join(parts) + "; time: their sum)")
    if meta.get("patterns"):
        details.append("-k " + esc(" ".join(meta["patterns"])))
    if meta.get("date"):
        details.append(esc(str(meta["date"])))
    out.append(f"<p>{' &middot; '.join(details)}</p>")
    out.append("<p>Verdicts (dEQP's tiers): <b>PASS</b> = softras matches GL within the scene's tolerance "
               "on every pixel (and, in the spec profile, both pictures lie within the bounds of what a "
               "conformant GL may draw); <b>QUALITY WARNING</b> = they differ only in ways GL allows (strict: "
               "on the pixels of the ambiguity mask; spec: within the bounds); <b>FAIL</b> = a difference GL "
               "does not allow; <b>NOT SUPPORTED</b> = the GL context lacks what the scene needs (or it would "
               "need more memory than --max-memory); <b>CRASH</b> = the worker process died during the check "
               "(signal or exit status, and its last output); <b>TIMEOUT</b> = the check overran --timeout; "
               "<b>FLAKY</b> = the verdict changed between attempts (--retries). Images: "
               "row 0 = top; x, y in the reasons count columns and rows from the top left.</p>")

    out.append('<table class="summary"><tr><th>verdict</th><th>scene</th><th>why</th>'
               "<th>SSIM</th><th>max diff</th><th>bad px</th><th>FLIP</th><th>time</th></tr>")
    for result in ordered:
        fig = result.figures
        first = result.reasons[0] if result.reasons else ""
        ssim = f"{fig['ssim']:.5f}" if "ssim" in fig else ""
        flip = f"{fig['flip_mean']:.4f}" if "flip_mean" in fig else ""
        out.append(f"<tr><td>{_badge(result.verdict)}</td><td><a href=\"#{esc(result.name)}\">"
                   f"{esc(result.name)}</a></td><td>{esc(first)}</td><td>{ssim}</td>"
                   f"<td>{fig.get('max_diff', '')}</td><td>{fig.get('bad_pixels', '')}</td><td>{flip}</td>"
                   f"<td>{result.seconds:.2f} s</td></tr>")
    out.append("</table>")

    for result in ordered:
        out.append(f'<section class="{result.verdict}" id="{esc(result.name)}">')
        out.append(f"<h2>{_badge(result.verdict)} {esc(result.name)}</h2>")
        out.append(f"<p><code>{esc(result.path)}</code>"
                   + (f" &mdash; {esc(result.description)}" if result.description else "") + "</p>")
        if result.tolerance:
            t = result.tolerance
            out.append(f"<p>Tolerance ({esc(result.tolerance_source)}): threshold {t['threshold']}/255, "
                       f"bad pixels &le; {100 * t['max_bad_fraction']:.2f}%, SSIM &ge; {t['min_ssim']:g}</p>")
        out.append('<ul class="reasons">' + "".join(f"<li>{esc(reason)}</li>" for reason in result.reasons)
                   + "</ul>")
        if result.attempts:
            out.append('<ol class="reasons">' + "".join(
                f"<li>{_badge(attempt['verdict'])} {attempt.get('seconds', 0):.2f} s"
                + (f": {esc(attempt['reasons'][0])}" if attempt.get("reasons") else "") + "</li>"
                for attempt in result.attempts) + "</ol>")
        if result.figures:
            out.append(f'<p class="figures">{esc(_figures_text(result.figures))}</p>')
        pictures = _image_paths(result)
        if pictures:
            height, width = next(iter(result.images.values())).shape[:2]
            scale = max(1.0, min(3.0, 256 / max(width, height)))
            shown = max(1, round(width * scale)) if width * scale <= 320 else 320
            out.append('<div class="pictures">')
            for name, path in pictures.items():
                out.append(f'<figure><a href="{esc(path)}"><img src="{esc(path)}" width="{shown}" '
                           f'alt="{esc(name)}"></a><figcaption><b>{esc(name)}</b>: '
                           f"{esc(IMAGE_CAPTIONS[name])}</figcaption></figure>")
            out.append("</div>")
        out.append("</section>")
    out.append("</body></html>")
    return "\n".join(out) + "\n"


def _folder_name(result: SceneResult, taken: set) -> str:
    name = result.name
    suffix = 2
    while name in taken:
        name = f"{result.name}-{suffix}"
        suffix += 1
    taken.add(name)
    return name


def write_scene_images(folder: str | os.PathLike, result: SceneResult) -> None:
    """Write one scene's pictures into ``folder/<result.name>/`` (atomically, each)."""
    from softras.scene.imageio import write_png_atomic

    if not result.images:
        return
    (Path(folder) / result.name).mkdir(exist_ok=True)
    for name in IMAGE_CAPTIONS:
        if name in result.images:
            write_png_atomic(Path(folder) / result.name / f"{name}.png", result.images[name])


def write_summary(folder: str | os.PathLike, results: list[SceneResult], meta: dict) -> Path:
    """Write results.json, junit.xml and index.html (atomically, each); returns index.html's path."""
    from softras.scene.imageio import write_text_atomic

    folder = Path(folder)
    write_text_atomic(folder / "results.json", results_json(results, meta))
    write_text_atomic(folder / "junit.xml", junit_xml(results, meta))
    index = folder / "index.html"
    write_text_atomic(index, index_html(results, meta))
    return index


def write_report(folder: str | os.PathLike, results: list[SceneResult], meta: dict) -> Path:
    """Write the report into ``folder`` (created if needed); returns index.html's path.

    Parameters
    ----------
    folder : path
        The report folder.
    results : list of SceneResult
        From :func:`softras.verification.conformance.run`. Two scenes with the same name
        (from different folders) get ``name-2`` and so on for their pictures.
    meta : dict
        About the run: ``seconds``, ``jobs``, ``gl_renderer``, ``shard``,
        ``patterns``, ``date`` (any JSON-able values; stored in results.json).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    taken: set = set()
    for result in results:
        result.name = _folder_name(result, taken)
        write_scene_images(folder, result)
    return write_summary(folder, results, meta)
