"""piglit-style random lines: softras's line stage must equal llvmpipe pixel for pixel.

Like tests/test_random_triangles.py, lines are drawn 24 at a time with
additive blending, line k adding 2^(k mod 8)/255 to channel k // 8, so one
image holds 24 independent coverage masks.  Positions are given in clip
space (identity camera), so both renderers see the same float32 vertices.
softras's side goes through the line stage's own functions (vertex ->
`softras.pipeline.lines.line_fragments`: clip, viewport, rasterize), independent of
the pipeline's wiring.

Every kind of line: end points on pixel centres, on pixel corners, on a
1/2, 1/4 and 1/1024 grid (diamond borders and snapping ties), anywhere,
short, shorter than a pixel, zero length, horizontal and vertical, exact
diagonals, long lines clipped by the viewport, lines clipped by the near and
far planes, end points on the viewport's border.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import softras
from softras.pipeline import lines, ops, vertex

PER_PASS = 24
LINES_PER_KIND = 240            # per viewport size: 14 kinds x 2 sizes x 240 = 6720 lines
KINDS = ["centres", "corners", "halves", "quarters", "ties", "subpixel", "short", "tiny", "zero",
         "axis", "diagonal", "long", "depth_clipped", "border"]
MSAA4 = np.array([[0.375, 0.125], [0.875, 0.375], [0.125, 0.625], [0.625, 0.875]])
IDENTITY = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]


def random_lines(rng: np.random.Generator, n: int, kind: str, width: int, height: int) -> np.ndarray:
    """(n, 2, 3): window x, y (GL, y up) and NDC z of each end point."""
    size = np.array([width, height])
    z = np.zeros((n, 2, 1))
    if kind == "centres":
        xy = rng.integers(0, size, size=(n, 2, 2)) + 0.5
    elif kind == "corners":
        xy = rng.integers(0, size + 1, size=(n, 2, 2)).astype(float)
    elif kind in ("halves", "quarters", "ties"):
        grid = {"halves": 2, "quarters": 4, "ties": 1024}[kind]
        xy = np.round(rng.uniform(0, size, size=(n, 2, 2)) * grid) / grid
    elif kind == "subpixel":
        xy = rng.uniform(0, size, size=(n, 2, 2))
    elif kind == "short":
        xy = rng.uniform(1, size - 1, size=(n, 1, 2)) + rng.uniform(-1.5, 1.5, size=(n, 2, 2))
    elif kind == "tiny":
        a = rng.uniform(1, size - 1, size=(n, 1, 2))
        xy = np.concatenate([a, a + rng.uniform(-0.6, 0.6, size=(n, 1, 2))], axis=1)
    elif kind == "zero":
        a = rng.uniform(0, size, size=(n, 1, 2))
        step = rng.choice([0, 1 / 512, 1 / 256, 1 / 128], size=(n, 1, 2)) * rng.choice([-1, 1], size=(n, 1, 2))
        xy = np.concatenate([a, a + step], axis=1)
    elif kind == "axis":
        xy = rng.uniform(0, size, size=(n, 2, 2))
        axis = rng.integers(0, 2, n)
        xy[np.arange(n), 1, axis] = xy[np.arange(n), 0, axis]
    elif kind == "diagonal":
        a = rng.integers(2, size - 2, size=(n, 1, 2)) + rng.choice([0, 0.25, 0.5], size=(n, 1, 2))
        length = rng.integers(-20, 21, size=(n, 1, 1)) + rng.choice([0, 0.5], size=(n, 1, 1))
        sign = rng.choice([-1, 1], size=(n, 1, 1))
        xy = np.concatenate([a, a + np.concatenate([length, length * sign], axis=2)], axis=1)
    elif kind == "long":
        xy = rng.uniform(-size, 2 * size, size=(n, 2, 2))
    elif kind == "depth_clipped":
        xy = rng.uniform(-0.2 * size, 1.2 * size, size=(n, 2, 2))
        z = rng.uniform(-3, 3, size=(n, 2, 1))
    elif kind == "border":
        xy = rng.uniform(0, size, size=(n, 2, 2))
        for i in range(n):
            axis = rng.integers(0, 2)
            xy[i, rng.integers(0, 2), axis] = rng.choice([0, size[axis]])
    else:
        raise ValueError(kind)
    return np.concatenate([xy, z], axis=2)


def to_ndc(segment: np.ndarray, width: int, height: int) -> list:
    ndc = np.array(segment, float)
    ndc[:, 0] = segment[:, 0] / (width / 2) - 1
    ndc[:, 1] = segment[:, 1] / (height / 2) - 1
    return ndc.tolist()


def coverage_scene(segments: np.ndarray, width: int, height: int, samples: int = 1) -> dict:
    """A scene drawing up to 24 lines (window x, y and NDC z), one bit each."""
    nodes = []
    for k, segment in enumerate(segments):
        color = [0.0, 0.0, 0.0, 1.0]
        color[k // 8] = (1 << (k % 8)) / 255
        nodes.append({"name": f"l{k}", "mesh": {"primitive": "lines", "positions": to_ndc(segment, width, height),
                                                "indices": [[0, 1]]},
                      "material": {"color": color}, "blend": "add", "depth_test": False})
    return {"softras_scene": 1, "width": width, "height": height, "background": [0, 0, 0, 1],
            "samples": samples, "camera": {"projection_matrix": IDENTITY, "view_matrix": IDENTITY},
            "nodes": nodes}


def coverage_masks(image: np.ndarray, n: int) -> np.ndarray:
    """(H, W, 4) encoded image (row 0 = top) -> (n, H, W) bool, row 0 = GL's bottom row."""
    return np.stack([(image[::-1, :, k // 8] >> (k % 8)) & 1 for k in range(n)]).astype(bool)


def draw_clip(scene, draw) -> np.ndarray:
    mvp = vertex.model_view_projection(scene.camera.projection, scene.camera.view, draw.world)
    return vertex.to_clip(draw.mesh.positions, mvp, "gl")


def soft_coverage(scene: dict, positions=None) -> np.ndarray:
    """(n, H, W) covered-sample counts of each draw, through softras.pipeline.lines."""
    scene = softras.load_scene(scene)
    out = np.zeros((len(scene.draws), scene.height, scene.width), int)
    for k, draw in enumerate(scene.draws):
        lf = lines.line_fragments(draw_clip(scene, draw), draw.mesh.indices, scene.width, scene.height,
                                  values=np.ones((len(draw.mesh.positions), 1)), sample_positions=positions)
        f = lf.fragments
        out[k, f.y, f.x] = [bin(int(m)).count("1") for m in f.mask]
    return out


def fail_with_first(mismatched: list, what: str, seed, kind: str, width: int, height: int, samples: int = 1):
    index, count, segment = mismatched[0]
    minimal = coverage_scene(segment[None], width, height, samples)
    pytest.fail(f"{len(mismatched)} {what} differ (seed {seed}, kind {kind}, {width}x{height}); "
                f"first: line {index}, {count} pixels, window x, y / NDC z {segment.tolist()}; "
                f"minimal scene: {json.dumps(minimal)}")


@pytest.mark.gl
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("width, height", [(64, 48), (256, 160)])
def test_line_pixels_identical_to_llvmpipe(kind, width, height):
    seed = [20261207, width, KINDS.index(kind)]
    rng = np.random.default_rng(seed)
    mismatched = []
    for start in range(0, LINES_PER_KIND, PER_PASS):
        segments = random_lines(rng, PER_PASS, kind, width, height)
        scene = coverage_scene(segments, width, height)
        soft = soft_coverage(scene) > 0
        gl = coverage_masks(softras.render(scene, backend="gl"), PER_PASS)
        for k in np.nonzero((soft != gl).any(axis=(1, 2)))[0]:
            mismatched.append((start + k, int((soft[k] != gl[k]).sum()), segments[k]))
    if mismatched:
        fail_with_first(mismatched, f"of {LINES_PER_KIND} lines", seed, kind, width, height)


@pytest.mark.gl
@pytest.mark.parametrize("kind", ["subpixel", "centres", "quarters", "long"])
def test_msaa_line_coverage_identical_to_llvmpipe(kind):
    """4x MSAA lines (Mesa's rectangular lines): covered samples per pixel,
    three lines per image in the red, green and blue channels."""
    width, height = 140, 70                 # crosses a 64-pixel tile border
    seed = [20261208, KINDS.index(kind)]
    rng = np.random.default_rng(seed)
    mismatched = []
    for start in range(0, 90, 3):
        segments = random_lines(rng, 3, kind, width, height)
        scene = coverage_scene(segments, width, height, samples=4)
        for k, node in enumerate(scene["nodes"]):
            node["material"]["color"] = [float(c == k) for c in range(3)] + [1.0]
        soft = soft_coverage(scene, MSAA4)
        image = softras.render(scene, backend="gl")[::-1].astype(float)
        gl = np.rint(np.moveaxis(image[..., :3], 2, 0) / 255 * 4).astype(int)
        for k in np.nonzero((soft != gl).any(axis=(1, 2)))[0]:
            mismatched.append((start + k, int((soft[k] != gl[k]).sum()), segments[k]))
    if mismatched:
        fail_with_first(mismatched, "of 90 MSAA lines", seed, kind, width, height, samples=4)


# --------------------------------------------------------------------------- colours and depth


def star_scene() -> dict:
    """Stars of coloured lines under a perspective camera (the line_star scene).

    A tilted star of 72 lines with sub-pixel end points and depth, a small
    star of 40 lines 0.8 to 3.5 pixels long, and a ring of 24 lines clipped
    by the viewport and the near plane; depth test "less" decides overlaps.
    """
    def star(n, r0, r1, phase, short_every=None, r_short=None, hub=(1, 1, 1), z_tip=0.0):
        positions, indices, colors = [], [], []
        for i in range(n):
            a = 2 * math.pi * i / n + phase
            r = r_short if (short_every and i % short_every == 1) else r1
            c, s = math.cos(a), math.sin(a)
            tip = [0.5 + 0.5 * math.cos(2 * math.pi * (i / n - k / 3)) for k in range(3)]
            indices.append([len(positions), len(positions) + 1])
            positions += [[r0 * c, r0 * s, 0.0], [r * c, r * s, z_tip * math.cos(3 * a)]]
            colors += [list(hub), tip]
        return {"primitive": "lines", "positions": positions, "indices": indices, "colors": colors}

    return {
        "softras_scene": 1, "width": 160, "height": 120, "background": [0, 0, 0, 1], "samples": 1,
        "camera": {"projection": "perspective", "fov_y": 50, "near": 0.5, "far": 50,
                   "eye": [0.37, -0.61, 12.0], "target": [0.37, 0.29, 0.0], "up": [0, 1, 0]},
        "nodes": [
            {"name": "big_star", "translate": [-1.3, 0.2, 0.0], "rotate": [24, 1, -0.6, 0.1],
             "scale": [0.08, 0.08, 0.08], "mesh": star(72, 6.0, 52.0, 0.0137, 3, 23.7, z_tip=9.0)},
            {"name": "small_star", "translate": [3.61, 2.23, 0.0], "scale": [0.25, 0.25, 0.25],
             "mesh": star(40, 1.0, 2.3, 0.05, 2, 1.3, hub=(1, 1, 0.2))},
            {"name": "clipped_ring", "translate": [4.2, -2.9, 0.0], "scale": [0.08, 0.08, 0.08],
             "mesh": star(24, 9.0, 40.0, 0.1, hub=(0.2, 1, 1), z_tip=160.0)},
        ],
    }


def render_line_scene(scene) -> np.ndarray:
    """A scene of line draws through softras.pipeline.lines and softras.pipeline.ops (gl precision)."""
    scene = softras.load_scene(scene)
    positions = MSAA4 if scene.samples == 4 else np.array([[0.5, 0.5]])
    color, depth = ops.new_framebuffer(scene.width, scene.height, len(positions), scene.background, quantize=True)
    for draw in scene.draws:
        mesh = draw.mesh
        base = (mesh.colors if mesh.colors is not None else np.ones((len(mesh.positions), 4))) * draw.material.color
        lf = lines.line_fragments(draw_clip(scene, draw), mesh.indices, scene.width, scene.height, values=base,
                                  sample_positions=positions)
        if len(lf) == 0:
            continue
        rgba = lf.values.copy()
        rgba[:, :3] *= rgba[:, 3:4]                     # premultiplied
        f = lf.fragments
        ops.apply_fragments(f.x, f.y, f.mask, ops.quantize_depth(lf.z), rgba, color, depth,
                            ops.DEPTH_FUNCS[draw.depth_test], draw.depth_write,
                            ops.BLEND_MODES[draw.blend], True)
    return ops.resolve(color)


@pytest.mark.gl
def test_star_colours_and_depth_identical_to_llvmpipe():
    """Perspective-correct colours along the major axis, depth, clipping: every
    pixel of the image equal."""
    scene = star_scene()
    soft = render_line_scene(scene)
    gl = softras.render(scene, backend="gl")
    assert (gl[..., :3].max(axis=2) > 0).sum() > 2000          # the lines are there
    diff = np.abs(soft.astype(int) - gl.astype(int)).max(axis=2)
    bad = np.argwhere(diff > 0)
    assert len(bad) == 0, f"{len(bad)} pixels differ, max {diff.max()}/255, first (row, col) {bad[:5].tolist()}"


@pytest.mark.gl
def test_line_colours_identical_to_llvmpipe():
    """Random lines, random vertex colours, identity camera: every line pixel's colour equal."""
    width, height = 96, 64
    rng = np.random.default_rng(20261209)
    differing = 0
    for _ in range(40):
        segment = np.concatenate([rng.uniform(0, [width, height], size=(2, 2)), np.zeros((2, 1))], axis=1)
        colors = np.concatenate([rng.uniform(0, 1, size=(2, 3)), np.ones((2, 1))], axis=1)
        scene = {"softras_scene": 1, "width": width, "height": height, "background": [0, 0, 0, 0],
                 "camera": {"projection_matrix": IDENTITY, "view_matrix": IDENTITY},
                 "nodes": [{"name": "l", "depth_test": False,
                            "mesh": {"primitive": "lines", "positions": to_ndc(segment, width, height),
                                     "indices": [[0, 1]], "colors": colors.tolist()}}]}
        differing += int((render_line_scene(scene) != softras.render(scene, backend="gl")).any(axis=2).sum())
    assert differing == 0


@pytest.mark.gl
def test_msaa_star_within_resolve_rounding_of_llvmpipe():
    """4x MSAA: llvmpipe evaluates MSAA line attributes half a pixel up and
    right (colours at (x + 1, y + 1), depth at each sample + (0.5, 0.5)),
    which softras.pipeline.lines reproduces; without that the star is up to 14/255
    off.  What is left is the resolve's rounding of partly covered pixels
    (llvmpipe averages float32 samples, softras.pipeline.ops rounds the exact mean):
    at most 1/255."""
    scene = star_scene()
    scene["samples"] = 4
    soft = render_line_scene(scene)
    gl = softras.render(scene, backend="gl")
    diff = np.abs(soft.astype(int) - gl.astype(int)).max(axis=2)
    assert diff.max() <= 1, f"{(diff > 1).sum()} pixels differ by more than 1/255, max {diff.max()}/255"
