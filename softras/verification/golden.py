"""Golden images: glref's renderings of the conformance scenes, kept in git.

A golden folder holds one PNG per scene, ``<golden folder>/<scene stem>.png``,
rendered by glref, and a ``manifest.json`` that says where they came from and
what they contain. Both folders belong to the project being checked, never to
the installed package: ``softras golden`` with no PATH uses ``./scenes`` and
``./golden`` of the current directory (this repository's own ``scenes/`` and
``golden/`` when run from its root, docs/design.md section 1), and
``--golden-dir`` (or the ``golden_dir`` argument) names any other folder; the
pytest plugin keeps a test's golden images in ``golden/`` beside its test
module (docs/pytest_plugin.md). The manifest::

    {
      "softras_golden": 1,
      "provenance": {"GL_RENDERER": "llvmpipe (LLVM 15.0.6, 256 bits)",
                     "GL_VERSION": "4.5 (Core Profile) Mesa 22.3.6",
                     "GL_VENDOR": "Mesa/X.org", "mesa": "22.3.6", "llvm": "15.0.6",
                     "cpu": "...", "moderngl": "5.13.0", "python": "3.11.2",
                     "date": "2024-05-01T12:00:00+00:00", ...},
      "images": {"fill_rule_grid.png": {"scene": "fill_rule_grid.json",
                                        "width": 128, "height": 96,
                                        "sha256": "<hash of the decoded pixels>",
                                        "date": "..."}}
    }

``sha256`` is the hash of the *decoded* pixels (RGBA ``uint8``, row 0 = top,
rows then columns then channels), not of the PNG file, so re-encoding a PNG
does not change it while any edit of a pixel does. ``provenance`` describes
the update that last changed something (``date`` is its time); an image's
``date`` the time its pixels last changed.

:func:`update` (``softras golden --update``) is the only writer. It builds the
new folder beside ``golden/`` (``.golden.new-*``) and swaps it in with renames
(an atomic exchange where the OS has one), so an interrupted or failed update
leaves ``golden/`` exactly as it was. An update that changes no image (the
same pixels, scenes and files, on the same OpenGL with the same capability
record) writes nothing at all, not even a temporary folder: the manifest keeps
the provenance of the update that made the images, whatever the date or the
versions of Python and the libraries now. All images of one folder come from
one OpenGL implementation: updating a subset of the scenes on a machine whose
GL differs from the manifest's is refused.

:func:`verify` (``softras golden``) checks, for each scene:

1. the golden PNG decodes to the pixels whose hash the manifest records (an
   edited or damaged golden image is caught);
2. glref's rendering equals the golden image exactly, when glref runs on the
   OpenGL that made it (same renderer, version and vendor strings). On another
   GL the two are compared with the scene's tolerance instead, and the result
   says so;
3. softras's rendering (``precision="gl"``) passes :func:`softras.compare`
   against the golden image with the scene's tolerance.

Why one module of ~700 lines: golden images are one workflow (provenance,
manifest, check, update with its all-or-nothing writes); the sections below
follow it, and the atomic-update code must sit beside the manifest it protects.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import errno
import hashlib
import json
import os
import platform
import re
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from softras.scene.parse import folder_scene_files

__all__ = [
    "SCENES_DIR", "GOLDEN_DIR", "MANIFEST", "GoldenError", "Change", "Verification",
    "golden_path", "default_scenes", "pixel_hash", "provenance", "read_manifest", "update", "verify",
    "failure_images",
]

#: Where the scenes live by default: ``scenes/`` of the current directory (a
#: relative path, resolved when used, never the installed package's folder).
SCENES_DIR = Path("scenes")
#: Where their golden images live by default: ``golden/`` of the current directory.
GOLDEN_DIR = Path("golden")
#: Name of the manifest file inside the golden folder.
MANIFEST = "manifest.json"
#: Version of the manifest format.
FORMAT = 1

#: The provenance keys that identify the OpenGL implementation.
_GL_IDENTITY = ("GL_RENDERER", "GL_VERSION", "GL_VENDOR")
#: The capability record of the GL that drew the images (glref.info()), kept in the manifest.
CAPABILITY_KEYS = ("GL_SHADING_LANGUAGE_VERSION", "version", "device_index", "subpixel_bits", "max_samples",
                   "sample_counts", "sample_positions", "max_anisotropy", "max_texture_size",
                   "max_renderbuffer_size", "max_viewport_dims")

NO_GOLDEN = "no golden image: run softras golden --update"


class GoldenError(ValueError):
    """Bad input or environment for update / verify. ``str(error)`` is one line."""


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


# ---------------------------------------------------------------------------
# Names, hashes, provenance


def golden_path(scene_path: str | os.PathLike, golden_dir: str | os.PathLike | None = None) -> Path:
    """The golden image of a scene: ``<golden_dir>/<scene stem>.png``.

    ``golden_dir`` defaults to ``golden/`` of the current directory
    (:data:`GOLDEN_DIR`, relative).
    """
    return Path(golden_dir if golden_dir is not None else GOLDEN_DIR) / f"{Path(scene_path).stem}.png"


def default_scenes(scenes_dir: str | os.PathLike | None = None) -> list[Path]:
    """The scene files of a folder (`softras.scene.parse.folder_scene_files`:
    ``*.json``, ``*.gltf``, ``*.glb``, sorted by name); none when it is missing.

    ``scenes_dir`` defaults to ``scenes/`` of the current directory
    (:data:`SCENES_DIR`): this repository's scenes when run from its root.
    """
    folder = Path(scenes_dir if scenes_dir is not None else SCENES_DIR)
    return [Path(path) for path in folder_scene_files(folder)] if folder.is_dir() else []


def pixel_hash(image: np.ndarray) -> str:
    """sha256 (hex) of an image's decoded pixels: RGBA uint8 bytes, row 0 = top."""
    array = np.ascontiguousarray(image, dtype=np.uint8)
    if array.ndim != 3 or array.shape[2] != 4:
        raise ValueError(f"expected an (H, W, 4) image, got shape {array.shape}")
    return hashlib.sha256(array.tobytes()).hexdigest()


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as handle:
            for line in handle:
                key, _, value = line.partition(":")
                if key.strip() == "model name" and value.strip():
                    return value.strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def _search(pattern: str, text: str | None) -> str | None:
    match = re.search(pattern, text or "")
    return match.group(1) if match else None


def provenance(info: dict | None = None) -> dict:
    """Describe the machine and OpenGL that render the golden images now.

    ``info`` is :func:`glref.info`'s dictionary (asked for when omitted).
    ``mesa`` is parsed from GL_VERSION ("... Mesa 22.3.6"), ``llvm`` from
    GL_RENDERER ("llvmpipe (LLVM 15.0.6, 256 bits)"); either is None when the
    driver is not Mesa / not LLVM based.
    """
    if info is None:
        import glref

        info = glref.info()
    try:
        from importlib.metadata import version

        softras_version = version("softras")
    except Exception:  # noqa: BLE001 - not installed: no version to record
        softras_version = None
    result = {key: info.get(key) for key in _GL_IDENTITY}
    result.update(
        mesa=_search(r"Mesa (\d+(?:\.\d+)*(?:-\w+)?)", info.get("GL_VERSION")),
        llvm=_search(r"LLVM (\d+(?:\.\d+)*)", info.get("GL_RENDERER")),
        cpu=_cpu_model(),
        moderngl=info.get("moderngl"),
        python=platform.python_version(),
        numpy=np.__version__,
        softras=softras_version,
        platform=platform.platform(),
        env=info.get("env"),
        depth_format=info.get("depth_format"),
        capabilities={key: info.get(key) for key in CAPABILITY_KEYS if key in info},
        date=datetime.now(timezone.utc).isoformat(timespec="seconds"),
    )
    return result


def _gl_identity(prov: dict | None) -> tuple:
    return tuple((prov or {}).get(key) for key in _GL_IDENTITY)


def _gl_record(prov: dict | None) -> tuple:
    """What of a provenance describes the GL that drew the images: its identity,
    capability record and depth format (not the date, the machine's tools or versions)."""
    prov = prov or {}
    return _gl_identity(prov) + (prov.get("capabilities"), prov.get("depth_format"))


def _describe_gl(prov: dict | None) -> str:
    prov = prov or {}
    return f"{prov.get('GL_RENDERER')}, OpenGL {prov.get('GL_VERSION')}"


# ---------------------------------------------------------------------------
# Manifest


def read_manifest(golden_dir: str | os.PathLike) -> dict | None:
    """Read ``golden_dir/manifest.json``; None when there is none.

    Raises GoldenError when it exists but is not a valid manifest.
    """
    path = Path(golden_dir) / MANIFEST
    if not path.exists():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise GoldenError(f"{path}: cannot read manifest: {_one_line(error)}") from None
    if (not isinstance(data, dict) or data.get("softras_golden") != FORMAT
            or not isinstance(data.get("images"), dict) or not isinstance(data.get("provenance"), dict)):
        raise GoldenError(f"{path}: not a softras golden manifest (format {FORMAT})")
    for name, entry in data["images"].items():
        if not isinstance(entry, dict) or not {"scene", "width", "height", "sha256"} <= set(entry):
            raise GoldenError(f"{path}: images[{name!r}] needs scene, width, height and sha256")
    return data


def _manifest_text(manifest: dict) -> str:
    return json.dumps(manifest, indent=2) + "\n"


# ---------------------------------------------------------------------------
# Scenes


def _load_scenes(scene_paths: Iterable[str | os.PathLike]) -> list[tuple[Path, object]]:
    """Load every scene first (bad input is found before anything is rendered).

    Raises GoldenError for a missing file, a bad scene or two scenes with the
    same stem (they would share a golden image).
    """
    from softras.scene import SceneError, load_scene

    loaded = []
    seen: dict[str, Path] = {}
    for scene_path in scene_paths:
        path = Path(scene_path)
        if not path.is_file():
            raise GoldenError(f"{path}: no such scene file")
        name = golden_path(path, ".").name
        if name in seen:
            raise GoldenError(f"{path}: same golden image name {name} as {seen[name]}")
        seen[name] = path
        try:
            scene = load_scene(path)
        except SceneError as error:
            message = _one_line(error)
            raise GoldenError(message if str(path) in message else f"{path}: {message}") from None
        loaded.append((path, scene))
    if not loaded:
        raise GoldenError("no scene files given")
    return loaded


def _render_gl(scene) -> np.ndarray:
    """glref's rendering of a loaded scene (looked up at call time: tests patch it)."""
    import glref

    return glref.render(scene)


def _gl_info() -> dict:
    """glref.info(), with a missing GL turned into GoldenError."""
    try:
        import glref
    except ModuleNotFoundError as error:
        if error.name not in ("moderngl", "glcontext"):
            raise
        raise GoldenError(f"OpenGL reference renderer unavailable: {_one_line(error)}") from None
    try:
        return glref.info()
    except glref.GLUnavailable as error:
        raise GoldenError(f"OpenGL unavailable: {_one_line(error)}") from None


# ---------------------------------------------------------------------------
# Update


@dataclass
class Change:
    """What :func:`update` did to one golden image."""

    name: str                   # file name in the golden folder, e.g. "hierarchy.png"
    status: str                 # "added" | "changed" | "unchanged" | "removed"
    scene: str | None = None    # the scene file (None for "removed")
    diff_pixels: int | None = None  # "changed": pixels whose RGBA differ (None if the size changed)
    detail: str = ""

    def line(self) -> str:
        text = f"{self.status:<9} {self.name}"
        if self.detail:
            text += f"  ({self.detail})"
        return text


def _diff_pixels(a: np.ndarray, b: np.ndarray) -> int:
    return int(np.count_nonzero(np.any(a != b, axis=-1)))


def _fsync_file(path: Path) -> None:
    with open(path, "rb") as handle:
        os.fsync(handle.fileno())


def _fsync_dir(path: Path) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _exchange(a: Path, b: Path) -> bool:
    """Atomically swap two paths (Linux renameat2 RENAME_EXCHANGE). False if unsupported."""
    if sys.platform != "linux":
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    renameat2.restype = ctypes.c_int
    if renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.ENOSYS, errno.EINVAL, errno.EOPNOTSUPP):
        return False
    raise OSError(code, os.strerror(code), str(a))


def _swap_in(new: Path, target: Path) -> None:
    """Replace folder ``target`` by folder ``new``; the old one is removed.

    ``target`` always holds either the complete old or the complete new
    folder: an atomic exchange where available; otherwise the old folder is
    renamed aside, the new one into place (and the old one back on failure).
    """
    if not target.exists():
        os.rename(new, target)
    elif _exchange(new, target):
        shutil.rmtree(new)  # now the old folder
    else:
        aside = Path(tempfile.mkdtemp(prefix=f".{target.name}.old-", dir=target.parent))
        aside.rmdir()
        os.rename(target, aside)
        try:
            os.rename(new, target)
        except BaseException:
            os.rename(aside, target)
            raise
        shutil.rmtree(aside)
    _fsync_dir(target.parent)


def _check_golden_dir(golden_dir: Path) -> None:
    if golden_dir.exists() and not golden_dir.is_dir():
        raise GoldenError(f"{golden_dir}: not a folder")
    parent = golden_dir.absolute().parent
    if not parent.is_dir():
        raise GoldenError(f"{golden_dir}: folder {parent} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise GoldenError(f"{golden_dir}: folder {parent} is not writable")


def update(
    scene_paths: Iterable[str | os.PathLike],
    golden_dir: str | os.PathLike | None = None,
    *,
    prune: bool = False,
    on_change: Callable[[Change], None] | None = None,
) -> list[Change]:
    """Render scenes with glref and store them as golden images, all or nothing.

    Parameters
    ----------
    scene_paths : iterable of path
        The scene files to (re)render.
    golden_dir : path, optional
        The golden folder (default ``golden/`` of the current directory).
    prune : bool
        Remove golden images of scenes not in ``scene_paths`` (a full update).
        Without it the other existing images and their manifest entries are
        kept as they are.
    on_change : callable, optional
        Called with each :class:`Change` as soon as it is known (progress).

    Returns
    -------
    list of Change
        One per scene (added / changed / unchanged), then the removed images.

    The new folder is assembled next to ``golden_dir`` and swapped in only when
    complete; on any error (a scene that fails to render, a full disk) the
    temporary folder is deleted and ``golden_dir`` is left untouched. Nothing
    is written when nothing changed.

    Raises
    ------
    GoldenError
        Bad scenes, no OpenGL, an unwritable folder, an unreadable manifest
        (partial update), or a partial update on a different OpenGL.
    """
    from softras.scene.imageio import ImageError, read_png, write_png_atomic

    golden_dir = Path(golden_dir if golden_dir is not None else GOLDEN_DIR)
    scenes = _load_scenes(scene_paths)
    _check_golden_dir(golden_dir)
    try:
        old_manifest = read_manifest(golden_dir) if golden_dir.is_dir() else None
    except GoldenError:
        if not prune:
            raise
        old_manifest = None  # a full update rebuilds the manifest anyway
    old_images = dict(old_manifest["images"]) if old_manifest else {}
    prov = provenance(_gl_info())

    if old_manifest and not prune and _gl_identity(old_manifest["provenance"]) != _gl_identity(prov):
        raise GoldenError(
            f"{golden_dir} was made with {_describe_gl(old_manifest['provenance'])}, this machine has "
            f"{_describe_gl(prov)}: update all scenes (softras golden --update without PATH)")

    def report(change: Change) -> Change:
        if on_change is not None:
            on_change(change)
        return change

    # 1. Render every scene and compare it with the image it would replace, in
    #    memory: nothing is written before it is known that something changes.
    now = prov["date"]
    updating = {golden_path(path, golden_dir).name for path, _ in scenes}
    changes: list[Change] = []
    entries: dict[str, dict] = {}
    fresh: dict[str, np.ndarray | None] = {}   # name -> new pixels (None: keep the old file's bytes)
    for path, scene in scenes:
        name = golden_path(path, golden_dir).name
        image = np.ascontiguousarray(_render_gl(scene), dtype=np.uint8)
        height, width = image.shape[:2]
        entry = {"scene": path.name, "width": width, "height": height,
                 "sha256": pixel_hash(image), "date": now}
        old_file = golden_dir / name
        old = None
        if old_file.is_file():
            try:
                old = read_png(old_file)
            except ImageError:
                old = None
        fresh[name] = image
        if old is None:
            change = Change(name, "added", str(path), detail=f"{width}x{height}")
        elif old.shape != image.shape:
            change = Change(name, "changed", str(path),
                            detail=f"size {old.shape[1]}x{old.shape[0]} -> {width}x{height}")
        else:
            count = _diff_pixels(old, image)
            old_entry = old_images.get(name)
            if count == 0 and old_entry and old_entry.get("sha256") == entry["sha256"]:
                change = Change(name, "unchanged", str(path), diff_pixels=0)
                fresh[name] = None
                entry["date"] = old_entry.get("date", now)
            elif count == 0:
                change = Change(name, "changed", str(path), diff_pixels=0,
                                detail="same pixels, manifest entry rewritten")
            else:
                change = Change(name, "changed", str(path), diff_pixels=count,
                                detail=f"{count} pixel{'s' if count != 1 else ''} differ")
        if old_images.get(name, {}).get("scene") not in (None, path.name) and change.status == "unchanged":
            change.status, change.detail = "changed", f"scene is now {path.name}"
        entries[name] = entry
        changes.append(report(change))

    # 2. What else the folder holds: kept as it is, or removed (a full update
    #    drops the images of scenes that are gone).
    removed: list[Change] = []
    kept: list[Path] = []
    if golden_dir.is_dir():
        for item in sorted(golden_dir.iterdir()):
            if item.name == MANIFEST or item.name in updating:
                continue
            if item.suffix.lower() == ".png" and (prune or item.name not in old_images):
                removed.append(Change(item.name, "removed", detail="no scene" if prune else "not in manifest"))
                continue
            kept.append(item)
            if item.name in old_images:
                entries[item.name] = old_images[item.name]
        for name in sorted(set(old_images) - updating - set(entries)):
            if not any(change.name == name for change in removed):
                removed.append(Change(name, "removed", detail="file was missing"))
    for change in removed:
        report(change)

    # 3. Nothing changed: write nothing (not even the new date or tool versions).
    modified = any(change.status != "unchanged" for change in changes) or bool(removed)
    same_gl = old_manifest is not None and _gl_record(old_manifest["provenance"]) == _gl_record(prov)
    if not modified and same_gl and old_images == entries:
        return changes + removed

    # 4. Build the new folder beside the old one and swap it in.
    temp = Path(tempfile.mkdtemp(prefix=f".{golden_dir.name}.new-", dir=golden_dir.absolute().parent))
    try:
        for item in kept:
            if item.is_dir():
                shutil.copytree(item, temp / item.name, symlinks=True)
            else:
                shutil.copy2(item, temp / item.name, follow_symlinks=False)
                _fsync_file(temp / item.name)
        for name, image in fresh.items():
            if image is None:
                shutil.copy2(golden_dir / name, temp / name)
                _fsync_file(temp / name)
            else:
                write_png_atomic(temp / name, image)
        manifest = {"softras_golden": FORMAT, "provenance": prov,
                    "images": dict(sorted(entries.items()))}
        manifest_path = temp / MANIFEST
        manifest_path.write_text(_manifest_text(manifest), encoding="utf-8")
        _fsync_file(manifest_path)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temp, 0o777 & ~umask)  # mkdtemp makes it 0700
        _fsync_dir(temp)
        _swap_in(temp, golden_dir)
    finally:
        if temp.exists():
            shutil.rmtree(temp, ignore_errors=True)
    return changes + removed


# ---------------------------------------------------------------------------
# Verify


@dataclass
class Verification:
    """The result of verifying one scene against its golden image."""

    scene: str                        # the scene file
    golden: str                       # the golden image file
    passed: bool = False
    failures: list[str] = field(default_factory=list)
    hash_ok: bool | None = None       # golden pixels match the manifest's sha256
    gl_exact: bool = True             # glref compared exactly (same GL) or with tolerance
    gl_diff_pixels: int | None = None  # pixels where glref differs from the golden image
    gl_comparison: object = None      # Comparison, when compared with tolerance (other GL)
    soft: object = None               # softras.verification.metrics.Comparison, soft vs golden
    seconds: float = 0.0
    images: dict = field(default_factory=dict)  # golden / gl / soft arrays (keep_images)

    @property
    def name(self) -> str:
        return Path(self.golden).name

    def line(self) -> str:
        """One line: PASS/FAIL, the scene, the three checks, the time."""
        parts = []
        if self.hash_ok:
            parts.append("hash ok")
        if self.gl_diff_pixels is not None:
            if self.gl_exact:
                parts.append("gl identical" if self.gl_diff_pixels == 0 else
                             f"gl differs in {self.gl_diff_pixels} pixel{'s' if self.gl_diff_pixels != 1 else ''}")
            elif self.gl_comparison is not None:
                parts.append(f"gl (other GL, tolerance) {'pass' if self.gl_comparison.passed else 'FAIL'} "
                             f"ssim {self.gl_comparison.ssim:.4f}, {self.gl_diff_pixels} pixels differ")
        if self.soft is not None:
            parts.append(f"soft {'pass' if self.soft.passed else 'FAIL'} ssim {self.soft.ssim:.4f}, "
                         f"{self.soft.bad_pixels} bad ({self.soft.bad_fraction:.2%}), max diff {self.soft.max_diff}")
        text = f"{'PASS' if self.passed else 'FAIL'}  {Path(self.golden).stem}: " + "; ".join(parts)
        if self.failures:
            text += ("; " if parts else "") + "; ".join(self.failures)
        return text + f"  ({self.seconds:.2f} s)"


def failure_images(result: Verification) -> dict[str, np.ndarray]:
    """The pictures of a verified scene (:func:`verify` with ``keep_images``):
    its golden, gl and soft images, and heat maps ``diff_gl`` and ``diff_soft``
    of each against the golden image where it is there and the sizes agree
    (`softras.verification.metrics.compare`)."""
    from softras.verification.metrics import compare

    images = dict(result.images)
    golden = images.get("golden")
    if golden is not None:
        for name in ("gl", "soft"):
            if name in images and images[name].shape == golden.shape:
                images[f"diff_{name}"] = compare(images[name], golden).diff_image
    return images


def _tolerance_text(comparison) -> str:
    return (f"ssim {comparison.ssim:.4f} (min {comparison.min_ssim}), bad {comparison.bad_fraction:.2%} "
            f"(max {comparison.max_bad_fraction:.2%}, threshold {comparison.threshold}), "
            f"max diff {comparison.max_diff}")


def verify(
    scene_paths: Iterable[str | os.PathLike],
    golden_dir: str | os.PathLike | None = None,
    *,
    orphans: bool = False,
    keep_images: bool = False,
    on_result: Callable[[Verification], None] | None = None,
) -> list[Verification]:
    """Check golden images against the manifest, glref and softras.

    Parameters
    ----------
    scene_paths : iterable of path
        The scenes to verify.
    golden_dir : path, optional
        The golden folder (default ``golden/`` of the current directory).
    orphans : bool
        Also report, as failures, golden images whose scene is not among
        ``scene_paths`` (used when verifying all scenes).
    keep_images : bool
        Keep the golden, gl and soft images in :attr:`Verification.images`.
    on_result : callable, optional
        Called with each :class:`Verification` when it is done (progress).

    Returns
    -------
    list of Verification
        One per scene, in order, then one per orphan image.

    Raises
    ------
    GoldenError
        Bad scenes, no OpenGL, an unreadable manifest.
    """
    from softras.renderer import render_scene
    from softras.scene.imageio import ImageError, read_png
    from softras.verification.metrics import compare
    from softras.scene import SceneError
    from softras.verification.verifier import scene_tolerance

    golden_dir = Path(golden_dir if golden_dir is not None else GOLDEN_DIR)
    scenes = _load_scenes(scene_paths)
    if golden_dir.exists() and not golden_dir.is_dir():
        raise GoldenError(f"{golden_dir}: not a folder")
    manifest = read_manifest(golden_dir) if golden_dir.is_dir() else None
    images = manifest["images"] if manifest else {}
    here = _gl_info()
    same_gl = manifest is None or _gl_identity(manifest["provenance"]) == _gl_identity(here)

    results: list[Verification] = []
    for path, scene in scenes:
        start = time.perf_counter()
        golden_file = golden_path(path, golden_dir)
        result = Verification(scene=str(path), golden=str(golden_file), gl_exact=same_gl)
        fail = result.failures.append
        golden = None
        entry = images.get(golden_file.name)
        if not golden_file.is_file():
            fail(NO_GOLDEN)
        else:
            try:
                golden = read_png(golden_file)
            except ImageError as error:
                fail(f"golden image unreadable: {_one_line(error)}")
        if golden is not None:
            if entry is None:
                fail(f"{golden_file.name} is not in {MANIFEST}: run softras golden --update")
            else:
                result.hash_ok = pixel_hash(golden) == entry["sha256"]
                if not result.hash_ok:
                    fail(f"golden pixels do not match the sha256 in {MANIFEST} "
                         f"(image edited outside softras golden --update?)")
                if entry.get("scene") != path.name:
                    fail(f"{MANIFEST} says {golden_file.name} is for scene {entry.get('scene')}")
            if golden.shape[:2] != (scene.height, scene.width):
                fail(f"golden image is {golden.shape[1]}x{golden.shape[0]}, "
                     f"scene is {scene.width}x{scene.height}: run softras golden --update")
                golden = None
        if golden is not None:
            tolerance = scene_tolerance(scene)[0]
            gl = np.ascontiguousarray(_render_gl(scene), dtype=np.uint8)
            result.gl_diff_pixels = _diff_pixels(gl, golden)
            if same_gl:
                if result.gl_diff_pixels:
                    fail(f"glref no longer reproduces the golden image ({result.gl_diff_pixels} "
                         f"pixel{'s' if result.gl_diff_pixels != 1 else ''} differ): the scene, glref or "
                         f"the driver changed; review, then softras golden --update")
            else:
                result.gl_comparison = compare(gl, golden, **tolerance)
                if not result.gl_comparison.passed:
                    fail(f"glref on {_describe_gl(here)} vs golden from {_describe_gl(manifest['provenance'])}: "
                         + _tolerance_text(result.gl_comparison))
            try:
                soft = render_scene(scene, precision="gl")
            except (SceneError, NotImplementedError) as error:
                fail(f"softras cannot render the scene: {_one_line(error)}")
                soft = None
            if soft is not None:
                result.soft = compare(soft, golden, **tolerance)
                if not result.soft.passed:
                    fail("softras vs golden: " + _tolerance_text(result.soft))
            if keep_images:
                result.images = {"golden": golden, "gl": gl}
                if soft is not None:
                    result.images["soft"] = soft
        result.passed = not result.failures
        result.seconds = time.perf_counter() - start
        results.append(result)
        if on_result is not None:
            on_result(result)

    if orphans and golden_dir.is_dir():
        known = {golden_path(path, golden_dir).name for path, _ in scenes}
        names = set(images) | {item.name for item in golden_dir.glob("*.png")}
        for name in sorted(names - known):
            result = Verification(scene=images.get(name, {}).get("scene", "?"), golden=str(golden_dir / name),
                                  failures=["golden image without a scene: run softras golden --update"])
            results.append(result)
            if on_result is not None:
                on_result(result)
    return results
