"""piglit-style random triangles: softras's coverage must equal llvmpipe's exactly.

Triangles are drawn many to an image with additive blending, each adding its
own value to one channel, so one image of each renderer holds the coverage of
every triangle of a pass:

- 1 sample: triangle k adds 2^(k mod 8)/255 to channel k // 8 (24 per pass;
  RGBA8 sums of distinct powers of two are exact);
- 4x MSAA: triangle k adds 4 * 5^(k mod 3)/255 to every sample it covers in
  channel k // 3 (9 per pass): the resolved byte is sum_k 5^k n_k with n_k
  the triangle's covered samples in the pixel (0..4), an integer mean that
  llvmpipe's float32 resolve gives exactly.

Each pass is compared with GL three ways, every one on its own:

- the fast path (`softras.render`, softras.kernels.draw's fused kernel): each
  triangle's covered samples per pixel, decoded from its image;
- the readable stages, batched over the pass (`stage_image`: the
  functions softras.pipeline.render's general path calls, softras.pipeline.vertex.to_clip
  -> clip.clip_triangles -> setup.setup_triangles -> rasterize.rasterize):
  each triangle's covered samples per pixel, encoded like the images;
- every `RENDER_SCENE_EVERY`-th pass end to end through the stages
  (`render_scene(scene, fast_path=False)`), byte for byte.

Positions are given directly in clip space (an identity camera; the clipping
kinds use a perspective matrix whose clip coordinates are the positions' own),
so both renderers see the same float32 vertices and differences can only come
from clipping, the viewport transform, snapping, culling and the fill rule.

The "ties" kind builds its triangles in softras's fixed point (1/256 pixel,
llvmpipe's): every triangle has an edge through a sample (a pixel centre, or
an MSAA sample position) strictly between its end points, most have their
vertices on samples too, and even x coordinates are given exactly half-way
between two 1/256 positions (snapped to the even one).  `edge_ties` counts the
samples with an edge function exactly 0 and the test asserts them (the
numbers are in its docstring).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import softras
from softras.pipeline import clip, rasterize, setup, vertex
from softras.renderer import render_scene
from softras.pipeline.sampling import GL_CENTER, GL_MSAA4

PER_PASS = 24
PER_PASS_MSAA = 9
TRIANGLES_PER_KIND = 1008
RENDER_SCENE_EVERY = 14         # every 14th pass also through render_scene(fast_path=False)
KINDS = ["pixel_centres", "pixel_corners", "subpixel", "slivers", "ties", "large"]
CLIP_KINDS = ["near_far", "sides", "behind_eye", "far_outside"]
CULLS = ["none", "back", "front"]
IDENTITY = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
# The clipping kinds' camera: clip = P (x, y, z, 1) = (x, y, A z + B, -z), so the
# position (x_c, y_c, -w_c) has clip coordinates (x_c, y_c, z(w_c), w_c), which
# lie inside the near and far planes for NEAR <= w_c <= FAR.
NEAR, FAR = 0.5, 4.0
PERSPECTIVE = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, -(FAR + NEAR) / (FAR - NEAR), -2 * FAR * NEAR / (FAR - NEAR),
               0, 0, -1, 0]


def random_triangles(rng: np.random.Generator, n: int, kind: str, width: int, height: int,
                     positions: np.ndarray = GL_CENTER) -> np.ndarray:
    """(n, 3, 2) window coordinates (GL, y up) inside the viewport.

    positions : the sample positions the "ties" kind puts on edges."""
    size = np.array([width, height])
    if kind == "pixel_centres":
        return rng.integers(0, size, size=(n, 3, 2)) + 0.5
    if kind == "pixel_corners":
        return rng.integers(0, size + 1, size=(n, 3, 2)).astype(float)
    if kind == "subpixel":
        return rng.uniform(0, size - 2, size=(n, 1, 2)) + rng.uniform(0, 1.5, size=(n, 3, 2))
    if kind == "slivers":
        a, b = rng.uniform(0, size, size=(n, 1, 2)), rng.uniform(0, size, size=(n, 1, 2))
        c = a + (b - a) * rng.uniform(0, 1, size=(n, 1, 1)) + rng.normal(0, 0.3, size=(n, 1, 2))
        return np.clip(np.concatenate([a, b, c], axis=1), 0, size)
    if kind == "ties":
        return tie_triangles(rng, n, width, height, positions)
    if kind == "large":
        return rng.uniform(0, size, size=(n, 3, 2))
    raise ValueError(kind)


def tie_triangles(rng: np.random.Generator, n: int, width: int, height: int,
                  positions: np.ndarray) -> np.ndarray:
    """(n, 3, 2) window coordinates of triangles with samples exactly on their edges.

    Built in raster units X = (x_w - 0.5) * 256 (`softras.pipeline.setup.snap`): a
    sample point P (pixel * 256 + a sample's offset), an edge direction d,
    end points P + i d and P - j d (i, j >= 1), so P lies strictly inside
    the edge; d is a whole-pixel step (then P + k d are samples too) or, for a
    quarter of the triangles, any raster step.  The third vertex is a whole
    number of pixels from the first (all three vertices on samples of the
    same index, so the other edges meet samples wherever their step has a
    common divisor) or, for a third of them, anywhere on the raster.  Window
    x of a vertex with an even X is given half-way to a neighbour (X +- 1/2)
    half the time when the width is a power of two: llvmpipe's round-half-even
    snap brings it back to X."""
    offsets = setup.sample_offsets(np.asarray(positions, float), "gl")[0]
    limit = np.array([width, height]) * 256 - 256
    found = []
    while sum(len(f) for f in found) < n:
        m = 4 * n
        point = rng.integers(0, [width, height], size=(m, 2)) * 256 + offsets[rng.integers(len(offsets), size=m)]
        step = rng.integers(-6, 7, size=(m, 2)) * 256
        fine = rng.random(m) < 0.25
        step[fine] = rng.integers(-900, 901, size=(int(fine.sum()), 2))
        i, j = rng.integers(1, 5, size=(2, m, 1))
        v0, v1 = point + i * step, point - j * step
        v2 = v0 + rng.integers(-12, 13, size=(m, 2)) * 256
        anywhere = rng.random(m) < 0.33
        v2[anywhere] = rng.integers(0, limit + 1, size=(int(anywhere.sum()), 2))
        tri = np.stack([v0, v1, v2], axis=1)
        area = ((tri[:, 1, 0] - tri[:, 0, 0]) * (tri[:, 2, 1] - tri[:, 0, 1])
                - (tri[:, 2, 0] - tri[:, 0, 0]) * (tri[:, 1, 1] - tri[:, 0, 1]))
        keep = (step != 0).any(axis=1) & (area != 0) & (tri >= 0).all(axis=(1, 2)) & (tri <= limit).all(axis=(1, 2))
        found.append(tri[keep])
    raster = np.concatenate(found)[:n].astype(float)
    # (Exactly half-way only where window -> NDC -> window is exact in float32:
    # W/2 a power of two.)
    exact = (width & (width - 1)) == 0
    halfway = exact & (raster[..., 0] % 2 == 0) & (rng.random(raster.shape[:2]) < 0.5)
    raster[..., 0] += halfway * rng.choice([-0.5, 0.5], size=raster.shape[:2])
    return 0.5 + raster / 256


def clipped_triangles(rng: np.random.Generator, n: int, kind: str, width: int, height: int) -> np.ndarray:
    """(n, 3, 3) clip x, y, w of triangles that cross the view volume's planes
    (z follows from w, see PERSPECTIVE: outside the near plane for w < NEAR,
    beyond the far one for w > FAR)."""
    size = np.array([width, height])
    if kind == "near_far":
        window = rng.uniform(-0.1, 1.1, size=(n, 3, 2)) * size
        w = np.exp(rng.uniform(np.log(0.15), np.log(12.0), size=(n, 3, 1)))
    elif kind == "sides":
        window = rng.uniform(-1.5, 2.5, size=(n, 3, 2)) * size
        w = rng.uniform(0.6, 3.5, size=(n, 3, 1))
    elif kind == "behind_eye":
        w = rng.uniform(-3, 3, size=(n, 3, 1))
        window = rng.uniform(-0.5, 1.5, size=(n, 3, 2)) * size
    elif kind == "far_outside":
        # One vertex 1e3..1e7 viewports away: the clipper starts each new
        # vertex from the end nearer the plane (Mesa's draw_pipe_clip.c).
        window = rng.uniform(0.05, 0.95, size=(n, 3, 2)) * size
        far = 10.0 ** rng.uniform(3, 7, size=(n, 2)) * rng.choice([-1, 1], size=(n, 2))
        window[:, 0] = size * (0.5 + far * (rng.random((n, 2)) < [[0.7, 0.7]]))
        w = rng.uniform(0.6, 3.5, size=(n, 3, 1))
    else:
        raise ValueError(kind)
    ndc = window / (size / 2) - 1
    return np.concatenate([ndc * w, w], axis=2)


def coverage_scene(triangles: np.ndarray, width: int, height: int, samples: int = 1,
                   culls: list | None = None) -> dict:
    """A scene drawing a pass of triangles, one node each, encoded as the
    module docstring says.  triangles : (n, 3, 2) window coordinates (identity
    camera) or (n, 3, 3) clip x, y, w (the PERSPECTIVE camera)."""
    nodes = []
    clip_space = triangles.shape[2] == 3
    for k, tri in enumerate(triangles):
        if clip_space:
            position = np.stack([tri[:, 0], tri[:, 1], -tri[:, 2]], axis=1)
        else:
            position = np.zeros((3, 3))
            position[:, 0] = tri[:, 0] / (width / 2) - 1
            position[:, 1] = tri[:, 1] / (height / 2) - 1
        color = [0.0, 0.0, 0.0, 1.0]
        if samples == 1:
            color[k // 8] = (1 << (k % 8)) / 255
        else:
            color[k // 3] = 4 * 5 ** (k % 3) / 255
        node = {"name": f"t{k}", "mesh": {"positions": position.tolist(), "indices": [[0, 1, 2]]},
                "material": {"color": color}, "blend": "add", "depth_test": False}
        if culls is not None:
            node["cull"] = culls[k]
        nodes.append(node)
    camera = {"projection_matrix": PERSPECTIVE if clip_space else IDENTITY, "view_matrix": IDENTITY}
    scene = {"softras_scene": 1, "width": width, "height": height, "background": [0, 0, 0, 1],
             "camera": camera, "nodes": nodes}
    if samples != 1:
        scene["samples"] = samples
    return scene


def coverage_masks(image: np.ndarray, n: int) -> np.ndarray:
    """(H, W, 4) encoded image -> (n, H, W) bool coverage of each triangle (1 sample)."""
    return np.stack([(image[..., k // 8] >> (k % 8)) & 1 for k in range(n)]).astype(bool)


def coverage_counts(image: np.ndarray, n: int, samples: int) -> np.ndarray:
    """(H, W, 4) encoded image -> (n, H, W) covered samples of each triangle per pixel."""
    if samples == 1:
        return coverage_masks(image, n).astype(int)
    return np.stack([(image[..., k // 3].astype(int) // 5 ** (k % 3)) % 5 for k in range(n)])


def sample_values(n: int, samples: int) -> tuple[np.ndarray, np.ndarray]:
    """(channel, byte added per covered sample) of each triangle of a pass."""
    k = np.arange(n)
    if samples == 1:
        return k // 8, 1 << (k % 8)
    return k // 3, 4 * 5 ** (k % 3)


def stage_image(scene, positions: np.ndarray, ties: bool = False):
    """The pass's encoded RGB bytes (H, W, 3), row 0 = top, from each draw's
    covered samples computed by the stage functions alone (gl precision,
    llvmpipe clipping), the draws of one cull mode in one batch; with ties,
    also `edge_ties` per draw, (n, 3)."""
    offsets, unit = setup.sample_offsets(positions, "gl")
    width, height, n = scene.width, scene.height, len(scene.draws)
    channel, value = sample_values(n, len(positions))
    image = np.zeros(height * width * 3)
    on_edges = np.zeros((n, 3), int)
    for cull in CULLS:
        draws = [k for k, d in enumerate(scene.draws) if d.cull == cull]
        if not draws:
            continue
        clips, indices, owner, base = [], [], [], 0
        for k in draws:
            draw = scene.draws[k]
            mvp = vertex.model_view_projection(scene.camera.projection, scene.camera.view, draw.world)
            clips.append(vertex.to_clip(draw.mesh.positions, mvp, "gl"))
            indices.append(draw.mesh.indices + base)
            owner += [k] * len(draw.mesh.indices)
            base += len(draw.mesh.positions)
        clipped = clip.clip_triangles(np.concatenate(clips), np.concatenate(indices), precision="gl",
                                      policy="llvmpipe", width=width, height=height)
        tris = setup.setup_triangles(clipped.clip, width, height, precision="gl", cull=cull, offsets=offsets,
                                     unit=unit, generated=clipped.generated)
        frags = rasterize.rasterize(tris, offsets, unit)
        draw = np.asarray(owner, int)[clipped.source[tris.triangle]][frags.tri]
        bits = (frags.mask if len(positions) == 1 else
                sum((frags.mask.astype(np.int64) >> s) & 1 for s in range(len(positions))))
        where = np.ravel_multi_index((height - 1 - frags.y, frags.x, channel[draw]), (height, width, 3))
        image += np.bincount(where, bits * value[draw], image.size)
        if ties:
            np.add.at(on_edges, np.asarray(owner, int)[clipped.source[tris.triangle]],
                      edge_ties(tris, offsets, unit))
    return (image / len(positions)).reshape(height, width, 3), on_edges


def edge_ties(tris: setup.TriangleSetup, offsets: np.ndarray, unit: float) -> np.ndarray:
    """(T, 3) per set-up triangle: samples of its bounding box on one edge
    (that edge function exactly 0, the others >= 0) that the fill rule
    covers, that it leaves out, and samples on two edges (a vertex)."""
    out = np.zeros((len(tris), 3), int)
    for t in range(len(tris)):
        x0, x1, y0, y1 = tris.bbox[t]
        px, py = np.meshgrid(np.arange(x0, x1 + 1), np.arange(y0, y1 + 1))
        sx = (px[..., None] * int(unit) + offsets[:, 0]).ravel()
        sy = (py[..., None] * int(unit) + offsets[:, 1]).ravel()
        e = (tris.edge_a[t][:, None] * (sx - tris.edge_x0[t][:, None])
             + tris.edge_b[t][:, None] * (sy - tris.edge_y0[t][:, None]))           # (3, samples)
        zero = (e == 0) & (e >= 0).all(axis=0)
        one = zero.sum(axis=0) == 1
        covered = ((e > 0) | ((e == 0) & tris.edge_inclusive[t][:, None])).all(axis=0)
        out[t] = [(one & covered).sum(), (one & ~covered).sum(), (zero.sum(axis=0) >= 2).sum()]
    return out


def compare_pass(scene_data: dict, n: int, samples: int, pass_index: int, ties: bool = False):
    """Render one pass with GL, the fast path, the stages and (every
    RENDER_SCENE_EVERY-th pass) render_scene(fast_path=False).  Returns
    {path: [(triangle within the pass, differing pixels)]} and the stages'
    `edge_ties` per triangle."""
    scene = softras.load_scene(scene_data)
    positions = GL_CENTER if samples == 1 else GL_MSAA4
    gl = softras.render(scene, backend="gl")[..., :3]
    images = {"fast path": softras.render(scene)[..., :3]}
    images["stages"], on_edges = stage_image(scene, positions, ties)
    if pass_index % RENDER_SCENE_EVERY == 0:
        images["render_scene(fast_path=False)"] = render_scene(scene, fast_path=False)[..., :3]
    differ = {}
    for path, image in images.items():
        if (image == gl).all():
            continue
        mine, theirs = (coverage_counts(np.asarray(im, np.uint8), n, samples) for im in (image, gl))
        differ[path] = ([(k, int((mine[k] != theirs[k]).sum())) for k in range(n) if (mine[k] != theirs[k]).any()]
                        or [(0, int((image != gl).any(axis=2).sum()))])
    return differ, on_edges


def run_kind(generate, n_triangles: int, per_pass: int, width: int, height: int, samples: int = 1,
             culls=None, ties: bool = False):
    """All passes of one case: (mismatches [(path, triangle, pixels, vertices,
    cull)], `edge_ties` (n, 3) when asked)."""
    mismatched, tie_counts = [], []
    for p, start in enumerate(range(0, n_triangles, per_pass)):
        triangles = generate(per_pass)
        cull = culls(per_pass) if culls else None
        differ, on_edges = compare_pass(coverage_scene(triangles, width, height, samples, cull),
                                        per_pass, samples, p, ties)
        tie_counts.append(on_edges)
        for path, found in differ.items():
            mismatched += [(path, start + k, pixels, triangles[k], cull[k] if cull else "none")
                           for k, pixels in found]
    return mismatched, np.concatenate(tie_counts)


def snapping_ties(triangles: np.ndarray, width: int, height: int) -> int:
    """How many vertex x coordinates of (n, 3, 2) window triangles reach
    softras's snap (`setup.viewport_transform` of the scene's float32 NDC,
    then (x_w - 0.5) * 256 in float32) exactly half-way between two 1/256 positions."""
    ndc = triangles[..., 0] / (width / 2) - 1
    clip_x = np.stack([ndc, np.zeros_like(ndc), np.zeros_like(ndc), np.ones_like(ndc)], axis=-1)
    x_w = setup.viewport_transform(clip_x.astype(np.float32).astype(float), width, height, "gl")[0][..., 0]
    shifted = (x_w.astype(np.float32) - np.float32(0.5)) * np.float32(256)
    return int((shifted - np.floor(shifted) == 0.5).sum())


def fail_with_first(mismatched, n_triangles, what, width, height, samples=1):
    path, index, pixels, tri, cull = mismatched[0]
    minimal = coverage_scene(tri[None], width, height, samples, [cull])
    paths = ", ".join(f"{p}: {sum(m[0] == p for m in mismatched)}" for p in dict.fromkeys(m[0] for m in mismatched))
    pytest.fail(f"triangles differing from GL ({what}; of {n_triangles}) by path: {paths}; "
                f"first: {path}, triangle {index}, {pixels} pixels, vertices {tri.tolist()}; "
                f"minimal scene: {json.dumps(minimal)}")


def assert_ties(on_edges: np.ndarray, minimum_fraction: float):
    """Most triangles have a sample exactly on one edge (not at a vertex), and
    the fill rule both covers such samples and leaves them out."""
    with_tie = (on_edges[:, :2].sum(axis=1) > 0).mean()
    assert with_tie >= minimum_fraction, f"only {with_tie:.1%} of the triangles have a sample on an edge"
    assert on_edges[:, 0].sum() > 0 and on_edges[:, 1].sum() > 0, on_edges.sum(axis=0)


@pytest.mark.gl
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("width, height", [(64, 48), (256, 160)])
def test_coverage_identical_to_llvmpipe(kind, width, height):
    """1 sample, 1,008 triangles per kind and size.  In "ties", every triangle
    has a pixel centre exactly on an edge away from its vertices: at 64x48
    6,465 such samples (3,360 covered by the fill rule, 3,105 not) and 1,785
    pixel centres on a vertex, at 256x160 7,536 (3,651 / 3,885) and 1,946;
    1,318 and 1,305 of the 3,024 vertices' x are snapping ties."""
    seed = 20261121 + width
    rng = np.random.default_rng([seed, len(kind)])
    drawn = []

    def generate(n):
        drawn.append(random_triangles(rng, n, kind, width, height))
        return drawn[-1]

    mismatched, on_edges = run_kind(generate, TRIANGLES_PER_KIND, PER_PASS, width, height, ties=kind == "ties")
    triangles = np.concatenate(drawn)
    if mismatched:
        fail_with_first(mismatched, TRIANGLES_PER_KIND, f"seed {seed}, kind {kind}", width, height)
    if kind == "ties":
        assert_ties(on_edges, 1.0)
        assert snapping_ties(triangles, width, height) > 1000


@pytest.mark.gl
@pytest.mark.parametrize("kind", ["ties", "subpixel", "slivers", "large"])
def test_msaa_coverage_identical_to_llvmpipe(kind):
    """4x MSAA (llvmpipe's sample positions), 216 triangles per kind on a
    100 x 70 viewport (two 64-pixel tiles across): covered samples per pixel
    of each triangle.  "ties" puts MSAA sample positions exactly on edges."""
    width, height = 128, 70
    seed = [20261122, len(kind)]
    rng = np.random.default_rng(seed)
    mismatched, on_edges = run_kind(lambda n: random_triangles(rng, n, kind, width, height, GL_MSAA4),
                                    216, PER_PASS_MSAA, width, height, samples=4, ties=kind == "ties")
    if mismatched:
        fail_with_first(mismatched, 216, f"seed {seed}, 4x MSAA, kind {kind}", width, height, 4)
    if kind == "ties":
        assert_ties(on_edges, 1.0)


@pytest.mark.gl
@pytest.mark.parametrize("samples", [1, 4])
@pytest.mark.parametrize("kind", CLIP_KINDS)
def test_clipped_and_culled_coverage_identical_to_llvmpipe(kind, samples):
    """Triangles through the near and far planes, beyond the sides, with
    vertices behind the eye or 1e3..1e7 viewports away, each drawn with a
    random cull mode (none, back, front) and either winding: 144 per kind."""
    width, height = 97, 75
    seed = [20261123, len(kind), samples]
    rng = np.random.default_rng(seed)
    per_pass = PER_PASS if samples == 1 else PER_PASS_MSAA
    mismatched, _ = run_kind(lambda n: clipped_triangles(rng, n, kind, width, height), 144, per_pass,
                             width, height, samples, culls=lambda n: [str(c) for c in rng.choice(CULLS, size=n)])
    if mismatched:
        fail_with_first(mismatched, 144, f"seed {seed}, kind {kind}, {samples} samples", width, height, samples)
