"""Merging shard reports: the reports of ``softras conformance --shard I/N`` into one.

A CI matrix runs the N shards on N machines, each writing its own report
folder (:mod:`softras.verification.report`); ``softras conformance --merge
DIR... --report OUT`` reads them (:func:`read_shards`), checks that they are the
shards of one run (:func:`check_shards`) and writes one report into OUT
(:func:`write_merged`): results.json, junit.xml, index.html and failures.csv
over all scenes, and every scene's pictures copied (byte for byte) into
``OUT/<scene>/``, so each picture the merged page lists is there.

The reports must be the shards of one run. Refused, before anything is
written (:class:`MergeError`, one line):

* a folder that is missing, holds no results.json, or whose results.json is
  not a conformance report or has another format version (:data:`FORMAT`);
* an incomplete run (interrupted: ``complete`` false; finish it with
  ``--resume`` first) or a picture its results.json lists that is missing;
* shards of different N, a shard given twice, a shard of the N missing, or
  an unsharded report among shards;
* shards rendered with different GL renderers (``gl_renderer``: renderer and
  version strings): a llvmpipe and a softpipe matrix are two runs, merged
  into two reports, never one; also different ``--profile`` or ``-k``;
* the same scene in two shards, or shards whose scenes are not the shards of
  their union (run on different scene sets).

Unsharded reports (no ``--shard``) can be merged with each other too, e.g.
runs over different scene folders, under the same rules (same GL, profile,
no scene twice).

The merged results.json has no ``options`` (it cannot be ``--resume``\\ d),
``shard`` null and ``merged``: one record per input (folder, shard, GL,
date, seconds, jobs, scene count); ``seconds`` is the shards' seconds added
up. The exit status follows the merged verdicts as a run's does
(:func:`softras.verification.runner.exit_status`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

from softras.verification.conformance import ConformanceError, SceneResult, _one_line, parse_shard, shard
from softras.verification.report import FORMAT

__all__ = ["MergeError", "Shard", "Merged", "read_shards", "check_shards", "merged_meta", "write_merged", "merge", "print_merged"]


class MergeError(ConformanceError):
    """Reports that cannot be merged (missing, not reports, not shards of one run); one line."""


@dataclass
class Shard:
    """One input report: its folder, its results.json, and its scenes read back."""

    folder: Path
    data: dict
    results: list[SceneResult] = field(default_factory=list)

    @property
    def spec(self) -> tuple[int, int] | None:
        text = self.data.get("shard")
        return parse_shard(text) if text else None


def _read_shard(folder: Path) -> Shard:
    from softras.verification.runner import RunnerError, result_from_dict

    if not folder.exists():
        raise MergeError(f"--merge {folder}: no such folder")
    if not folder.is_dir():
        raise MergeError(f"--merge {folder}: not a folder")
    path = folder / "results.json"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise MergeError(f"--merge {folder}: no results.json there (not a conformance report folder)") from None
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise MergeError(f"--merge {folder}: cannot read results.json: {_one_line(error)}") from None
    if not isinstance(data, dict) or "softras_conformance" not in data or not isinstance(data.get("scenes"), list):
        raise MergeError(f"--merge {folder}: results.json is not a softras conformance report")
    if data["softras_conformance"] != FORMAT:
        raise MergeError(f"--merge {folder}: report format version {data['softras_conformance']!r}, this softras "
                         f"merges version {FORMAT} (re-run that shard with this softras)")
    if data.get("complete") is False:
        pending = data.get("pending") or []
        raise MergeError(f"--merge {folder}: an incomplete run ({len(pending)} scene"
                         f"{'s' if len(pending) != 1 else ''} not run): finish it with --resume {folder} first")
    if data.get("shard"):
        try:
            parse_shard(str(data["shard"]))
        except ConformanceError:
            raise MergeError(f"--merge {folder}: results.json has a malformed shard {data['shard']!r}") from None
    results = []
    for entry in data["scenes"]:
        if not isinstance(entry, dict):
            raise MergeError(f"--merge {folder}: results.json has a scene entry that is not an object")
        for relative in (entry.get("images") or {}).values():
            picture = folder / str(relative)
            if Path(str(relative)).is_absolute() or ".." in Path(str(relative)).parts:
                raise MergeError(f"--merge {folder}: results.json lists a picture outside the folder: {relative}")
            if not picture.is_file():
                raise MergeError(f"--merge {folder}: scene {entry.get('name')}: its picture {relative} is missing")
        try:
            results.append(result_from_dict(entry, folder))
        except RunnerError as error:
            raise MergeError(f"--merge {_one_line(error)}") from None
    return Shard(folder, data, results)


def read_shards(folders) -> list[Shard]:
    """Read each report folder (see the module's docstring for what is refused)."""
    folders = [Path(folder) for folder in folders]
    if not folders:
        raise MergeError("--merge: give the report folders of the shards")
    seen = {}
    for folder in folders:
        key = folder.resolve()
        if key in seen:
            raise MergeError(f"--merge: {folder} is given twice")
        seen[key] = folder
    return [_read_shard(folder) for folder in folders]


def _same(shards: list[Shard], key: str, what: str) -> None:
    first = shards[0]
    for other in shards[1:]:
        if other.data.get(key) != first.data.get(key):
            raise MergeError(f"--merge: {first.folder} and {other.folder} differ in {what}: "
                             f"{first.data.get(key)!r} and {other.data.get(key)!r} (not shards of one run)")


def check_shards(shards: list[Shard]) -> None:
    """MergeError unless ``shards`` are the shards of one run (the module's docstring lists the rules)."""
    _same(shards, "gl_renderer", "GL renderer")
    _same(shards, "profile", "--profile")
    _same(shards, "patterns", "-k")
    specs = [item.spec for item in shards]
    if any(spec is None for spec in specs) and any(spec is not None for spec in specs):
        plain = next(item for item in shards if item.spec is None)
        sharded = next(item for item in shards if item.spec is not None)
        raise MergeError(f"--merge: {plain.folder} is not a shard (no --shard) but {sharded.folder} is shard "
                         f"{sharded.data['shard']}")
    owner = {}
    for item in shards:
        for result in item.results:
            if result.name in owner:
                raise MergeError(f"--merge: scene {result.name} is in both {owner[result.name]} and {item.folder}")
            owner[result.name] = item.folder
    if specs[0] is None:
        return
    counts = {count for _, count in specs}
    if len(counts) > 1:
        first = shards[0]
        other = next(item for item in shards if item.spec[1] != first.spec[1])
        raise MergeError(f"--merge: {first.folder} is shard {first.data['shard']} and {other.folder} shard "
                         f"{other.data['shard']}: shards of different N")
    count = counts.pop()
    by_index = {}
    for item in shards:
        index = item.spec[0]
        if index in by_index:
            raise MergeError(f"--merge: {by_index[index].folder} and {item.folder} are both shard {index}/{count}")
        by_index[index] = item
    missing = [index for index in range(1, count + 1) if index not in by_index]
    if missing:
        raise MergeError(f"--merge: shard{'s' if len(missing) > 1 else ''} "
                         f"{', '.join(f'{index}/{count}' for index in missing)} missing (give all {count})")
    # Each shard holds exactly its round-robin part of the union: shards of one scene set.
    union = [Path(f"{name}.json") for name in owner]
    for index, item in by_index.items():
        expected = sorted(path.stem for path in shard(union, index, count))
        got = sorted(result.name for result in item.results)
        if expected != got:
            raise MergeError(f"--merge: {item.folder} (shard {index}/{count}) does not hold shard {index} of the "
                             f"{len(union)} scenes of these reports: were the shards run on different scene sets?")


def merged_meta(shards: list[Shard], results: list[SceneResult]) -> dict:
    """The merged run's record for results.json (no ``options``: a merged report is not resumable)."""
    first = shards[0].data
    jobs = {item.data.get("jobs") for item in shards}
    count = shards[0].spec[1] if shards[0].spec else None
    seconds = sum(float(item.data.get("summary", {}).get("seconds") or 0.0) for item in shards)
    return {
        "seconds": round(seconds, 3),
        "jobs": jobs.pop() if len(jobs) == 1 else sorted(jobs, key=str),
        "gl_renderer": first.get("gl_renderer"),
        "profile": first.get("profile"),
        "gl": first.get("gl"),
        "shard": None,
        "patterns": first.get("patterns") or [],
        "paths": [result.path for result in results],
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "complete": True, "interrupted": False, "pending": [],
        "merged": {"count": count, "reports": [
            {"folder": str(item.folder), "shard": item.data.get("shard"), "gl_renderer": item.data.get("gl_renderer"),
             "date": item.data.get("date"), "seconds": item.data.get("summary", {}).get("seconds"),
             "jobs": item.data.get("jobs"), "scenes": len(item.results)}
            for item in sorted(shards, key=lambda item: item.spec or (0, 0))]},
    }


@dataclass
class Merged:
    """A merged report: its results (sorted by name, an unsharded run's order), meta, index.html, baseline check."""

    results: list
    meta: dict
    index: Path
    baseline: object = None


def write_merged(folder, shards: list[Shard], *, baseline=None) -> Merged:
    """Write the merged report into ``folder``: pictures, results.json, junit.xml, index.html, failures.csv.

    ``baseline``: a :class:`softras.verification.runner.Baseline` to compare the merged results with
    (stored in results.json, as a run with ``--baseline`` does).
    """
    from softras.scene.imageio import copy_file_atomic, write_text_atomic
    from softras.verification.report import write_summary
    from softras.verification.runner import compare_baseline, failures_csv

    folder = Path(folder)
    results = sorted((result for item in shards for result in item.results), key=lambda result: result.name)
    check = compare_baseline(results, baseline) if baseline is not None else None
    source = {result.name: item.folder for item in shards for result in item.results}
    entries = {entry["name"]: entry for item in shards for entry in item.data["scenes"]}
    folder.mkdir(parents=True, exist_ok=True)
    for result in results:
        images = entries[result.name].get("images") or {}
        if result.images:
            (folder / result.name).mkdir(exist_ok=True)
        for key in result.images:
            copy_file_atomic(source[result.name] / images[key], folder / result.name / f"{key}.png")
    meta = merged_meta(shards, results)
    if check is not None:
        meta["baseline"] = check.to_dict()
    index = write_summary(folder, results, meta)
    title = f"{meta.get('gl_renderer')}, profile {meta.get('profile')}"
    write_text_atomic(folder / "failures.csv", failures_csv(results, title))
    return Merged(results, meta, index, check)


def merge(folders, out, *, baseline=None) -> Merged:
    """Read, check and merge the reports in ``folders`` into ``out``; MergeError (nothing written) when they
    are not the shards of one run or ``out`` is one of them."""
    shards = read_shards(folders)
    check_shards(shards)
    if any(Path(out).resolve() == item.folder.resolve() for item in shards):
        raise MergeError(f"--report {out}: is one of the reports being merged; write the merged report elsewhere")
    return write_merged(out, shards, baseline=baseline)


def print_merged(merged: Merged, out) -> int:
    """Print what a run prints at its end (scenes that did not pass, the baseline, the counts); the exit status."""
    from softras.verification.conformance import PASS, VERDICT_ORDER
    from softras.verification.runner import _summary_line, exit_status

    for result in sorted(merged.results, key=lambda r: (VERDICT_ORDER[r.verdict], r.name)):
        if result.verdict != PASS:
            print(result.line(), file=out)
            for reason in result.reasons[1:]:
                print(f"{'':<16}{reason}", file=out)
    check = merged.baseline
    if check is not None:
        for line in check.lines():
            print(line, file=out)
    reports = merged.meta["merged"]["reports"]
    print(f"report: {merged.index}", file=out)
    print(f"conformance --merge: {len(reports)} report{'s' if len(reports) != 1 else ''}"
          + (f" (shards of {merged.meta['merged']['count']})" if merged.meta["merged"]["count"] else "")
          + f", {_summary_line(merged.results)}, {merged.meta['seconds']:.1f} s in the shards "
            f"(GL: {merged.meta.get('gl_renderer')}, profile {merged.meta.get('profile')})", file=out)
    out.flush()
    return exit_status(merged.results, check)
