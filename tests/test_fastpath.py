"""The gl fast path (softras.kernels.draw) returns the general pipeline's bytes exactly.

Every scene in scenes/ is rendered at its own sample count and at 4x MSAA
through both paths (``fast_path=False`` forces the stages of
softras.pipeline.render); scenes the fast path does not support must say why.
Seeded random scenes add what the conformance scenes do not stress: many
overlapping triangles with every depth function and blend mode, triangles
crossing every clip plane, both windings with culling, and textures with
every filter and wrap mode.
"""

from __future__ import annotations

from pathlib import Path

import numba
import numpy as np
import pytest

import softras
from softras.kernels import draw as fastpath
from softras.kernels import interpolate as k_interpolate
from softras.kernels import lanes as k_lanes
from softras.kernels import light as k_light
from softras.kernels import lines as k_lines
from softras.kernels import ops as k_ops
from softras.kernels import rasterize as k_rasterize
from softras.kernels import rgba8 as k_rgba8
from softras.kernels import setup as k_setup
from softras.kernels import texture as k_texture
from softras.pipeline import fragment, sampling, texture_beyond, vertex
from softras.pipeline.ops import blend_byte
from softras.renderer import render_scene

SCENES = sorted((Path(__file__).resolve().parents[1] / "scenes").glob("*.json"))


def both_paths(scene, **options):
    """(general, fast) images of one scene; fails unless the fast path takes it."""
    reason = fastpath.unsupported(scene, precision="gl", clipping=options.get("clipping"))
    assert reason is None, reason
    return (render_scene(scene, precision="gl", fast_path=False, **options),
            render_scene(scene, precision="gl", **options))


def assert_same(general, fast, what):
    differ = (general != fast).any(axis=-1)
    assert not differ.any(), (f"{what}: {int(differ.sum())} pixels differ, first at row/col "
                              f"{np.argwhere(differ)[0].tolist()}")


def fresh(kernel):
    """A compile of a cached kernel helper from its source as it is now, not
    cached.  numba keys a function's cache on its own file: a helper that
    reads another module's constants (the lane rows of
    `softras.kernels.lanes`) loads its old code after an edit of that module
    alone (the drivers are keyed on every kernel source, so renders are not
    affected).  Tests that call such a helper directly call a fresh one."""
    options = {key: value for key, value in kernel.targetoptions.items() if key not in ("cache", "nopython")}
    return numba.njit(**options)(kernel.py_func)


@pytest.mark.parametrize("samples", [None, 4])
@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_every_scene_is_bit_identical_or_dispatched(path, samples):
    scene = softras.load_scene(path)
    reason = fastpath.unsupported(scene, precision="gl", clipping=None)
    if reason is not None:
        # Dispatched to the general path: the reason names a feature the scene uses.
        assert any(word in reason for word in ("lines with", "texture",
                                               "alpha test")), reason
        return
    assert_same(*both_paths(scene, samples=samples), f"{path.name} samples={samples}")


def test_unsupported_options_take_the_general_path():
    scene = softras.load_scene(SCENES[0])
    assert fastpath.unsupported(scene, precision="exact", clipping=None)
    assert fastpath.unsupported(scene, precision="gl", clipping="guard_band")


DEPTHS = ["less", "lequal", "equal", "greater", "gequal", "notequal", "always", "never", False]
BLENDS = ["none", "over", "over_straight", "add", "subtract", "reverse_subtract", "min", "max"]


def random_scene(seed: int, *, textured: bool = False, width: int = 97, height: int = 75,
                 vectorised: bool | str = False) -> dict:
    """Overlapping random triangles in clip space (some crossing the frustum, w
    from near 0 to 3), random colours with alpha, per-node depth / blend / cull.
    vectorised: textures that the fast path filters in lanes (`_lanes_bilinear_fixed`:
    linear image filters, power-of-two or clamped sizes, both fixed-point wraps;
    "nearest": `_lanes_nearest_fixed`, nearest image filters),
    uv up to +-60, and every third node without vertex colours (white: the
    texel's bytes are the fragment's, `fastpath.plain_colors`)."""
    rng = np.random.default_rng(seed)
    nodes = []
    filters = ["nearest", "linear", "nearest_mipmap_nearest", "linear_mipmap_nearest",
               "nearest_mipmap_linear", "linear_mipmap_linear"]
    textures = {}
    if vectorised:
        for k, (size, wrap_s, wrap_t) in enumerate([([16, 16], "repeat", "repeat"),
                                                    ([13, 7], "clamp_to_edge", "clamp_to_edge"),
                                                    ([32, 8], "repeat", "clamp_to_edge"),
                                                    ([8, 32], "clamp_to_edge", "repeat")]):
            image = "nearest" if vectorised == "nearest" else "linear"
            textures[f"t{k}"] = {"procedural": "noise" if k % 2 else "checker", "size": size,
                                 "wrap_s": wrap_s, "wrap_t": wrap_t, "mag_filter": image,
                                 "min_filter": [image, f"{image}_mipmap_nearest",
                                                f"{image}_mipmap_linear"][(seed + k) % 3]}
    elif textured:
        for k, (wrap_s, wrap_t) in enumerate([("repeat", "repeat"), ("clamp_to_edge", "mirrored_repeat"),
                                              ("mirrored_repeat", "clamp_to_edge"), ("repeat", "clamp_to_edge")]):
            textures[f"t{k}"] = {"procedural": "noise" if k % 2 else "checker", "size": [[16, 16], [13, 7],
                                 [32, 5], [9, 9]][k], "wrap_s": wrap_s, "wrap_t": wrap_t,
                                 "min_filter": filters[(seed + k) % 6], "mag_filter": ["nearest", "linear"][k % 2]}
    for k in range(6):
        n = int(rng.integers(1, 40))
        # World positions around the camera's view: some cross the near
        # (z > 2) and far (z < -1.5) planes and the sides of the frustum.
        xyz = rng.uniform([-2.5, -2.0, -2.5], [2.5, 2.0, 2.4], size=(3 * n, 3))
        mesh = {"positions": xyz.tolist(),
                "indices": np.arange(3 * n).reshape(n, 3).tolist(),
                "colors": rng.uniform(0, 1, size=(3 * n, 4)).round(3).tolist()}
        node = {"name": f"n{k}", "mesh": mesh,
                "depth_test": DEPTHS[int(rng.integers(len(DEPTHS)))],
                "depth_write": bool(rng.integers(2)),
                "blend": BLENDS[int(rng.integers(len(BLENDS)))],
                "cull": ["none", "back", "front"][int(rng.integers(3))]}
        if vectorised:
            mesh["uvs"] = (rng.uniform(-2, 3, size=(3 * n, 2)) * [[1], [20]][k % 2]).tolist()
            node["material"] = {"texture": f"t{int(rng.integers(4))}"}
            if k % 3 == 0:
                del mesh["colors"]
        elif textured:
            mesh["uvs"] = rng.uniform(-2, 3, size=(3 * n, 2)).tolist()
            node["material"] = {"texture": f"t{int(rng.integers(4))}"}
        nodes.append(node)
    return {"softras_scene": 1, "width": width, "height": height,
            "background": rng.uniform(0, 1, 4).round(2).tolist(), "textures": textures,
            "camera": {"projection": "perspective", "fov_y": 70, "near": 0.5, "far": 4,
                       "eye": [0, 0, 2.5], "target": [0, 0, 0]},
            "nodes": nodes}


def random_line_scene(seed: int) -> dict:
    """`random_scene` with every other node a draw of random lines (crossing
    the frustum too, some of zero length, some axis-aligned), with its own
    depth test, depth write, blend and material colour: lines drawn over,
    under and between triangles."""
    data = random_scene(seed)
    rng = np.random.default_rng(1000 + seed)
    for k, node in enumerate(data["nodes"]):
        if k % 2 == 0:
            continue
        n = int(rng.integers(1, 60))
        xyz = rng.uniform([-2.5, -2.0, -2.5], [2.5, 2.0, 2.4], size=(2 * n, 3))
        xyz[1:4:2] = xyz[0:3:2]                                  # zero length
        xyz[5:8:2, 1] = xyz[4:7:2, 1]                            # horizontal
        xyz[9:12:2, 0] = xyz[8:11:2, 0]                          # vertical
        node["mesh"] = {"primitive": "lines", "positions": xyz[:2 * n].tolist(),
                        "indices": np.arange(2 * n).reshape(n, 2).tolist(),
                        "colors": rng.uniform(0, 1, size=(2 * n, 4)).round(3).tolist()}
        node["material"] = {"color": rng.uniform(0.3, 1, 4).round(2).tolist()}
    return data


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("samples", [1, 4])
def test_random_line_scenes_are_bit_identical(seed, samples):
    """Line draws on the compiled path (`softras.kernels.lines`) give the
    stages' bytes: diamond lines at one sample, rectangular ones at 4."""
    scene = softras.load_scene(random_line_scene(seed))
    assert any(d.mesh.primitive == "lines" for d in scene.draws)
    assert_same(*both_paths(scene, samples=samples), f"random line scene seed {seed}, {samples} samples")


@pytest.mark.parametrize("samples", [1, 4])
def test_lines_across_row_bands_are_bit_identical(samples):
    """The line kernel covers by bands of `k_lines.BAND` rows in parallel:
    long lines crossing several bands (and the frustum), blended "over" and
    depth-tested in a draw, so each pixel must see the lines in draw order,
    give the stages' bytes."""
    rng = np.random.default_rng(77)
    n = 400
    xyz = rng.uniform([-2.5, -2.0, -2.5], [2.5, 2.0, 2.4], size=(2 * n, 3))
    nodes = [{"name": f"wire{k}", "blend": "over", "depth_test": ["less", "always"][k],
              "mesh": {"primitive": "lines", "positions": xyz.tolist(),
                       "indices": np.arange(2 * n).reshape(n, 2).tolist(),
                       "colors": rng.uniform(0, 1, size=(2 * n, 4)).round(3).tolist()}} for k in range(2)]
    scene = softras.load_scene({"softras_scene": 1, "width": 150, "height": 5 * k_lines.BAND + 7,
                                "background": [0, 0, 0, 1], "nodes": nodes,
                                "camera": {"projection": "perspective", "fov_y": 70, "near": 0.5, "far": 4,
                                           "eye": [0, 0, 2.5], "target": [0, 0, 0]}})
    assert_same(*both_paths(scene, samples=samples), f"lines across bands, {samples} samples")


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("samples", [1, 4])
def test_random_scenes_are_bit_identical(seed, samples):
    scene = softras.load_scene(random_scene(seed))
    assert_same(*both_paths(scene, samples=samples), f"random scene seed {seed}, {samples} samples")


def lit_scene(seed: int, shading: str = "gouraud") -> dict:
    """`random_scene` lit with ``shading``: vertex normals in every direction,
    a point and a directional light, random material terms (lit colours
    above 1 and below 0 included: the framebuffer clamps), some draws
    textured."""
    rng = np.random.default_rng(1000 + seed)
    data = random_scene(seed, textured=seed % 2 == 1)
    data["lights"] = [{"type": "point", "position": rng.uniform(-3, 3, 3).tolist(), "color": [1, 0.9, 0.8]},
                      {"type": "directional", "direction": rng.uniform(-1, 1, 3).tolist(), "color": [0.4, 0.5, 0.6]}]
    for node in data["nodes"]:
        n = len(node["mesh"]["positions"])
        node["mesh"]["normals"] = rng.normal(size=(n, 3)).tolist()
        node["material"] = dict(node.get("material", {}), shading=shading,
                                ambient=float(rng.uniform(0, 0.3)), diffuse=float(rng.uniform(0.3, 1.2)),
                                specular=float(rng.uniform(0, 1)), shininess=float(rng.uniform(1, 64)))
    return data


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("samples", [1, 4])
def test_random_gouraud_scenes_are_bit_identical(seed, samples):
    """Gouraud-lit draws on the compiled path equal the stages byte for byte."""
    scene = softras.load_scene(lit_scene(seed))
    assert all(d.material.shading == "gouraud" for d in scene.draws)
    assert_same(*both_paths(scene, samples=samples), f"random Gouraud scene seed {seed}, {samples} samples")


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("samples", [1, 4])
def test_random_flat_scenes_are_bit_identical(seed, samples):
    """Flat-shaded draws on the compiled path (one lit colour per triangle,
    `k_light.flat_corner_colors`, not interpolated) equal the stages byte
    for byte, clipped triangles (which take their source's colour) included."""
    scene = softras.load_scene(lit_scene(seed, "flat"))
    assert all(d.material.shading == "flat" for d in scene.draws)
    assert_same(*both_paths(scene, samples=samples), f"random flat scene seed {seed}, {samples} samples")


# Phong exponents numpy.power special-cases (2, 0.5), and some it does not.
PHONG_SHININESS = [2.0, 0.5, 0.0, 1.0, 32.0, None]


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("samples", [1, 4])
def test_random_phong_scenes_are_bit_identical(seed, samples):
    """Phong-lit draws on the compiled path (`softras.kernels.light`: the
    colour, world position and normal interpolated and lit per pixel) equal
    the stages byte for byte, textured (odd seeds) and clipped triangles
    included."""
    data = lit_scene(seed, "phong")
    if PHONG_SHININESS[seed] is not None:
        for node in data["nodes"]:
            node["material"]["shininess"] = PHONG_SHININESS[seed]
    scene = softras.load_scene(data)
    assert all(d.material.shading == "phong" for d in scene.draws)
    assert_same(*both_paths(scene, samples=samples), f"random Phong scene seed {seed}, {samples} samples")


# Normal and bump maps of every kind of sampler the compiled path filters:
# the vectorised 8.8 filter (power of two, repeat), the float filter
# (mirrored_repeat, an odd size), llvmpipe's anisotropic filter, nearest.
MAP_TEXTURES = {
    "m_lanes": {"procedural": "noise", "size": [16, 16], "min_filter": "linear_mipmap_linear",
                "mag_filter": "linear"},
    "m_float": {"procedural": "checker", "size": [13, 7], "wrap_s": "mirrored_repeat",
                "min_filter": "linear_mipmap_nearest", "mag_filter": "linear"},
    "m_aniso": {"procedural": "noise", "size": [32, 32], "min_filter": "linear_mipmap_linear",
                "mag_filter": "linear", "max_anisotropy": 8},
    "m_nearest": {"procedural": "noise", "size": [9, 9], "wrap_t": "clamp_to_edge",
                  "min_filter": "nearest_mipmap_nearest", "mag_filter": "nearest"},
}


def mapped_scene(seed: int) -> dict:
    """`lit_scene` with Phong shading and, per node, a normal or a bump map
    (`MAP_TEXTURES`, bump scales 0 to 200, uv up to +-10), half of the maps
    on textured draws (odd seeds)."""
    rng = np.random.default_rng(3000 + seed)
    data = lit_scene(seed, "phong")
    data["textures"].update(MAP_TEXTURES)
    names = sorted(MAP_TEXTURES)
    for k, node in enumerate(data["nodes"]):
        mesh, material = node["mesh"], node["material"]
        if "uvs" not in mesh:
            mesh["uvs"] = (rng.uniform(-2, 2, size=(len(mesh["positions"]), 2)) * [1, 5][k % 2]).tolist()
        name = names[(seed + k) % len(names)]
        if (seed + k) % 2:
            material["normal_map"] = name
        else:
            material["bump_map"] = name
            material["bump_scale"] = float([0, 1, 30, 200][(seed + k) % 4] * rng.uniform(0.5, 1.5))
    return data


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("samples", [1, 4])
def test_random_mapped_scenes_are_bit_identical(seed, samples):
    """Normal- and bump-mapped Phong draws on the compiled path
    (`softras.kernels.maps._map_normals`, `k_light._perturb`: the map sampled at each
    quad's level of detail, the normal perturbed in the interpolated
    tangent frame) equal the stages byte for byte, with and without a
    colour texture, every map filter, clipped triangles included."""
    scene = softras.load_scene(mapped_scene(seed))
    kinds = {(d.material.normal_map is not None, d.material.texture is not None) for d in scene.draws}
    assert len(kinds) >= 2, kinds
    assert_same(*both_paths(scene, samples=samples), f"random mapped scene seed {seed}, {samples} samples")


# Sample counts and patterns beyond GL's 1 and 4: the tile driver of any
# count (`fastpath.ANY_SAMPLES`), more than MAX_PASS_SAMPLES in passes, with
# the stages' exact resolve (box) or the tent.
OTHER_SAMPLES = [(2, "halton", "box"), (9, "rotated_grid", "box"), (16, "jittered", "tent"),
                 (sampling.MAX_PASS_SAMPLES, "poisson", "box"), (4, "grid", "tent"), (49, "grid", "box")]


@pytest.mark.parametrize("samples, pattern, resolve", OTHER_SAMPLES)
@pytest.mark.parametrize("kind", ["unlit", "gouraud", "flat", "phong", "textured", "lane_filtered", "mapped",
                                  "lines"])
def test_any_sample_count_and_pattern_is_bit_identical(kind, samples, pattern, resolve):
    """Every kind of draw at other sample counts and patterns (any count,
    any positions) gives the stages' bytes."""
    seed = samples
    if kind == "unlit":
        data = random_scene(seed)
    elif kind in ("gouraud", "flat", "phong"):
        data = lit_scene(seed, kind)
    elif kind == "textured":
        data = random_scene(100 + seed, textured=True)
    elif kind == "lane_filtered":
        data = random_scene(200 + seed, vectorised=True)
    elif kind == "mapped":
        data = mapped_scene(seed)
    else:
        data = random_line_scene(seed)
    scene = softras.load_scene(data)
    assert_same(*both_paths(scene, samples=samples, pattern=pattern, resolve_filter=resolve),
                f"{kind} scene seed {seed}, {samples} samples {pattern}, {resolve} resolve")


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("samples", [1, 4])
def test_random_alpha_tested_scenes_are_bit_identical(seed, samples):
    """Alpha-tested materials (glTF MASK) on the compiled path
    (`k_interpolate._lane_alpha_test`: before the depth test, whole
    fragments) equal the stages byte for byte: unlit, Gouraud, flat and
    Phong, textured (odd seeds) or not, random vertex alphas, every depth
    function and blend mode."""
    shading = ["unlit", "gouraud", "flat", "phong"][seed % 4]
    data = (random_scene(400 + seed, textured=seed % 2 == 1) if shading == "unlit"
            else lit_scene(400 + seed, shading))
    for k, node in enumerate(data["nodes"]):
        node["material"] = dict(node.get("material", {}), alpha_cutoff=[0.5, 0.3, 0.7, 0.0][k % 4])
    for tex in data["textures"].values():           # (texel alphas on both sides of the cutoffs)
        if tex["procedural"] == "checker":
            tex.update(color0=[0.9, 0.8, 0.7, 0.9], color1=[0.2, 0.3, 0.4, 0.35])
    scene = softras.load_scene(data)
    assert all(d.material.alpha_cutoff is not None for d in scene.draws)
    assert_same(*both_paths(scene, samples=samples), f"random alpha-tested {shading} scene seed {400 + seed}")


def test_phong_colors_are_the_stages_to_the_bit():
    """`k_light._phong_colors` lights lanes with the float64 bits of
    `softras.pipeline.render.phong_attributes` and
    `softras.pipeline.fragment.blinn_phong` (a one-ulp difference in a sum
    order would pass the byte-level scene tests almost always: the bytes
    flip only at rounding boundaries).  Random weights, corners, normals
    (zero, so NaN, included), point and directional lights, and each
    special-cased exponent."""
    from types import SimpleNamespace

    from softras.pipeline import render as stages
    from softras.scene.model import Light
    rng = np.random.default_rng(11)
    n = k_lanes.LANES
    lights = [Light("point", rng.uniform(-3, 3, 3), None, np.array([1.0, 0.9, 0.8])),
              Light("directional", None, rng.uniform(-1, 1, 3), np.array([0.4, 0.5, 0.6]))]
    phong_colors = fresh(k_light._phong_colors)
    for trial, shininess in enumerate([2.0, 0.5, 0.0, 1.0, 17.3, 64.0]):
        material = SimpleNamespace(ambient=0.15, diffuse=0.9, specular=0.7, shininess=shininess)
        base = rng.uniform(-0.2, 1.3, (3, 4))
        world = rng.normal(size=(3, 3))
        normals = rng.normal(size=(3, 3)) * (trial != 2)            # trial 2: zero normals
        persp = rng.dirichlet([1, 1, 1], n)
        eye = rng.normal(size=3) * 3
        draw = SimpleNamespace(mesh=SimpleNamespace(normals=normals), world=np.eye(4))
        with np.errstate(all="ignore"):
            colors, position, normal = stages.phong_attributes(persp, lambda v: v[None], np.zeros(n, int),
                                                               base, world, draw)
            expected = fragment.blinn_phong(colors[:, :3], position, normal, eye, lights, material)
        lf = np.zeros((k_lanes._NLF, 2 * n))
        lf[k_lanes._LF_W:k_lanes._LF_W + 3, :n] = persp.T
        table, lighting = k_light.light_table(lights, eye, material)
        lit, lit_rows = np.concatenate([world, normals], axis=1), np.array([[0, 1, 2]])     # (corner k in row k)
        phong_colors(n, 0, base[None], lit, lit_rows, lf, table, tuple(lighting), False)
        got = lf[k_lanes._LF_LIT:k_lanes._LF_LIT + 4, :n].T
        assert np.array_equal(got[:, :3].view(np.int64), expected.view(np.int64)), f"shininess {shininess}"
        assert np.array_equal(got[:, 3], colors[:, 3])


def test_perturbed_normals_are_the_stages_to_the_bit():
    """`k_light._perturb` (per lane, the compiled paths' normal and bump
    mapping) gives the float64 bits of `fragment.perturb_normals`: random
    unit normals, tangents of any length and direction (parallel to the
    normal, zero and NaN included), both handednesses (and zero), and
    tangent-space normals of a normal map (2 rgb - 1) and of a bump map."""
    rng = np.random.default_rng(12)
    n = 4096
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    tangent = np.concatenate([rng.normal(size=(n, 3)) * rng.uniform(0, 3, (n, 1)),
                              rng.choice([-1.0, 1.0, 0.0, -0.5], (n, 1))], axis=1)
    tangent[:64, :3] = normal[:64] * 2.0                    # parallel: T is 0 / 0
    tangent[64:96, :3] = 0.0
    tangent[96:100, 0] = np.nan
    mapped = np.concatenate([rng.integers(0, 256, (n // 2, 3)) / 255.0 * 2.0 - 1.0,
                             np.stack([rng.normal(size=n // 2) * 40, rng.normal(size=n // 2) * 40,
                                       np.ones(n // 2)], axis=1)])
    with np.errstate(all="ignore"):
        expected = fragment.perturb_normals(normal, tangent, mapped)

    @numba.njit(error_model="numpy")
    def perturb_all(normal, tangent, mapped, out):
        for f in range(normal.shape[0]):
            out[f, 0], out[f, 1], out[f, 2] = k_light._perturb(
                normal[f, 0], normal[f, 1], normal[f, 2], tangent[f, 0], tangent[f, 1], tangent[f, 2],
                tangent[f, 3], mapped[f, 0], mapped[f, 1], mapped[f, 2])

    got = np.empty((n, 3))
    perturb_all(normal, tangent, mapped, got)
    same = (got.view(np.int64) == expected.view(np.int64)) | (np.isnan(got) & np.isnan(expected))
    assert same.all(), f"{int((~same.all(axis=1)).sum())} normals differ, first {np.argwhere(~same)[0]}"


def test_world_attributes_are_the_stages_to_the_bit():
    """`k_light._world_attributes` (the Phong inputs of the compiled set-up)
    writes the float64 bits of `vertex.world_positions` and
    `vertex.world_normals` (not unit): random world matrices (a mirror, zero
    entries of both signs), positions and normals with zeros of both signs,
    NaN and infinities."""
    rng = np.random.default_rng(14)
    n = 3000
    for trial in range(4):
        world = np.eye(4)
        world[:3] = rng.normal(size=(3, 4)) * rng.choice([0.0, -0.0, 1.0, 1.0, 1.0], (3, 4))
        world[:3, :3] += np.eye(3) * (trial + 1)                   # (invertible)
        if trial == 1:
            world[0] *= -1.0                                       # a mirror
        positions = rng.normal(size=(n, 3)) * rng.choice([0.0, -0.0, 1.0, 1e300], (n, 3))
        normals = rng.normal(size=(n, 3)) * rng.choice([0.0, -0.0, 1.0], (n, 3))
        positions[:5, 0], normals[5:10, 1] = np.nan, np.inf
        out = np.empty((n, 6))
        with np.errstate(all="ignore"):
            expected = np.concatenate([vertex.world_positions(positions, world),
                                       vertex.world_normals(normals, world, unit=False)], axis=1)
        fresh(k_light._world_attributes)(positions, np.ascontiguousarray(world[:3]), normals,
                                         vertex.normal_rows(world), out)
        same = (out.view(np.int64) == expected.view(np.int64)) | (np.isnan(out) & np.isnan(expected))
        assert same.all(), f"trial {trial}: {int((~same).sum())} values differ"


def test_a_pass_finds_the_eye_and_normal_rows_only_for_lit_draws():
    """`k_light.viewing`: nothing for a pass of unlit draws (they read
    neither the eye nor normal rows); for a lit pass the eye and each lit
    triangle draw's rows, the bits of `vertex.normal_rows`."""
    from softras import bench_scenes
    from softras.scene import ordered_draws
    unlit = softras.load_scene(bench_scenes.parts_scene(64, parts=4))
    assert k_light.viewing(unlit, ordered_draws(unlit)) is None
    lit = softras.load_scene(bench_scenes.parts_scene(64, parts=4, textured=True))
    view = k_light.viewing(lit, ordered_draws(lit))
    assert np.array_equal(view.eye, vertex.eye_position(lit.camera.view))
    assert len(view.normal_rows) == 4
    for draw in lit.draws:
        assert np.array_equal(view.normal_rows[id(draw)], vertex.normal_rows(draw.world))


def test_vertex_and_face_lighting_are_the_stages_to_the_bit():
    """`k_light.base_colors` (Gouraud, per vertex) and `k_light.face_colors`
    (flat, per triangle) give the float64 bits of
    `softras.pipeline.render.vertex_base_colors` and `flat_colors`: random
    meshes under a random world matrix (zero normals and degenerate faces,
    so NaN, included), vertex colours outside [0, 1], point and directional
    lights, each special-cased exponent."""
    from types import SimpleNamespace

    from softras.pipeline import render as stages
    from softras.scene.model import Light
    from softras.scene.transforms import look_at_matrix
    rng = np.random.default_rng(12)
    for trial, shininess in enumerate([2.0, 0.5, 0.0, 1.0, 17.3, 64.0]):
        lights = [Light("point", rng.uniform(-3, 3, 3), None, np.array([1.0, 0.9, 0.8])),
                  Light("directional", None, rng.uniform(-1, 1, 3), np.array([0.4, 0.5, 0.6]))][:1 + trial % 2]
        n = 200
        normals = rng.normal(size=(n, 3))
        normals[:5] = 0.0                                              # zero normals: NaN
        mesh = SimpleNamespace(positions=rng.normal(size=(n, 3)), normals=normals,
                               colors=rng.uniform(-0.2, 1.3, (n, 4)))
        triangles = rng.integers(0, n, (300, 3))
        triangles[:3, 1] = triangles[:3, 0]                            # degenerate faces: NaN
        world = np.eye(4)
        world[:3] = rng.normal(size=(3, 4))
        material = SimpleNamespace(shading="gouraud", color=rng.uniform(0.2, 1, 4), ambient=0.15, diffuse=0.9,
                                   specular=0.7, shininess=shininess)
        scene = SimpleNamespace(lights=lights,
                                camera=SimpleNamespace(view=look_at_matrix(rng.normal(size=3) * 3, np.zeros(3),
                                                                           np.array([0.0, 1.0, 0.0]))))
        draw = SimpleNamespace(mesh=mesh, world=world, material=material)
        with np.errstate(all="ignore"):
            expected = stages.vertex_base_colors(scene, draw)
            got = k_light.base_colors(scene, draw)
            assert np.array_equal(got.view(np.int64), expected.view(np.int64)), f"gouraud, shininess {shininess}"
            material.shading = "flat"
            base = stages.vertex_base_colors(scene, draw)
            world_positions = vertex.world_positions(mesh.positions, world)
            expected = stages.flat_colors(world_positions, triangles, base,
                                          vertex.eye_position(scene.camera.view), lights,
                                          material)[0]
            got = k_light.face_colors(scene, draw, base, triangles)
        assert np.array_equal(got.view(np.int64), expected.view(np.int64)), f"flat, shininess {shininess}"


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("fixed_point", [True, False])
def test_random_textured_scenes_are_bit_identical(seed, fixed_point):
    scene = softras.load_scene(random_scene(100 + seed, textured=True))
    assert_same(*both_paths(scene, texture_fixed_point=fixed_point),
                f"random textured scene seed {100 + seed}, fixed point {fixed_point}")


def stretched_uvs(data: dict) -> dict:
    """A random scene's nodes with their uvs scaled 20x along u, 20x along v
    and 3x both, in turn: minified along one axis, magnified along the other."""
    for k, node in enumerate(data["nodes"]):
        node["mesh"]["uvs"] = (np.asarray(node["mesh"]["uvs"]) * [[1, 20], [20, 1], [3, 3]][k % 3]).tolist()
    return data


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("samples", [1, 4])
@pytest.mark.parametrize("name", texture_beyond.FILTERS)
def test_random_beyond_filter_scenes_are_bit_identical(name, seed, samples):
    """softras's own filters (``texture_filter`` "ripmap", "ewa", "level0",
    `softras.kernels.texture_beyond._beyond_lane`) on the compiled path give
    the stages' bytes (`softras.pipeline.texture_beyond.sample_beyond`):
    every min filter (the ripmap's mipmap_nearest: the nearest level; the
    others: four levels blended), both mag filters, every wrap, odd sizes,
    uv up to +-60 (minified along one axis, magnified along the other: EWA's
    eccentricity cap, its levels and their blend, its empty ellipses on
    the degenerate and w ~ 0 triangles); even seeds name the textures one
    by one, some left to their own filter."""
    data = stretched_uvs(random_scene(300 + seed, textured=True))
    scene = softras.load_scene(data)
    option = name if seed % 2 else {texture: [name, None][k % 2] for k, texture in enumerate(sorted(scene.textures))}
    assert fastpath.unsupported(scene, precision="gl", clipping=None) is None
    assert_same(*both_paths(scene, samples=samples, texture_filter=option),
                f"random {name} scene seed {300 + seed}, {samples} samples")


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("samples", [1, 4])
@pytest.mark.parametrize("image", ["linear", "nearest"])
def test_random_lane_filtered_scenes_are_bit_identical(seed, samples, image):
    """The vectorised filter paths (`k_texture._lanes_bilinear_fixed`,
    `k_texture._lanes_nearest_fixed`) with both of llvmpipe's fixed-point
    wraps (mirrored_repeat filters in float: the scalar path)."""
    scene = softras.load_scene(random_scene(200 + seed, vectorised=True if image == "linear" else image))
    for name, tex in scene.textures.items():
        sampler = k_texture.texture_tables(softras.pipeline.texture.prepare(tex), True)[0]
        assert sampler.vectorised == {"linear": k_texture.VECTORISED_LINEAR,
                                      "nearest": k_texture.VECTORISED_NEAREST}[image], name
    assert_same(*both_paths(scene, samples=samples), f"random lane-filtered scene seed {200 + seed}")


def test_random_coverage_scenes_are_bit_identical():
    """The piglit-style coverage scenes of tests/test_random_triangles.py."""
    from test_random_triangles import coverage_scene, random_triangles
    rng = np.random.default_rng(20261121)
    for kind in ["pixel_centres", "pixel_corners", "subpixel", "slivers", "ties", "large"]:
        for _ in range(4):
            scene = softras.load_scene(coverage_scene(random_triangles(rng, 24, kind, 64, 48), 64, 48))
            assert_same(*both_paths(scene), f"coverage scene {kind}")


def test_bench_grid_is_bit_identical():
    from softras import bench
    scene = softras.load_scene(bench.grid_scene(40, 200))
    assert_same(*both_paths(scene), "bench grid")


@pytest.mark.parametrize("samples", [1, 4])
def test_bench_floor_is_bit_identical(samples):
    """The trilinear floor: white (`plain_colors`), one level near the camera, two further off."""
    from softras import bench
    scene = softras.load_scene(bench.floor_scene(160))
    assert fastpath.plain_colors(np.ones((4, 4)) * scene.draws[0].material.color)
    assert_same(*both_paths(scene, samples=samples), f"bench floor, {samples} samples")


# ----------------------------------------------------------------------------- kernel pieces


def test_branch_free_wrap_equals_wrap_index():
    """`_wrap_select` (lanes) = `texture.wrap_index` for power-of-two sizes in
    every mode, and for any size with clamp_to_edge."""
    from softras.pipeline.texture import WRAP_CODES, wrap_index
    indices = list(range(-70, 70)) + [-2**40 - 3, 2**40 + 5, -2**62, 2**62 - 1]
    for mode in WRAP_CODES.values():
        for size in (1, 2, 4, 8, 64, 4096) + ((3, 7, 13, 100) if mode == WRAP_CODES["clamp_to_edge"] else ()):
            for i in indices:
                assert k_texture._wrap_select(i, size, mode) == wrap_index(i, size, mode), (i, size, mode)


def test_plain_colors_give_the_texel_bytes():
    """`plain_colors`: the fragment colour of white corners, (w0 + w1 + w2)^2 k/255
    (alpha (w0 + w1 + w2) k/255) through `ops.unorm8`, is the texel byte k for
    every k when the weights' sum is 1 within far more than a few ulp."""
    from softras.pipeline.ops import unorm8
    k = np.arange(256)
    for sum_of_weights in 1 + np.array([0.0, 1e-12, -1e-12, 2.0**-52, -2.0**-53, 7 * 2.0**-52, -9 * 2.0**-53]):
        for value in (sum_of_weights * sum_of_weights * (k / 255.0), sum_of_weights * (k / 255.0)):
            assert [unorm8(v) for v in value] == k.tolist(), sum_of_weights
    assert fastpath.plain_colors(np.ones((5, 4)))
    assert not fastpath.plain_colors(np.array([[1.0, 1.0, 1.0, 1.0], [1.0, 1.0, 1.0, 0.999]]))


def unorm8_boundaries() -> np.ndarray:
    """Colour values on `ops.unorm8`'s rounding boundaries: float64 values
    halfway between two float32 values x (even, where the tie goes) and
    next(x) that unorm8 turns into different bytes.  A value one float64
    ulp above gives the other byte."""
    from softras.pipeline.ops import unorm8
    values = []
    for k in range(255):
        a = np.float32((k + 0.5) / 255)
        for _ in range(40):
            a = np.nextafter(a, np.float32(0), dtype=np.float32)
        for _ in range(80):
            b = np.nextafter(a, np.float32(2), dtype=np.float32)
            if unorm8(float(a)) != unorm8(float(b)) and not a.view(np.int32) & 1:
                values.append((float(a) + float(b)) / 2)
                break
            a = b
    return np.array(values)


def test_flat_lane_words_take_the_colour_as_it_is():
    """`_lane_words` with ``flat``: the word is `shade_unlit` then `unorm8`
    of corner 0's colour itself, on unorm8's rounding boundaries
    (`unorm8_boundaries`) at weights that sum to 1 + 3e-16, where
    interpolating the same colour at all three corners rounds every one of
    them the other way."""
    from softras.kernels import interpolate as k_interpolate
    from softras.kernels.lanes import _LF_W, _LI_WORD, _NLF
    from softras.pipeline.fragment import shade_unlit
    from softras.pipeline.ops import unorm8
    boundaries = unorm8_boundaries()
    n = len(boundaries)
    assert n > 50
    colors = np.zeros((n, 3, 4))
    colors[:, 0, :3] = np.stack([boundaries, np.roll(boundaries, 1), np.roll(boundaries, 2)], axis=1)
    colors[:, 0, 3] = 1.0
    colors[:, 1:] = colors[:, :1]        # (the kernels hold zeros there: any value is weighted by 0)
    lf = np.zeros((_NLF, n))
    lf[_LF_W:_LF_W + 3] = np.array([0.3, 0.3, 0.4])[:, None] * (1 + 3e-16)
    li = np.zeros((_LI_WORD + 1, n), np.int64)
    expected = shade_unlit(colors[:, 0], np.ones(4))
    lane_words = fresh(k_interpolate._lane_words)
    for t in range(n):
        lane_words(1, t, colors, lf, li, False, True)
        word = int(li[_LI_WORD, 0])
        assert [(word >> (8 * c)) & 255 for c in range(4)] == [unorm8(v) for v in expected[t]], t


def test_frexp32_equals_math_frexp():
    """`_frexp32` (bits) = math.frexp for normal float32s, (x, 0) for inf / NaN."""
    import math
    rng = np.random.default_rng(3)
    values = np.concatenate([np.float32([1.1754944e-38, 3.4028235e38, 1, 0.5, 0.75, 2, 1e-30]),
                             (10.0 ** rng.uniform(-37, 38, 2000)).astype(np.float32)])
    for x in values:
        m, e = k_texture._frexp32(x)
        assert (float(m), e) == math.frexp(float(x)), x
    for x in np.float32([np.inf, np.nan]):
        m, e = k_texture._frexp32(x)
        assert e == 0 and (m == x or (m != m and x != x))


def quad_derivatives(seed: int) -> np.ndarray:
    """(3000, 4) float32 quad derivatives (ddx_s, ddx_t, ddy_s, ddy_t) over 50
    octaves, the first 400 rows drawn from zero, subnormal, huge, infinite
    and NaN values."""
    rng = np.random.default_rng(seed)
    specials = np.float32([0, 1e-42, 1e-20, 1 / 256, 1, 3e19, 3e38, np.inf, -np.inf, np.nan])
    d = (rng.standard_normal((3000, 4)) * 2.0 ** rng.integers(-30, 20, (3000, 1))).astype(np.float32)
    d[:400] = specials[rng.integers(len(specials), size=(400, 4))]
    return d


def test_quad_lod_equals_choose_levels():
    """`_quad_lod` (selects, bit tricks) = `texture.choose_levels` (gl) on random
    derivatives over 50 octaves, zero, subnormal, huge, inf and NaN ones."""
    from softras.pipeline import texture
    d = quad_derivatives(4)
    for mip, min_filter in ((0, "linear"), (1, "linear_mipmap_nearest"), (2, "linear_mipmap_linear")):
        width, height, n_levels = 64, 16, 7
        sampler = k_texture.Sampler(min_filter=1, mag_filter=0, mip=mip, wrap_s=0, wrap_t=0, fixed8=1,
                                    levels=n_levels, vectorised=0, aniso=0, ripmap=0, beyond=0)
        with np.errstate(all="ignore"):
            du = d[:, :2] * np.float32([width, height])
            dv = d[:, 2:] * np.float32([width, height])
            choice = texture.choose_levels(texture.rho_squared(du, dv), min_filter, n_levels, gl=True)
        for i in range(len(d)):
            level0, level1, frac, image_filter, two = k_texture._quad_lod(sampler, width, height, *d[i])
            magnified = bool(choice.magnified[i])
            assert image_filter == (0 if magnified else 1), d[i]
            assert level0 == (0 if magnified else choice.level0[i]), (d[i], mip)
            if not magnified:
                assert (level1, frac) == (choice.level1[i], choice.frac[i]), (d[i], mip)
            assert two == (not magnified and choice.level1[i] != choice.level0[i] and choice.frac[i] > 0)


def test_aniso_level_equals_llvmpipe_aniso_levels():
    """`k_texture._aniso_level` = `texture.llvmpipe_aniso_levels` on random
    derivatives over 50 octaves and on zeros, subnormals, huge values,
    infinities and NaN."""
    from softras.pipeline import texture
    d = quad_derivatives(5)
    width, height, n_levels = 64, 16, 7
    with np.errstate(all="ignore"):
        expected = texture.llvmpipe_aniso_levels(d[:, :2] * np.float32([width, height]),
                                                 d[:, 2:] * np.float32([width, height]), n_levels)
    got = [k_texture._aniso_level(*d[i], width, height, n_levels - 1) for i in range(len(d))]
    assert got == expected.tolist()


ANISO = [2, 16, 4.5, 1.5]       # (1.5 truncates to 1 in gl: not anisotropic)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("samples", [1, 4])
def test_random_anisotropic_scenes_are_bit_identical(seed, samples):
    """llvmpipe's anisotropic filter on the compiled path
    (`k_texture._aniso_lane`, the stages' `ewa_texel`) equals the stages on
    random textured scenes with every wrap and filter, uv up to +-60 (long
    thin footprints)."""
    data = random_scene(300 + seed, textured=True)
    for name, tex in data["textures"].items():
        tex["max_anisotropy"] = ANISO[(seed + int(name[1])) % len(ANISO)]
    for k, node in enumerate(data["nodes"]):
        node["mesh"]["uvs"] = (np.asarray(node["mesh"]["uvs"]) * [[1, 20], [20, 1]][k % 2]).tolist()
    scene = softras.load_scene(data)
    kinds = {k_texture.texture_tables(softras.pipeline.texture.prepare(t), True)[0].aniso
             for t in scene.textures.values()}
    assert kinds == {0, 1}
    assert_same(*both_paths(scene, samples=samples), f"random anisotropic scene seed {300 + seed}")


def test_bench_anisotropic_floor_is_bit_identical():
    from softras import bench
    scene = softras.load_scene(bench.floor_scene(160, anisotropy=16))
    assert_same(*both_paths(scene), "bench floor, anisotropy 16")


@numba.njit
def _blend_words(mode, words, stored, got, expected):
    """`k_ops._blend_word` of each fragment word over its stored word (mode a
    value, unknown to the compiler: the branch-free code of the any-state
    copies) into got, and `ops.blend_byte` of their channels into expected."""
    for i in range(words.shape[0]):
        word, dst = words[i], stored[i]
        alpha = (word >> 24) & 255
        got[i] = k_ops._blend_word(mode, word, dst, alpha)
        bytes_ = 0
        for c in range(4):
            bytes_ |= blend_byte(mode, (word >> (8 * c)) & 255, (dst >> (8 * c)) & 255, alpha) << (8 * c)
        expected[i] = bytes_


def test_word_blend_equals_the_per_channel_blend():
    """`_blend_word` (the four spread lanes at once, without a branch) =
    `ops.blend_byte` per channel, every mode: every pair of fragment and
    stored bytes in each channel (R, G and B each get every pair, in
    another order), with every alpha byte for the modes that read it
    ("over", "over_straight") and the ends and a few others for the rest
    (alpha is the fragment's fourth byte, blended over every stored alpha)."""
    pairs = np.arange(65536, dtype=np.int64)
    src, dst = pairs >> 8, pairs & 255
    stored = dst | (np.roll(dst, 1) << 8) | (np.roll(dst, 2) << 16) | (np.roll(dst, 3) << 24)
    got, expected = np.empty_like(pairs), np.empty_like(pairs)
    for mode in range(8):
        for alpha in (range(256) if mode in (1, 2) else (0, 1, 127, 128, 254, 255)):
            words = src | (np.roll(src, 1) << 8) | (np.roll(src, 2) << 16) | (alpha << 24)
            _blend_words(mode, words, stored, got, expected)
            wrong = np.flatnonzero(got != expected)
            assert wrong.size == 0, (mode, alpha, hex(words[wrong[0]]), hex(stored[wrong[0]]))


def state_grid_scene(lit: bool) -> dict:
    """Every depth function (and none) with every blend mode, each pair in
    a cell of its own (a column a function, a row a blend; orthographic,
    so that no cell's result is drawn over by another's): an opaque quad
    writing depth, then with the pair's state a quad on a plane that
    crosses it (nearer on one side, farther on the other) and a quad on
    its very plane (equal depths), with depth writes in every other cell,
    vertex colours with alpha from 0.2 to 0.9; with ``lit`` Phong-shaded
    by a point light (the lane path), else unlit (the row path)."""
    funcs = ["less", "lequal", "equal", "greater", "gequal", "notequal", "always", "never", False]
    blends = ["none", "over", "over_straight", "add", "subtract", "reverse_subtract", "min", "max"]
    nodes = []
    for i, func in enumerate(funcs):
        for j, blend in enumerate(blends):
            k = len(blends) * i + j
            x0, x1, y0, y1 = i, i + 1, j, j + 1

            def quad(z_left, z_right, colors, **state):
                mesh = {"positions": [[x0, y0, z_left], [x1, y0, z_right], [x1, y1, z_right], [x0, y1, z_left]],
                        "indices": [[0, 1, 2], [0, 2, 3]], "colors": colors}
                node = {"name": f"{func}-{blend}-{len(nodes)}", "mesh": mesh, **state}
                if lit:
                    mesh["normals"] = [[0, 0, 1], [0.3, 0, 1], [0, 0.3, 1], [-0.3, -0.3, 1]]
                    node["material"] = {"shading": "phong", "ambient": 0.2, "diffuse": 0.8, "specular": 0.5,
                                        "shininess": 16}
                nodes.append(node)

            tint = [(k * 0.37) % 1, (k * 0.61) % 1, (k * 0.13) % 1]
            quad(-0.2, 0.2, [[*tint, 1], [0.5, 0.4, 0.3, 1], [0.2, 0.6, 0.9, 1], [0.9, 0.9, 0.1, 1]])
            state = {"depth_test": func, "depth_write": k % 2 == 0, "blend": blend}
            quad(0.2, -0.2, [[1 - tint[0], tint[1], 0.5, 0.2 + 0.7 * ((k * 0.29) % 1)], [1, 0.2, 0.1, 0.9],
                             [0.1, 1, 0.3, 0.5], [0.2, 0.3, 1, 0.2]], **state)
            quad(-0.2, 0.2, [[0.3, 0.3, 0.3, 0.6], [0.9, 0.1, 0.6, 0.3], [0.1, 0.1, 0.1, 0.8], [1, 1, 1, 0.4]],
                 **state)
    scene = {"softras_scene": 1, "width": 9 * 11, "height": 8 * 9, "background": [0.1, 0.2, 0.3, 1],
             "nodes": nodes,
             "camera": {"projection": "orthographic", "left": 0, "right": 9, "bottom": 0, "top": 8,
                        "near": 1, "far": 10, "eye": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0]}}
    if lit:
        scene["lights"] = [{"type": "point", "position": [4, 4, 3], "color": [1, 0.9, 0.8]}]
    return scene


@pytest.mark.parametrize("func", ["less", "lequal", "equal", "greater", "notequal"])
def test_transparent_layers_hidden_in_part_are_bit_identical(func):
    """The bench's transparent pass (`bench_scenes.blended_scene`): layers
    "over" without depth writes, an opaque grid slanting through them, so
    that a row of a layer is hidden at one end or both; the copy for any
    state shades only the run between a row's first and last passing pixel
    (`softras.kernels.draw._passing_run`) and gives the stages' bytes."""
    from softras.bench_scenes import blended_scene
    data = blended_scene(96, layers=4, cols=3, transparent=True)
    for node in data["nodes"][1:]:
        node["depth_test"] = func
    scene = softras.load_scene(data)
    assert_same(*both_paths(scene), f"transparent layers, {func}")


@pytest.mark.parametrize("lit", [False, True])
@pytest.mark.parametrize("samples", [1, 4])
def test_every_depth_function_with_every_blend_is_bit_identical(lit, samples):
    """The drivers' copies for common states and their copy for any other
    state (`softras.kernels.draw._flat_row`, without a branch on the
    depth function or the blend) give the stages' bytes for every pair."""
    scene = softras.load_scene(state_grid_scene(lit))
    assert_same(*both_paths(scene, samples=samples), f"every depth function and blend, lit {lit}, {samples} samples")


def test_integer_depth_test_equals_the_float_depth_test():
    """`_depth_pass_k` on the 24-bit integers k (-1 for NaN) = `ops._depth_pass`
    on the pipeline's depths k / (2^24 - 1), for every function, at the ends,
    neighbouring values and NaN on either side."""
    from softras.pipeline.ops import DEPTH_FUNCS, _depth_pass
    scale = k_ops.DEPTH_SCALE
    ks = [-1, 0, 1, 2, 8388607, 8388608, int(scale) - 1, int(scale)]
    for func in DEPTH_FUNCS.values():
        for k in ks:
            for stored in ks:
                z = np.nan if k < 0 else k / scale
                z_stored = np.nan if stored < 0 else stored / scale
                assert k_ops._depth_pass_k(func, k, stored) == _depth_pass(func, z, z_stored), (func, k, stored)


def test_lane_depths_round_like_the_float_depth():
    """`_lane_depths`: the integer k of the pipeline's rounded depth
    rint(clamp(z) * (2^24 - 1)) / (2^24 - 1) for in-range, clamped and NaN
    plane values (NaN -> -1)."""
    n = 6
    tri_f = np.zeros((1, k_setup._NF))
    li = np.zeros((k_lanes._LI_Z + 1, 8), np.int64)
    li[k_lanes._LI_PX, :n] = [0, 1, 2, 3, 4, 5]
    positions = np.array([[0.5, 0.5]])
    lane_depths = fresh(k_interpolate._lane_depths)
    for z0, dzdx in ((0.25, 0.1), (0.999, 0.001), (-0.3, 0.2), (np.nan, 0.0), (0.5, 1e-9)):
        tri_f[0, k_setup._F_X], tri_f[0, k_setup._F_Z], tri_f[0, k_setup._F_DZDX] = 0.0, z0, dzdx
        lane_depths(n, 0, tri_f, positions, li, 1)
        for l in range(n):
            z = z0 + dzdx * (l + 0.5)
            z = np.rint(min(max(z, 0.0), 1.0) * k_ops.DEPTH_SCALE) if z == z else np.nan
            assert li[k_lanes._LI_Z, l] == (-1 if np.isnan(z) else int(z)), (z0, dzdx, l)


def test_lane_weights_are_the_stages_to_the_bit():
    """`_lane_weights` (`_weights_at`): the perspective weights are
    `interpolate.perspective_weights_at` (of the edge functions) and the
    (s, t) `interpolate.interpolate` of the corner uvs under them, bit for
    bit, on random triangles (1/w over three decades) at pixel centres
    inside and outside.  (The pictures alone did not tell the weights of
    normalised barycentrics from these: a colour byte moves only where a
    value lies within an ulp or two of a rounding boundary.)"""
    from softras.pipeline import interpolate
    rng = np.random.default_rng(11)
    n = k_lanes.LANES
    lane_weights = fresh(k_interpolate._lane_weights)
    for _ in range(300):
        window = rng.uniform(-50.0, 600.0, (3, 2))
        inv_w = 1.0 / rng.uniform(0.1, 100.0, 3)
        uv = rng.uniform(-2.0, 3.0, (1, 3, 2))
        centres = rng.integers(-60, 620, (n, 2)) + 0.5
        tri_f = np.zeros((1, k_setup._NF))
        for k in range(3):
            tri_f[0, k_setup._F_X + k], tri_f[0, k_setup._F_Y + k] = window[k]
            tri_f[0, k_setup._F_W + k] = inv_w[k]
        lf = np.zeros((k_lanes._NLF, 2 * n))
        lf[k_lanes._LF_CX, :n], lf[k_lanes._LF_CY, :n] = centres[:, 0], centres[:, 1]
        lane_weights(n, 0, tri_f, lf, uv, True)
        weights = interpolate.perspective_weights_at(np.broadcast_to(window, (n, 3, 2)), np.broadcast_to(inv_w, (n, 3)),
                                                     centres)
        st = interpolate.interpolate(weights, np.broadcast_to(uv[0], (n, 3, 2)))
        assert np.array_equal(lf[k_lanes._LF_W:k_lanes._LF_W + 3, :n].T, weights)
        assert np.array_equal(lf[k_lanes._LF_S, :n], st[:, 0]) and np.array_equal(lf[k_lanes._LF_T, :n], st[:, 1])


def test_lane_filter_equals_the_per_channel_fixed_point_lerp():
    """`_lerp_lanes` on spread RGBA8 words = `_lerp8` per channel, for every weight 0..256."""
    rng = np.random.default_rng(7)
    words = rng.integers(0, 2**32, size=(200, 2), dtype=np.uint64)
    words[:4] = [[0, 0xFFFFFFFF], [0xFFFFFFFF, 0], [0xFFFFFFFF, 0xFFFFFFFF], [0x00FF00FF, 0xFF00FF00]]
    for a_word, b_word in words:
        a, b = k_rgba8._spread(a_word), k_rgba8._spread(b_word)
        for c in range(4):
            assert k_rgba8._lane(a, c) == (int(a_word) >> (8 * c)) & 255
        for w in list(range(0, 257, 17)) + [255, 256]:
            mixed = k_texture._lerp_lanes(w, a, b)
            for c in range(4):
                expect = k_texture._lerp8(w, (int(a_word) >> (8 * c)) & 255, (int(b_word) >> (8 * c)) & 255)
                assert k_rgba8._lane(mixed, c) == expect, (hex(a_word), hex(b_word), w, c)


def test_corner_values_are_the_stages_with_signed_zeros_and_infinities():
    """The set-up's corner attributes (`k_setup._corner_values`, in both
    corner orders) are `softras.pipeline.render.corner_values`' bit for bit
    on the triangles the gl clipper lists for a mesh across the clip planes
    (passed through, and fans whose corners the clipper kept or made), with
    -0, infinities and NaN among the vertex values: a kept corner takes its
    vertex's values as they are (its -0 stays -0, another vertex's
    infinity stays out), a made one the weighted sum from 0."""
    from softras.pipeline import clip as clip_stage
    from softras.pipeline import render as render_stage
    rng = np.random.default_rng(7)
    n = 60
    positions = rng.uniform(-1.6, 1.6, size=(n, 4))
    positions[:, 3] = rng.uniform(0.5, 1.5, size=n)
    indices = rng.integers(0, n, size=(90, 3))
    source, slot, fan_clip, fan_weights = clip_stage.triangle_list_gl(positions, indices)
    assert (slot < 0).any() and (slot >= 0).any()
    weights = np.where((slot < 0)[:, None, None], np.eye(3), fan_weights[np.maximum(slot, 0)])
    kept = weights.max(axis=2) == 1.0
    assert kept[slot >= 0].any() and not kept[slot >= 0].all()
    values = rng.normal(size=(n, 5))
    values[::3] = -0.0
    values[1::7, 1] = np.inf
    values[2::11, 2] = -np.inf
    values[3::13, 3] = np.nan
    clipped = (indices, source, slot, fan_clip, fan_weights)
    stage_clipped = clip_stage.ClippedTriangles(np.zeros((len(source), 3, 4)), source, weights)
    for swapped in (0, 1):
        order = np.array([1, 0, 2] if swapped else [0, 1, 2])
        tris = type("Tris", (), {"triangle": np.arange(len(source)), "corner": np.tile(order, (len(source), 1))})
        mesh = type("Mesh", (), {"indices": indices})
        with np.errstate(invalid="ignore"):
            expected = render_stage.corner_values(stage_clipped, tris, mesh)[1](values)
        got = np.empty((len(source), 3, values.shape[1]))
        for t in range(len(source)):
            k_setup._corner_values(values, got, t, clipped, swapped, values.shape[1])
        assert_same_bits(expected, got, f"swapped {swapped}")
        own = indices[source][np.arange(len(source))[:, None], weights.argmax(axis=2)][:, order]
        kept_here = kept[:, order]
        assert_same_bits(values[own[kept_here]], got[kept_here], f"kept corners, swapped {swapped}")


def test_line_end_values_are_the_stages_with_signed_zeros_and_infinities():
    """The gl line kernel's end values (`k_lines` set-up pass, the
    `LineTable`'s ends) are `softras.pipeline.lines.rasterized_lines`' bit
    for bit on lines across the clip planes, with -0, infinities and NaN
    among the vertex colours: an end the clipper kept takes its vertex's
    values as they are (-0 stays -0, the other end's infinity stays out),
    an end it made the weighted sum."""
    from softras.kernels.scratch import read_only
    from softras.pipeline import lines as lines_stage
    from softras.pipeline.clip import _plane_distances
    rng = np.random.default_rng(8)
    n, width, height = 80, 64, 48
    clip = rng.uniform(-1.6, 1.6, size=(n, 4))
    clip[:, 3] = rng.uniform(0.5, 1.5, size=n)
    clip = clip.astype(np.float32).astype(np.float64)
    indices = rng.integers(0, n, size=(120, 2))
    values = rng.uniform(0, 1, size=(n, 4))
    values[::3] = -0.0
    values[1::7, 1] = np.inf
    values[2::11, 2] = np.nan
    with np.errstate(invalid="ignore"):
        clipped = lines_stage.clip_lines(clip, indices, precision="gl", policy="llvmpipe", width=width,
                                         height=height)
        *_, expected = lines_stage.rasterized_lines(clip, indices, width, height, values=values,
                                                    sample_positions=np.array([[0.5, 0.5]]))
    assert clipped.generated.any() and not clipped.generated.all()
    c, finite, planes = lines_stage.clip_inputs(clip, "gl", "llvmpipe", width, height)
    m = len(indices)
    table = k_lines.LineTable(np.zeros(m, np.bool_), np.zeros((m, 4)), np.zeros((m, 4)), np.zeros((m, 4), np.int64),
                              np.zeros((m, 2, 3)), np.zeros((m, 2)), np.zeros((m, 2, 4)))
    k_lines._SET_UP_LINES(0, 1, c, _plane_distances(c, planes), finite, read_only(indices, np.int64),
                          read_only(values, np.float64), False, width, height, *table)
    got = table.ends[clipped.source]
    assert_same_bits(expected, got, "line ends")
    kept = ~clipped.generated
    assert_same_bits(values[indices[clipped.source]][kept], got[kept], "kept line ends")


def assert_same_bits(expected, got, what):
    """The same float64 values, NaN where NaN and the same sign of zero."""
    assert np.array_equal(expected, got, equal_nan=True), what
    assert np.array_equal(np.signbit(expected), np.signbit(got)), what


def test_reused_scratch_buffers_do_not_leak_between_renders():
    """Set-up tables, corner attributes, depth and (render_scene's) colour live
    in reused buffers: a big scene, a small one, then the big one again give
    the same bytes, and a returned picture or colour buffer is not overwritten
    by the next render (`ops.resolve_llvmpipe_bytes` copies the reused colour
    buffer at one sample; a picture that were a view of it would change)."""
    from softras import bench
    big = softras.load_scene(bench.grid_scene(30, 160))
    small = softras.load_scene(random_scene(3, width=40, height=30))
    same_size = softras.load_scene(bench.grid_scene(12, 160))
    first = render_scene(big, precision="gl")
    snapshot = first.copy()
    render_scene(small, precision="gl")
    render_scene(same_size, precision="gl")
    assert_same(snapshot, first, "a returned picture after two more renders")
    assert_same(first, render_scene(big, precision="gl"), "big scene after a small one")
    positions = np.array([[0.5, 0.5]])
    kept = fastpath.render_samples(big, positions)
    copy = kept.copy()
    fastpath.render_samples(small, positions)
    fastpath.render_samples(small, positions, reuse=True)
    assert (kept == copy).all()


def test_texture_tables_are_cached_per_prepared_texture():
    from softras import bench
    from softras.pipeline import texture
    scene = softras.load_scene(bench.floor_scene(32))
    tex = texture.prepare(scene.textures["checker"])
    assert k_texture.texture_tables(tex, True) is k_texture.texture_tables(tex, True)
    assert k_texture.texture_tables(tex, False)[0].fixed8 == 0
    assert k_texture.texture_tables(tex, True)[0].fixed8 == 1


def test_scratch_nbytes_counts_the_reused_buffers():
    """bench's memory figure adds the buffers a warm render keeps (fastpath.scratch_nbytes)."""
    from softras import bench
    scene = softras.load_scene(bench.grid_scene(8, 96))
    render_scene(scene, precision="gl")
    held = fastpath.scratch_nbytes()
    assert held >= 96 * 96 * (8 + 4)                       # depth (float64) and colour (RGBA8) at least
    assert held >= 2 * 8 * 8 * (k_setup._NF + k_setup._NI) * 8   # the set-up tables of 128 triangles


# ----------------------------------------------------------------------------- size thresholds
#
# Each size at which the fast path changes what it does, just below, at and
# just above: PARALLEL_SETUP (the set-up in a share a thread),
# PARALLEL_LIGHTING (Gouraud's vertex lighting likewise), TILE (the
# binning), BLOCK (the coverage blocks), LANES (the lanes shaded at once),
# _Scratch.MAX_BYTES (buffers kept between renders) and the texture tables'
# cache (cleared at 16 entries).  Byte equality with the stages every time.


def counted_scene(target: int, *, seed: int, textured: bool = False, cull: str = "none",
                  width: int = 97, height: int = 75) -> dict:
    """One draw whose clipped triangle list (what `softras.kernels.setup._setup` sets up) has
    exactly ``target`` triangles: small random triangles of both windings, a
    fifth of them through the near plane or the sides of the frustum (fanned
    into several), then triangles inside the view to make up the count."""
    rng = np.random.default_rng(seed)
    camera = {"projection": "perspective", "fov_y": 70, "near": 0.5, "far": 4, "eye": [0, 0, 2.5],
              "target": [0, 0, 0]}

    def triangles(n, spread):
        centre = rng.uniform(-1, 1, size=(n, 1, 3)) * spread + [0, 0, 0.3]
        return centre + rng.uniform(-0.15, 0.15, size=(n, 3, 3))

    spread = np.where(rng.random((target, 1, 1)) < 0.2, [2.5, 1.8, 2.0], [0.8, 0.6, 0.8])
    pool = triangles(target, spread)
    scene = {"softras_scene": 1, "width": width, "height": height, "background": [0.1, 0.2, 0.3, 1],
             "camera": camera, "textures": {}, "nodes": []}
    loaded = softras.load_scene(dict(scene, nodes=[{"name": "pool", "mesh": {
        "positions": pool.reshape(-1, 3).tolist(), "indices": np.arange(3 * target).reshape(-1, 3).tolist()}}]))
    fans = np.bincount(clip_list(loaded, 0)[0], minlength=target)
    keep = int(np.searchsorted(np.cumsum(fans), target, side="right"))
    extra = target - int(fans[:keep].sum())
    xyz = np.concatenate([pool[:keep], triangles(extra, np.array([0.3, 0.3, 0.3]))]).reshape(-1, 3)
    n = len(xyz) // 3
    mesh = {"positions": xyz.tolist(), "indices": np.arange(3 * n).reshape(n, 3).tolist(),
            "colors": rng.uniform(0, 1, size=(3 * n, 4)).round(3).tolist()}
    node = {"name": "counted", "mesh": mesh, "cull": cull, "blend": "over", "depth_test": "less"}
    if textured:
        mesh["uvs"] = rng.uniform(-1, 2, size=(3 * n, 2)).tolist()
        scene["textures"] = {"t": {"procedural": "noise", "size": [16, 16], "min_filter": "linear_mipmap_linear",
                                   "mag_filter": "linear"}}
        node["material"] = {"texture": "t"}
    scene["nodes"] = [node]
    assert len(clip_list(softras.load_scene(scene), 0)[0]) == target
    return scene


def clip_list(scene, k):
    """`clip.triangle_list_gl` of draw k, as `fastpath.draw_triangles` calls it."""
    from softras.pipeline import clip, vertex
    draw = scene.draws[k]
    mvp = vertex.model_view_projection(scene.camera.projection, scene.camera.view, draw.world)
    return clip.triangle_list_gl(vertex.to_clip(draw.mesh.positions, mvp, "gl"), draw.mesh.indices)


def assert_same_on_one_and_two_threads(scene, what):
    """The scene's gl render by the kernels equals the stages' with numba
    set to 1 and to 2 threads (the work in one call, and in a share a
    thread), each time from zeroed scratch buffers: a set-up row or lit
    colour a share skipped is then wrong in the picture, not left right
    from the render before."""
    general = render_scene(scene, precision="gl", fast_path=False)
    before = numba.get_num_threads()
    try:
        for threads in sorted({1, min(2, numba.config.NUMBA_NUM_THREADS)}):
            numba.set_num_threads(threads)
            for buffer in fastpath._scratch.buffers.values():
                buffer.fill(0)
            assert_same(general, render_scene(scene, precision="gl"), f"{what}, {threads} threads")
    finally:
        numba.set_num_threads(before)


@pytest.mark.parametrize("textured", [False, True])
@pytest.mark.parametrize("offset", [-1, 0, 1])
def test_parallel_setup_threshold_is_bit_identical(offset, textured):
    """PARALLEL_SETUP - 1, PARALLEL_SETUP and + 1 clipped triangles (`_setup`
    in one call, and in a share a thread), fans from the clipper among them,
    colours and uvs at the corners, with 1 and 2 threads."""
    assert k_setup.PARALLEL_SETUP == 4096
    target = k_setup.PARALLEL_SETUP + offset
    scene = softras.load_scene(counted_scene(target, seed=300 + offset, textured=textured,
                                             cull="back" if offset else "none"))
    assert_same_on_one_and_two_threads(scene, f"{target} triangles, textured {textured}")


@pytest.mark.parametrize("offset", [-1, 0, 1])
def test_parallel_lighting_threshold_is_bit_identical(offset):
    """PARALLEL_LIGHTING - 1, PARALLEL_LIGHTING and + 1 vertices of a
    Gouraud-lit mesh (its lighting in one call, and in a share a thread,
    `softras.kernels.light.base_colors`) under a point and a directional
    light, with 1 and 2 threads: a strip of small triangles along a random
    walk, so that every vertex is in sight and a vertex the lighting
    skipped shows."""
    assert k_light.PARALLEL_LIGHTING == 4096
    n = k_light.PARALLEL_LIGHTING + offset
    rng = np.random.default_rng(400 + offset)
    positions = np.cumsum(rng.uniform(-0.05, 0.05, size=(n, 3)) * [1, 1, 0.2], axis=0)
    positions -= positions.mean(axis=0)
    indices = np.stack([np.arange(n - 2), np.arange(1, n - 1), np.arange(2, n)], axis=1)
    scene = softras.load_scene({
        "softras_scene": 1, "width": 96, "height": 72, "background": [0, 0, 0, 1],
        "camera": {"projection": "perspective", "fov_y": 60, "near": 0.5, "far": 10, "eye": [0, 0, 3],
                   "target": [0, 0, 0]},
        "lights": [{"type": "point", "position": [2, 2, 3], "color": [1, 0.9, 0.8]},
                   {"type": "directional", "direction": [-1, -0.3, -0.5], "color": [0.2, 0.3, 0.5]}],
        "nodes": [{"name": "lit", "mesh": {"positions": positions.tolist(), "indices": indices.tolist(),
                                           "normals": rng.normal(size=(n, 3)).tolist()},
                   "material": {"shading": "gouraud", "color": [0.8, 0.6, 0.3, 1], "ambient": 0.1,
                                "diffuse": 0.7, "specular": 0.5, "shininess": 24}}]})
    assert len(scene.draws[0].mesh.positions) == n
    assert_same_on_one_and_two_threads(scene, f"{n} vertices")


def full_screen(width: int, height: int, textured: bool = False, samples: int = 1) -> dict:
    """One triangle over the whole viewport (and a second, half-transparent,
    over the lower-left half): every pixel, whole blocks, every lane."""
    mesh = {"positions": [[-1, -1, 0], [3, -1, 0], [-1, 3, 0]], "indices": [[0, 1, 2]],
            "colors": [[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1]]}
    half = {"positions": [[-1, -1, 0.5], [0.9, -1, 0.5], [-1, 0.7, 0.5]], "indices": [[0, 1, 2]],
            "colors": [[0.2, 0.8, 0.4, 0.5]] * 3}
    if textured:
        mesh["uvs"] = half["uvs"] = [[0, 0], [7, 0], [0, 5]]
    scene = {"softras_scene": 1, "width": width, "height": height, "background": [0, 0, 0, 1],
             "samples": samples, "textures": {}, "nodes": [
                 {"name": "all", "mesh": mesh}, {"name": "half", "mesh": half, "blend": "over"}]}
    if textured:
        scene["textures"]["t"] = {"procedural": "checker", "size": [16, 16], "squares": 4,
                                  "min_filter": "linear_mipmap_linear", "mag_filter": "linear"}
        for node in scene["nodes"]:
            node["material"] = {"texture": "t"}
    return scene


# Viewports whose pixel counts straddle LANES (63, 64, 65, 127, 128, 129: one
# block of 8x8 = 64 lanes, rows of 8-pixel blocks) and whose sides straddle
# BLOCK (7, 8, 9, 15, 16, 17) and TILE (63, 64, 65, 127, 128, 129).
SIZES = [(9, 7), (8, 8), (13, 5), (127, 1), (16, 8), (129, 1), (7, 9), (17, 15),
         (63, 65), (64, 64), (65, 63), (128, 129), (129, 127)]


@pytest.mark.parametrize("samples", [1, 4])
@pytest.mark.parametrize("textured", [False, True])
def test_block_lane_and_tile_sizes_are_bit_identical(textured, samples):
    """Full-screen draws on viewports around BLOCK, LANES and TILE."""
    assert (k_rasterize.BLOCK, k_lanes.LANES, k_rasterize.TILE) == (8, 64, 64)
    for width, height in SIZES:
        scene = softras.load_scene(full_screen(width, height, textured, samples))
        assert_same(*both_paths(scene), f"{width}x{height}, textured {textured}, {samples} samples")


def test_rectangles_around_block_and_lane_sizes_are_bit_identical():
    """Pixel-aligned rectangles 1..17 pixels on a side (two triangles each, at
    odd and even starts: textured blocks start at even pixels) across 64-pixel
    tile borders, untextured and textured, 1 and 4 samples."""
    width, height = 150, 140
    rng = np.random.default_rng(400)
    nodes = []
    sides = [1, 2, 7, 8, 9, 15, 16, 17]
    for k, (w, h) in enumerate([(w, h) for w in sides for h in sides]):
        x0, y0 = int(rng.integers(40, 90)), int(rng.integers(40, 80))
        corners = np.array([[x0, y0], [x0 + w, y0], [x0 + w, y0 + h], [x0, y0 + h]], float)
        ndc = np.concatenate([corners / [width / 2, height / 2] - 1, np.zeros((4, 1))], axis=1)
        node = {"name": f"r{k}", "blend": "add", "depth_test": False,
                "mesh": {"positions": ndc.tolist(), "indices": [[0, 1, 2], [0, 2, 3]],
                         "colors": [[0.05, 0.03, 0.02, 1]] * 4, "uvs": (corners / 16).tolist()}}
        if k % 2:
            node["material"] = {"texture": "t"}
        nodes.append(node)
    data = {"softras_scene": 1, "width": width, "height": height, "background": [0, 0, 0, 1],
            "textures": {"t": {"procedural": "noise", "size": [8, 8], "min_filter": "linear",
                               "mag_filter": "linear"}}, "nodes": nodes}
    for samples in (1, 4):
        assert_same(*both_paths(softras.load_scene(dict(data, samples=samples))), f"rectangles, {samples} samples")


def test_scratch_limit_is_bit_identical(monkeypatch):
    """`_Scratch.MAX_BYTES` (64 MiB; here 64 x 48 x 4 bytes): a buffer at the limit
    is kept and reused, one over it is fresh each render and not kept; renders
    either side of the limit, in turn, give the stages' bytes."""
    limit = 64 * 48 * 4
    monkeypatch.setattr(fastpath._Scratch, "MAX_BYTES", limit)
    monkeypatch.setattr(fastpath, "_scratch", fastpath._Scratch())
    at, over = (softras.load_scene(random_scene(500 + k, width=64, height=48 + k)) for k in (0, 1))
    expected = {k: render_scene(s, precision="gl", fast_path=False) for k, s in (("at", at), ("over", over))}
    for name, scene in (("at", at), ("over", over), ("at", at), ("over", over), ("at", at)):
        assert_same(expected[name], render_scene(scene, precision="gl"), f"{name} the scratch limit")
        held = {name: buffer.nbytes for name, buffer in fastpath._scratch.buffers.items()}
        assert held.get("color") == held.get("depth") == limit, f"buffers kept after {name}: {held}"
    assert fastpath.scratch_nbytes() == sum(b.nbytes for b in fastpath._scratch.buffers.values())


def test_scratch_hands_out_the_last_view_only_for_the_same_shape_and_dtype():
    """`_Scratch.take` gives the same view again for the same name, shape
    and dtype; another shape a view of that shape on the kept buffer (a new
    buffer when it has grown); another dtype a buffer of that dtype."""
    scratch = fastpath._Scratch()
    first = scratch.take("a", (10, 3), np.float64)
    assert scratch.take("a", (10, 3), np.float64) is first
    smaller = scratch.take("a", (4, 3), np.float64)
    assert smaller.shape == (4, 3) and np.shares_memory(smaller, first) and smaller.flags.c_contiguous
    again = scratch.take("a", (10, 3), np.float64)
    assert again.shape == (10, 3) and np.shares_memory(again, first)
    grown = scratch.take("a", (20, 3), np.float64)
    assert grown.shape == (20, 3) and not np.shares_memory(grown, first)
    assert scratch.take("a", (20, 3), np.float64) is grown
    as_int = scratch.take("a", (20, 3), np.int64)
    assert as_int.dtype == np.int64 and as_int.shape == (20, 3)
    assert scratch.take("a", (20, 3), np.float64).dtype == np.float64
    assert scratch.take("b", (20, 3), np.int64) is not as_int


def test_texture_table_cache_limit_is_bit_identical():
    """More textures than the tables' cache holds (it is cleared at 16): 20
    textured draws, each its own texture, rendered twice."""
    nodes, textures = [], {}
    for k in range(20):
        textures[f"t{k}"] = {"procedural": "noise" if k % 2 else "checker", "size": [4 + k, 8],
                             "min_filter": "nearest_mipmap_linear", "mag_filter": "nearest"}
        x = -1 + k * 0.1
        nodes.append({"name": f"n{k}", "material": {"texture": f"t{k}"},
                      "mesh": {"positions": [[x, -1, 0], [x + 0.1, -1, 0], [x + 0.05, 1, 0]],
                               "indices": [[0, 1, 2]], "uvs": [[0, 0], [1, 0], [0.5, 3]]}})
    scene = softras.load_scene({"softras_scene": 1, "width": 80, "height": 30, "textures": textures,
                                "nodes": nodes})
    general, fast = both_paths(scene)
    assert_same(general, fast, "20 textures")
    assert_same(general, render_scene(scene, precision="gl"), "20 textures, again")


def test_the_sample_memory_limit_counts_each_paths_bytes(monkeypatch):
    """The compiled path holds 8 bytes a sample (RGBA8 and depth), the stages
    32 (float64 RGBA): under one limit the compiled path renders pictures the
    stages refuse (4096^2 at 4x: 512 MiB here, 2 GiB there)."""
    from softras.pipeline import render as stage_render
    scene = softras.load_scene(random_scene(0, width=64, height=64))
    monkeypatch.setattr(stage_render, "MAX_SAMPLE_BYTES", 64 * 64 * 4 * 16)
    assert render_scene(scene, samples=4).shape == (64, 64, 4)
    with pytest.raises(ValueError, match="GiB of sample colour"):
        render_scene(scene, samples=4, fast_path=False)
    monkeypatch.setattr(stage_render, "MAX_SAMPLE_BYTES", 64 * 64 * 4 * 8 - 1)
    with pytest.raises(ValueError, match="GiB of sample colour"):
        render_scene(scene, samples=4)


def tiles_scene() -> dict:
    """A 200x150 picture (4 x 3 tiles of 64, the last column and row
    partial) that the fast path clears where draws first reach its tiles:
    40 small depth-tested quads along a diagonal (more than a batch, so the
    tiles at the far end are first drawn in a later batch), a line draw
    between them (the tiles no draw reached yet cleared before it), one
    blended quad drawn after the line, and tiles no draw reaches at all."""
    quad = {"positions": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], "indices": [[0, 1, 2], [0, 2, 3]],
            "colors": [[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1], [1, 1, 0, 1]]}
    nodes = [{"name": f"quad{k}", "mesh": quad, "scale": [0.08, 0.08, 1],
              "translate": [-1.6 + 0.07 * k, -1.1 + 0.045 * k, -0.01 * k]} for k in range(40)]
    nodes.insert(20, {"name": "line", "mesh": {"primitive": "lines", "positions": [[-1.9, 1.2, 0], [0.3, 1.3, 0]],
                                               "indices": [[0, 1]]}})
    nodes.append({"name": "over", "mesh": quad, "scale": [0.3, 0.3, 1], "translate": [0.9, 0.5, 0.5],
                  "blend": "over", "material": {"color": [0.2, 0.4, 1, 0.5]}})
    return {"softras_scene": 1, "width": 200, "height": 150, "background": [0.25, 0.5, 0.75, 0.8],
            "camera": {"projection": "perspective", "fov_y": 60, "near": 0.1, "far": 100, "eye": [0, 0, 3],
                       "target": [0, 0, 0]},
            "nodes": nodes}


@pytest.mark.parametrize("samples, pattern, framebuffer", [(1, None, None), (4, None, None), (1, None, "rgba32f"),
                                                          (3, "halton", "rgba32f")])
def test_tiles_cleared_where_first_drawn_give_the_stages_bytes(samples, pattern, framebuffer, monkeypatch):
    """The framebuffer's tiles are cleared where a draw first reaches them,
    the others before the line draw and at the end (or, for a one-sample
    picture, written as the background: `softras.kernels.ops._tiles_out`),
    with one share and with two: the stages' bytes, and every tile cleared
    exactly once."""
    scene = softras.load_scene(tiles_scene())
    options = dict(precision="gl", samples=samples, pattern=pattern, framebuffer=framebuffer)
    general = render_scene(scene, fast_path=False, **options)
    render_scene(scene, **options)          # (first: the kernels' preparation draws scenes of its own)
    cleared = []
    real_clear = k_ops._clear_fresh

    def clear_fresh(fb, rgba32f):
        cleared.append(int(fb[3].sum()))
        real_clear(fb, rgba32f)

    monkeypatch.setattr(fastpath, "_clear_fresh", clear_fresh)
    for threads in (1, 2):
        monkeypatch.setattr(fastpath.numba, "get_num_threads", lambda threads=threads: threads)
        cleared.clear()
        fast = render_scene(scene, **options)
        assert np.array_equal(general, fast, equal_nan=True), f"{threads} shares"
        # (Before the line: the tiles the first 20 quads did not reach; at
        # the end nothing is left, or a one-sample RGBA8 picture has no end.)
        expected = [12 - 3] + ([] if samples == 1 and framebuffer is None else [0])
        assert cleared == expected, cleared
