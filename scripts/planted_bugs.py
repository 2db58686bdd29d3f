"""Planted bugs: does the spec verification profile catch real mistakes?

Each planted bug (:data:`MUTATIONS`) is a mistake a renderer could make:
either a change to the scene it is given (a function ``Scene -> Scene``:
texture coordinates off by half a texel, a wrong wrap mode or min filter, a
vertex one pixel off, a material colour off by 5/255, ...) or a patch of
softras's own code while it renders (a context manager: the fill rule's tie
rule, perspective correction switched off). The bug lives only in the picture
under test: softras renders the *mutated* scene (or renders under the patch,
``fast_path=False`` so the patched stage runs), GL renders the *unmodified*
scene, and :func:`softras.verify` judges the pair against the unmodified
scene with ``profile="spec"`` and the capability record of the GL that drew
the reference. Every planted bug must FAIL. The unmodified softras picture
is judged the same way against each GL's picture: it must not FAIL (a
failure there is a false failure).

Two GL implementations draw the references, each in its own process (the
Gallium driver is chosen when the context is created): Mesa llvmpipe and
Mesa softpipe (``GALLIUM_DRIVER=softpipe``). A child process writes the
pictures (``pictures.npz``) and ``glref.info()`` (``info.json``) into a
folder; the judging happens here. ``--draw FOLDER`` writes such a folder
with this machine's GL and stops (on a GPU machine, say); ``--recorded
FOLDER`` judges against one drawn elsewhere as a further implementation
(tests/recorded/nvidia_h200: an NVIDIA H200's).

A mutation the GL specification permits is marked ``permitted``: a
consistent swap of the fill rule's tie rule (GL 4.6 section 14.6.1 asks only
that a sample exactly on an edge shared by two polygons be produced by
exactly one of them). The spec profile must *not* fail it (a FAIL there is
a false failure too); the strict profile's verdict (softras's contract with
llvmpipe, through its tolerance and ambiguity mask) is shown beside it on
llvmpipe, for information.

    python scripts/planted_bugs.py [--quick] [--only NAMES] [--json FILE] [--implementations llvmpipe,softpipe]
                                   [--recorded FOLDER ...] [--draw FOLDER]

Prints a Markdown table (mutation x scene x implementation: the verdict and
the number of the image's pixels outside the spec bounds; "changed px": the
pixels the bug changes in softras's own picture) and the false failure
count. Exit status 0 when every planted bug FAILs, no permitted one FAILs
and no unmodified scene FAILs under spec; else 1.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import softras  # noqa: E402
from softras.scene import Scene, load_scene  # noqa: E402
from softras.verification.verifier import FAIL, NOT_SUPPORTED, VERDICT_NAMES, spec_bounds  # noqa: E402

SCENES = REPO / "scenes"
IMPLEMENTATIONS = ("llvmpipe", "softpipe")

# ---------------------------------------------------------------------------
# Scene mutations (Scene -> Scene, frozen dataclasses: dataclasses.replace)


def _with_draws(scene: Scene, change: Callable) -> Scene:
    """The scene with ``change(draw) -> draw`` applied to every draw."""
    return dataclasses.replace(scene, draws=tuple(change(d) for d in scene.draws))


def _with_textures(scene: Scene, change: Callable) -> Scene:
    """The scene with ``change(texture) -> texture`` applied to every texture."""
    return dataclasses.replace(scene, textures={name: change(t) for name, t in scene.textures.items()})


def uv_half_texel(scene: Scene) -> Scene:
    """Every textured draw's u coordinates + 0.5 / (its texture's width)."""
    def change(draw):
        name = draw.material.texture
        if name is None or draw.mesh.uvs is None:
            return draw
        width = scene.textures[name].levels[0].shape[1]
        uvs = np.array(draw.mesh.uvs, dtype=np.float64)
        uvs[:, 0] += 0.5 / width
        return dataclasses.replace(draw, mesh=dataclasses.replace(draw.mesh, uvs=uvs))
    return _with_draws(scene, change)


_WRAP_SWAP = {"repeat": "clamp_to_edge", "clamp_to_edge": "repeat"}


def wrap_swapped(scene: Scene) -> Scene:
    """Every texture's wrap mode repeat <-> clamp_to_edge (s and t; mirrored_repeat kept)."""
    return _with_textures(scene, lambda t: dataclasses.replace(
        t, wrap_s=_WRAP_SWAP.get(t.wrap_s, t.wrap_s), wrap_t=_WRAP_SWAP.get(t.wrap_t, t.wrap_t)))


def nearest_level(scene: Scene) -> Scene:
    """Trilinear -> nearest level: every min filter X_mipmap_linear -> X_mipmap_nearest."""
    return _with_textures(scene, lambda t: dataclasses.replace(
        t, min_filter=t.min_filter.replace("_mipmap_linear", "_mipmap_nearest")))


def mipmaps_dropped(scene: Scene) -> Scene:
    """Mipmaps dropped: every min filter X_mipmap_Y -> X (linear_mipmap_* -> linear)."""
    return _with_textures(scene, lambda t: dataclasses.replace(t, min_filter=t.min_filter.split("_mipmap_")[0]))


def _window(scene: Scene, draw) -> tuple[np.ndarray, np.ndarray]:
    """(N, 4) clip coordinates of a draw's vertices and its (4, 4) model -> clip matrix."""
    mvp = (np.asarray(scene.camera.projection, np.float64) @ np.asarray(scene.camera.view, np.float64)
           @ np.asarray(draw.world, np.float64))
    positions = np.asarray(draw.mesh.positions, np.float64)
    return np.c_[positions, np.ones(len(positions))] @ mvp.T, mvp


def moved_vertex(scene: Scene, dx: float = 1.0, dy: float = 0.0) -> Scene:
    """One vertex moved by (dx, dy) pixels in window space.

    The vertex: of the first triangle draw, the one (used by a triangle, in
    front of the eye) farthest inside the viewport. Its clip position gets
    ``x_c += 2 dx / W * w_c`` (and y likewise) and is mapped back to model
    space through the inverse model-view-projection, so its window position
    moves by exactly (dx, dy) and its depth and w stay.
    """
    for index, draw in enumerate(scene.draws):
        if draw.mesh.primitive != "triangles":
            continue
        clip, mvp = _window(scene, draw)
        w = clip[:, 3]
        used = np.zeros(len(clip), bool)
        used[np.asarray(draw.mesh.indices).ravel()] = True
        with np.errstate(divide="ignore", invalid="ignore"):
            x = (clip[:, 0] / w + 1) * scene.width / 2
            y = (clip[:, 1] / w + 1) * scene.height / 2
        margin = np.minimum.reduce([x, scene.width - x, y, scene.height - y])
        margin = np.where(used & (w > 0) & np.isfinite(margin), margin, -np.inf)
        k = int(np.argmax(margin))
        if margin[k] <= 1:
            continue
        moved = clip[k] + np.array([2 * dx / scene.width * w[k], 2 * dy / scene.height * w[k], 0.0, 0.0])
        model = np.linalg.solve(mvp, moved)
        positions = np.array(draw.mesh.positions, dtype=np.float64)
        positions[k] = model[:3] / model[3]
        mesh = dataclasses.replace(draw.mesh, positions=positions)
        draws = list(scene.draws)
        draws[index] = dataclasses.replace(draw, mesh=mesh)
        return dataclasses.replace(scene, draws=tuple(draws))
    raise ValueError(f"{scene.source}: no triangle vertex inside the viewport to move")


COLOUR_STEP = 5.0 / 255.0


def colour_off(scene: Scene) -> Scene:
    """Every draw's material colour off by 5/255 in R, G and B (up where that stays <= 1, else down)."""
    def change(draw):
        color = np.array(draw.material.color, dtype=np.float64)
        rgb = color[:3]
        color[:3] = np.where(rgb + COLOUR_STEP <= 1.0, rgb + COLOUR_STEP, rgb - COLOUR_STEP)
        return dataclasses.replace(draw, material=dataclasses.replace(draw.material, color=color))
    return _with_draws(scene, change)


def shininess_up(scene: Scene) -> Scene:
    """Every lit draw's shininess x 1.5."""
    return _with_draws(scene, lambda d: d if d.material.shading == "unlit" else dataclasses.replace(
        d, material=dataclasses.replace(d.material, shininess=d.material.shininess * 1.5)))


LIGHT_MOVE = 0.5          # world units, the first point light along x
LIGHT_TURN = 5.0          # degrees, the first directional light (when there is no point light)


def light_moved(scene: Scene) -> Scene:
    """The first point light moved by LIGHT_MOVE world units along x (or, with
    no point light, the first directional light turned by LIGHT_TURN degrees about y)."""
    lights = list(scene.lights)
    for i, light in enumerate(lights):
        if light.type == "point":
            lights[i] = dataclasses.replace(light, position=np.asarray(light.position) + [LIGHT_MOVE, 0.0, 0.0])
            break
    else:
        for i, light in enumerate(lights):
            if light.type == "directional":
                a = np.radians(LIGHT_TURN)
                turn = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
                lights[i] = dataclasses.replace(light, direction=turn @ np.asarray(light.direction))
                break
        else:
            raise ValueError(f"{scene.source}: no light to move")
    return dataclasses.replace(scene, lights=tuple(lights))


_BLEND_SWAP = {"over": "over_straight", "over_straight": "over"}


def blend_swapped(scene: Scene) -> Scene:
    """Every draw's blend over (premultiplied) <-> over_straight."""
    return _with_draws(scene, lambda d: dataclasses.replace(d, blend=_BLEND_SWAP.get(d.blend, d.blend)))


_CULL_SWAP = {"back": "front", "front": "back"}


def culling_flipped(scene: Scene) -> Scene:
    """Every draw's face culling back <-> front."""
    return _with_draws(scene, lambda d: dataclasses.replace(d, cull=_CULL_SWAP.get(d.cull, d.cull)))


# ---------------------------------------------------------------------------
# Code patches (context managers: the stage is patched while softras renders)


@contextlib.contextmanager
def _patched(module, name: str, replacement):
    original = getattr(module, name)
    setattr(module, name, replacement)
    try:
        yield original
    finally:
        setattr(module, name, original)


def _tie_rule_patch(rule: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]):
    """A context manager: softras.pipeline.setup.setup_triangles with ``edge_inclusive = rule(a, b, inclusive)``."""
    from softras.pipeline import setup

    @contextlib.contextmanager
    def patch():
        original = setup.setup_triangles

        def setup_triangles(*args, **kwargs):
            tris = original(*args, **kwargs)
            return dataclasses.replace(tris, edge_inclusive=rule(tris.edge_a, tris.edge_b, tris.edge_inclusive))

        with _patched(setup, "setup_triangles", setup_triangles):
            yield
    return patch


#: Consistent swap: an edge is inclusive when it is a right edge (A < 0) or a
#: top edge (A == 0, B < 0) -- the opposite of softras's / llvmpipe's
#: left-or-bottom rule. Two triangles sharing an edge have opposite (A, B), so
#: a sample exactly on the edge still goes to exactly one of them.
fill_rule_swapped = _tie_rule_patch(lambda a, b, inclusive: (a < 0) | ((a == 0) & (b < 0)))

#: Non-conformant: no edge is inclusive, so a sample exactly on an edge shared
#: by two triangles is drawn by neither (a gap).
fill_rule_ties_excluded = _tie_rule_patch(lambda a, b, inclusive: np.zeros_like(inclusive))


@contextlib.contextmanager
def perspective_off():
    """softras.pipeline.interpolate.perspective_weights returns the screen-space
    (affine) barycentrics: attributes, texture coordinates and their
    derivatives interpolated without perspective correction."""
    from softras.pipeline import interpolate

    with _patched(interpolate, "perspective_weights", lambda lam, inv_w: lam / lam.sum(axis=1, keepdims=True)):
        yield


# ---------------------------------------------------------------------------
# The list


@dataclass(frozen=True)
class Mutation:
    """A planted bug: ``mutate`` (Scene -> Scene) or ``patch`` (a context
    manager factory, rendered with ``fast_path=False``), the scenes it is
    planted in, and whether the GL specification permits it."""

    name: str
    title: str
    scenes: tuple[str, ...]
    mutate: Callable[[Scene], Scene] | None = None
    patch: Callable[[], contextlib.AbstractContextManager] | None = None
    permitted: bool = False
    note: str = ""

    def render(self, scene: Scene) -> np.ndarray:
        """softras's picture of the scene with this bug planted."""
        from softras.renderer import render_scene

        if self.patch is None:
            return render_scene(self.mutate(scene), precision="gl")
        with self.patch():
            return render_scene(scene, precision="gl", fast_path=False)


MUTATIONS: tuple[Mutation, ...] = (
    Mutation("uv_half_texel", "uv + 0.5 texel (u)", ("texture_wrap_modes", "texture_photo", "texture_npot"),
             mutate=uv_half_texel),
    Mutation("wrap_swapped", "wrap repeat <-> clamp_to_edge",
             ("texture_wrap_modes", "texture_floor_trilinear", "texture_npot"), mutate=wrap_swapped),
    # Not texture_npot: its NPOT noise levels may be any value of the texels
    # near each footprint (texture_bounds.generated_levels), a wrong level too.
    Mutation("nearest_level", "trilinear -> nearest level (linear_mipmap_nearest)",
             ("texture_floor_trilinear", "texture_photo"), mutate=nearest_level),
    Mutation("mipmaps_dropped", "mipmaps dropped (min filter X_mipmap_Y -> X)",
             ("texture_floor_trilinear", "texture_mip_level_colors", "texture_photo"), mutate=mipmaps_dropped),
    Mutation("vertex_moved", "a vertex moved by 1 px (window x)",
             ("fill_rule_grid", "culling_back", "perspective_gradient"), mutate=moved_vertex),
    Mutation("colour_off", "material colour off by 5/255",
             ("perspective_gradient", "fill_rule_grid", "lit_spheres", "blend_equations"), mutate=colour_off),
    Mutation("fill_rule_swapped", "fill rule swapped consistently (top-right inclusive)",
             ("fill_rule_grid", "slivers", "tiny_triangles", "extreme_sliver_fan"), patch=fill_rule_swapped,
             permitted=True,
             note="permitted by the spec (GL 4.6 section 14.6.1: exactly one of two polygons sharing an edge "
                  "draws a sample on it; which one is the implementation's choice)"),
    Mutation("fill_rule_ties_excluded", "fill rule: ties excluded on every edge (gaps)",
             ("fill_rule_grid", "fan_shared_edges", "blend_self_overlap", "extreme_sliver_fan"),
             patch=fill_rule_ties_excluded),
    Mutation("shininess_up", "shininess x 1.5", ("lit_spheres", "displaced_grid"), mutate=shininess_up),
    Mutation("light_moved", f"point light moved {LIGHT_MOVE} units (x)", ("lit_spheres", "displaced_grid"),
             mutate=light_moved),
    Mutation("blend_swapped", "blend over <-> over_straight",
             ("blend_equations", "transparent_over_opaque", "blend_self_overlap"), mutate=blend_swapped),
    Mutation("culling_flipped", "culling back <-> front",
             ("culling_back", "culling_front", "sphere_back_culled", "lit_spheres"), mutate=culling_flipped),
    Mutation("perspective_off", "perspective correction off (affine barycentrics)",
             ("perspective_gradient", "texture_floor_trilinear", "near_plane_crossing"), patch=perspective_off),
)


def quick(mutations=MUTATIONS) -> tuple[Mutation, ...]:
    """Each mutation in its first scene only (the test's selection)."""
    return tuple(dataclasses.replace(m, scenes=m.scenes[:1]) for m in mutations)


def scene_names(mutations) -> list[str]:
    """Every scene the mutations use, in first-use order."""
    names: dict[str, None] = {}
    for m in mutations:
        names.update(dict.fromkeys(m.scenes))
    return list(names)


def scene_path(name: str) -> Path:
    return SCENES / f"{name}.json"


# ---------------------------------------------------------------------------
# GL's pictures: in this process, or in a child with GALLIUM_DRIVER set

_CHILD = r"""
import json, sys
from pathlib import Path
import numpy as np
import glref
from softras.scene import load_scene

out, paths = Path(sys.argv[1]), sys.argv[2:]
pictures, reasons = {}, {}
for path in paths:
    try:
        pictures[Path(path).stem] = glref.render(load_scene(path))
    except (glref.NotSupported, NotImplementedError) as exc:
        reasons[Path(path).stem] = " ".join(str(exc).split())
out.mkdir(parents=True, exist_ok=True)
np.savez_compressed(out / "pictures.npz", **pictures)
(out / "info.json").write_text(json.dumps({"info": glref.info(), "not_supported": reasons}, indent=1))
"""


@dataclass
class Reference:
    """One GL implementation's pictures: ``info`` (glref.info()), and per scene
    name an (H, W, 4) picture, or a string saying why GL could not draw it."""

    name: str
    info: dict
    pictures: dict[str, np.ndarray | str]
    seconds: float = 0.0


def gl_pictures_subprocess(driver: str | None, names, name: str | None = None,
                           folder: str | os.PathLike | None = None) -> Reference:
    """GL's pictures of the scenes, drawn by a child process with
    ``GALLIUM_DRIVER=driver`` (None: the environment's GL), written to
    ``folder`` (default a temporary one) as :func:`recorded_pictures` reads them."""
    start = time.perf_counter()
    paths = [str(scene_path(n)) for n in names]
    env = dict(os.environ) if driver is None else dict(os.environ, GALLIUM_DRIVER=driver)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
    with tempfile.TemporaryDirectory(prefix=f"planted_{driver}_") as scratch:
        out = Path(folder) if folder is not None else Path(scratch)
        done = subprocess.run([sys.executable, "-c", _CHILD, str(out), *paths], env=env, cwd=str(REPO),
                              capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(f"GL pictures with GALLIUM_DRIVER={driver} failed "
                               f"(exit {done.returncode}): {done.stderr.strip()[-2000:]}")
        reference = recorded_pictures(out, names, name or driver)
    renderer = str(reference.info.get("GL_RENDERER", ""))
    if driver is not None and not renderer.startswith(driver):
        raise RuntimeError(f"asked for GALLIUM_DRIVER={driver}, got GL_RENDERER {renderer!r}")
    reference.seconds = time.perf_counter() - start
    return reference


def recorded_pictures(folder: str | os.PathLike, names, name: str | None = None) -> Reference:
    """GL's pictures recorded in ``folder`` (``pictures.npz``: one (H, W, 4)
    picture per scene name; ``info.json``: ``{"info": glref.info(),
    "not_supported": {name: reason}}``), as ``--draw FOLDER`` writes them on
    the machine with that GL (a GPU machine, say); a scene missing there is
    "not recorded"."""
    folder = Path(folder)
    record = json.loads((folder / "info.json").read_text(encoding="utf-8"))
    with np.load(folder / "pictures.npz", allow_pickle=False) as data:
        stored = {key: data[key] for key in data.files}
    reasons = record.get("not_supported", {})
    pictures: dict[str, np.ndarray | str] = {n: stored[n] if n in stored else reasons.get(n, "not recorded")
                                             for n in names}
    info = record["info"]
    label = name or str(info.get("GL_RENDERER", "gl")).split("/")[0].split()[0]
    return Reference(label, info, pictures)


def gl_pictures_in_process(names, name: str | None = None) -> Reference:
    """GL's pictures of the scenes from this process's glref context."""
    import glref

    start = time.perf_counter()
    pictures: dict[str, np.ndarray | str] = {}
    for n in names:
        try:
            pictures[n] = glref.render(load_scene(scene_path(n)))
        except (glref.NotSupported, NotImplementedError) as exc:
            pictures[n] = " ".join(str(exc).split())
    info = glref.info()
    label = name or str(info.get("GL_RENDERER", "gl")).split()[0]
    return Reference(label, info, pictures, time.perf_counter() - start)


# ---------------------------------------------------------------------------
# Judging


@dataclass
class Row:
    """One verdict: a (mutation or None) x scene x implementation x profile."""

    mutation: str | None        # None: the unmodified softras picture
    scene: str
    implementation: str
    profile: str
    verdict: str
    expected: str               # "fail", "not fail" or "any" (shown for information)
    outside_image: int | None = None
    outside_reference: int | None = None
    changed_pixels: int | None = None   # pixels the mutation changed in softras's picture
    worst_255: float | None = None      # the image's largest excess beyond the spec bounds, in 1/255
    reasons: list[str] = dataclasses.field(default_factory=list)
    seconds: float = 0.0

    @property
    def ok(self) -> bool:
        if self.verdict == NOT_SUPPORTED or self.expected == "any":
            return True         # not judged (reported as such), or shown for information
        return (self.verdict == FAIL) == (self.expected == "fail")

    def to_dict(self) -> dict:
        out = dataclasses.asdict(self)
        out["ok"] = self.ok
        return out


def _judge(scene: Scene, image, reference, ref: Reference, profile: str = "spec",
           bounds=None) -> tuple[str, dict, list[str]]:
    if isinstance(reference, str):
        return NOT_SUPPORTED, {}, [f"GL cannot draw the scene: {reference}"]
    result = softras.verify(scene, image, reference, profile=profile, capabilities=ref.info, bounds=bounds)
    figures = dict(result.figures)
    if result.bounds is not None:
        value = np.asarray(image, np.float64) / (255.0 if np.asarray(image).dtype == np.uint8 else 1.0)
        excess = np.maximum(result.bounds.low() - value, value - result.bounds.high()).max()
        figures["worst_255"] = round(max(0.0, 255.0 * float(excess)), 2)
    return result.verdict, figures, list(result.reasons)


def run(references: list[Reference], mutations=MUTATIONS, *, log=None) -> list[Row]:
    """Judge every unmodified scene and every planted bug against every reference."""
    from softras.renderer import render_scene

    rows: list[Row] = []
    for name in scene_names(mutations):
        scene = load_scene(scene_path(name))
        start = time.perf_counter()
        clean = render_scene(scene, precision="gl")
        clean_seconds = time.perf_counter() - start
        # The spec bounds depend on the scene and the GL's capabilities, not on
        # the picture judged: one set per reference for every picture of the scene.
        bounds = {ref.name: spec_bounds(scene, ref.info) for ref in references
                  if not isinstance(ref.pictures[name], str)}
        for ref in references:
            start = time.perf_counter()
            verdict, figures, reasons = _judge(scene, clean, ref.pictures[name], ref, bounds=bounds.get(ref.name))
            rows.append(Row(None, name, ref.name, "spec", verdict, "not fail", figures.get("outside_image"),
                            figures.get("outside_reference"), 0, figures.get("worst_255"), reasons,
                            clean_seconds + time.perf_counter() - start))
            if log:
                log(_row_line(rows[-1]))
        for m in mutations:
            if name not in m.scenes:
                continue
            start = time.perf_counter()
            image = m.render(scene)
            render_seconds = time.perf_counter() - start
            changed = int((np.asarray(image) != np.asarray(clean)).any(axis=-1).sum())
            for ref in references:
                start = time.perf_counter()
                verdict, figures, reasons = _judge(scene, image, ref.pictures[name], ref,
                                                   bounds=bounds.get(ref.name))
                rows.append(Row(m.name, name, ref.name, "spec", verdict, "not fail" if m.permitted else "fail",
                                figures.get("outside_image"), figures.get("outside_reference"), changed,
                                figures.get("worst_255"), reasons,
                                render_seconds + time.perf_counter() - start))
                if log:
                    log(_row_line(rows[-1]))
                if m.permitted and ref.info.get("GL_RENDERER", "").startswith("llvmpipe"):
                    start = time.perf_counter()
                    verdict, figures, reasons = _judge(scene, image, ref.pictures[name], ref, "strict")
                    rows.append(Row(m.name, name, ref.name, "strict", verdict, "any", None, None, changed, None,
                                    reasons, time.perf_counter() - start))
                    if log:
                        log(_row_line(rows[-1]))
    return rows


def _row_line(row: Row) -> str:
    what = row.mutation or "(unmodified)"
    mark = "ok" if row.ok else "UNEXPECTED"
    return (f"{what:26s} {row.scene:26s} {row.implementation:9s} {row.profile:6s} "
            f"{VERDICT_NAMES[row.verdict]:16s} outside {row.outside_image} / {row.outside_reference} "
            f"(worst {row.worst_255}/255)  "
            f"changed {row.changed_pixels}  {row.seconds:.1f}s  {mark}")


def false_failures(rows: list[Row]) -> list[Row]:
    """Unmodified scenes (and permitted mutations) that FAILed under spec."""
    return [r for r in rows if r.profile == "spec" and r.expected == "not fail" and r.verdict == FAIL]


def missed(rows: list[Row]) -> list[Row]:
    """Rows whose verdict is not the expected one (planted bugs that did not FAIL, ...)."""
    return [r for r in rows if not r.ok]


# ---------------------------------------------------------------------------
# Report


def _cell(row: Row | None) -> str:
    if row is None:
        return "--"
    text = VERDICT_NAMES[row.verdict]
    if row.profile == "spec" and row.outside_image:
        text += f" ({row.outside_image} px, up to {row.worst_255:.0f}/255)"
    elif row.profile == "spec" and row.outside_image is not None:
        text += " (0 px)"
    return text if row.ok else f"**{text}** (unexpected)"


def table(rows: list[Row], mutations=MUTATIONS, implementations=None) -> str:
    """The Markdown table: one line per (mutation, scene, profile), a column per implementation."""
    implementations = implementations or list(dict.fromkeys(r.implementation for r in rows))
    titles = {m.name: m.title for m in mutations}
    index = {(r.mutation, r.scene, r.profile, r.implementation): r for r in rows}
    keys = list(dict.fromkeys((r.mutation, r.scene, r.profile) for r in rows))
    # Unmodified scenes first, then the mutations in list order.
    order = {None: -1, **{m.name: i for i, m in enumerate(mutations)}}
    place = {m.name: {scene: i for i, scene in enumerate(m.scenes)} for m in mutations}
    keys.sort(key=lambda k: (order.get(k[0], len(order)), k[2] != "spec",
                             k[1] if k[0] is None else place.get(k[0], {}).get(k[1], 0)))
    head = ["planted bug", "scene", "profile", "changed px"] + implementations + ["expected"]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    for mutation, scene, profile in keys:
        first = next(index[(mutation, scene, profile, i)] for i in implementations
                     if (mutation, scene, profile, i) in index)
        title = "(none: unmodified softras)" if mutation is None else titles.get(mutation, mutation)
        expected = {"fail": "FAIL", "not fail": "not FAIL", "any": "(for information)"}[first.expected]
        cells = [title, scene, profile, str(first.changed_pixels)]
        cells += [_cell(index.get((mutation, scene, profile, i))) for i in implementations]
        lines.append("| " + " | ".join(cells + [expected]) + " |")
    return "\n".join(lines)


def summary(rows: list[Row]) -> dict:
    """Counts for the report and the commit message."""
    spec = [r for r in rows if r.profile == "spec"]
    bugs = [r for r in spec if r.mutation is not None and r.expected == "fail"]
    judged = [r for r in bugs if r.verdict != NOT_SUPPORTED]
    permitted = [r for r in spec if r.mutation is not None and r.expected == "not fail"]
    clean = [r for r in spec if r.mutation is None]
    return {
        "planted_bug_verdicts": len(judged),
        "planted_bugs_failed": sum(r.verdict == FAIL for r in judged),
        "planted_bugs_not_supported": len(bugs) - len(judged),
        "permitted_verdicts": len(permitted),
        "permitted_failed": sum(r.verdict == FAIL for r in permitted),
        "unmodified_verdicts": len(clean),
        "false_failures": sum(r.verdict == FAIL for r in clean),
        "strict_verdicts": {VERDICT_NAMES[v]: sum(r.profile == "strict" and r.verdict == v for r in rows)
                            for v in VERDICT_NAMES if any(r.profile == "strict" and r.verdict == v for r in rows)},
        "unexpected": len(missed(rows)),
    }


def summary_text(counts: dict) -> str:
    return (f"planted bugs: {counts['planted_bugs_failed']} of {counts['planted_bug_verdicts']} verdicts FAIL"
            + (f" ({counts['planted_bugs_not_supported']} NOT SUPPORTED)" if counts["planted_bugs_not_supported"]
               else "")
            + f"; permitted (consistent fill-rule swap): {counts['permitted_failed']} of "
              f"{counts['permitted_verdicts']} FAIL under spec (strict on llvmpipe: "
              + ", ".join(f"{n} {k}" for k, n in counts["strict_verdicts"].items())
              + f"); unmodified scenes: {counts['false_failures']} false failures of "
              f"{counts['unmodified_verdicts']} verdicts")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", metavar="FILE", help="write every verdict (with reasons) as JSON")
    parser.add_argument("--quick", action="store_true", help="each planted bug in its first scene only")
    parser.add_argument("--implementations", default=",".join(IMPLEMENTATIONS),
                        help="Gallium drivers drawing the references, each in a child process "
                             "(default llvmpipe,softpipe)")
    parser.add_argument("--recorded", metavar="FOLDER", action="append", default=[],
                        help="also judge against a GL's pictures recorded elsewhere with --draw (repeatable)")
    parser.add_argument("--draw", metavar="FOLDER",
                        help="only draw this machine's GL pictures of the scenes into FOLDER, and exit")
    parser.add_argument("--only", metavar="NAMES", help="comma-separated mutation names")
    parser.add_argument("-v", "--verbose", action="store_true", help="print each verdict as it is made")
    args = parser.parse_args(argv)

    mutations = MUTATIONS
    if args.only:
        wanted = set(args.only.split(","))
        unknown = wanted - {m.name for m in MUTATIONS}
        if unknown:
            parser.error(f"unknown mutation(s): {', '.join(sorted(unknown))}")
        mutations = tuple(m for m in MUTATIONS if m.name in wanted)
    if args.quick:
        mutations = quick(mutations)
    started = time.perf_counter()
    names = scene_names(mutations)
    if args.draw:
        ref = gl_pictures_subprocess(None, names, folder=args.draw)
        print(f"{args.draw}: {ref.info.get('GL_RENDERER')}, {len(names)} scenes in {ref.seconds:.1f} s")
        return 0
    references = [gl_pictures_subprocess(driver, names) for driver in args.implementations.split(",") if driver]
    references += [recorded_pictures(folder, names) for folder in args.recorded]
    log = (lambda line: print(line, file=sys.stderr, flush=True)) if args.verbose else None
    rows = run(references, mutations, log=log)
    seconds = time.perf_counter() - started
    counts = summary(rows)

    print(table(rows, mutations, [r.name for r in references]))
    print()
    for ref in references:
        print(f"- {ref.name}: {ref.info.get('GL_RENDERER')}, {ref.info.get('GL_VERSION')}, "
              f"GL_SUBPIXEL_BITS {ref.info.get('subpixel_bits')} ({ref.seconds:.1f} s for its pictures)")
    print(f"- {summary_text(counts)}")
    print(f"- {len(rows)} verdicts in {seconds:.0f} s")
    for r in missed(rows):
        print(f"- UNEXPECTED: {r.mutation or '(unmodified)'} on {r.scene}, {r.implementation}, {r.profile}: "
              f"{VERDICT_NAMES[r.verdict]}: {'; '.join(r.reasons)}")
    if args.json:
        record = {"summary": counts, "seconds": round(seconds, 1),
                  "implementations": {ref.name: {k: ref.info.get(k) for k in
                                                 ("GL_RENDERER", "GL_VERSION", "subpixel_bits")}
                                      for ref in references},
                  "mutations": [{"name": m.name, "title": m.title, "scenes": list(m.scenes),
                                 "permitted": m.permitted, "note": m.note} for m in mutations],
                  "rows": [r.to_dict() for r in rows]}
        Path(args.json).write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")
    return 1 if missed(rows) else 0


if __name__ == "__main__":
    sys.exit(main())
