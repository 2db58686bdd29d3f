"""Clip stage: homogeneous clipping against the frustum planes."""

import numpy as np
import pytest

from softras.pipeline import rasterize, setup
from softras.pipeline.clip import (FRUSTUM_PLANES, _classify, _clip_kernel, _clip_with_polygons, clip_planes,
                                  clip_polygon, clip_triangles, plane_distances, triangle_list_gl)


def _tri(*points):
    return np.array(points, float)


@pytest.mark.parametrize("precision", ["gl", "exact"])
def test_inside_triangle_passes_unchanged(precision):
    clip = _tri([-0.5, -0.5, 0, 1], [0.5, -0.5, 0, 1], [0, 0.5, 0, 1])
    out = clip_triangles(clip, np.array([[0, 1, 2]]), precision=precision)
    assert len(out) == 1
    np.testing.assert_array_equal(out.clip[0], clip)
    np.testing.assert_array_equal(out.weights[0], np.eye(3))
    assert not out.generated.any()


def test_triangle_outside_one_plane_is_culled():
    clip = _tri([2, 0, 0, 1], [3, 1, 0, 1], [2, 1, 0, 1])     # x > w everywhere
    assert len(clip_triangles(clip, np.array([[0, 1, 2]]))) == 0


@pytest.mark.parametrize("precision", ["gl", "exact"])
def test_near_plane_cut_by_hand(precision):
    # One vertex behind the near plane (z < -w).  z + w is -2 at the outside
    # vertex, 1 and 2 at the others, so the edges meet z = -w at 2/3 of the
    # way to (0.5, 0, 0, 1) -> (1/3, 0, -1, 1) and half way to (0, 0.5, 1, 1)
    # -> (0, 0.25, -1, 1).
    clip = _tri([0, 0, -3, 1], [0.5, 0, 0, 1], [0, 0.5, 1, 1])
    out = clip_triangles(clip, np.array([[0, 1, 2]]), precision=precision)
    vertices = out.clip.reshape(-1, 4)
    assert (vertices[:, 2] >= -vertices[:, 3] - 1e-7).all()
    # The quadrilateral left over becomes two triangles.
    assert len(out) == 2
    # Every new vertex lies on the near plane, with weights that reproduce it.
    for t in range(len(out)):
        np.testing.assert_allclose(out.weights[t] @ clip, out.clip[t], atol=1e-6)
    new = vertices[out.generated.reshape(-1)]
    np.testing.assert_allclose(new[:, 2], -new[:, 3], atol=1e-7)
    assert any(np.allclose(v, [1 / 3, 0, -1, 1]) for v in new)
    assert any(np.allclose(v, [0, 0.25, -1, 1]) for v in new)


@pytest.mark.parametrize("precision", ["gl", "exact"])
def test_shared_edge_gives_identical_new_vertices(precision):
    # Two triangles share the edge a-b, which crosses the right plane x = w;
    # they traverse it in opposite directions.
    a, b = [0.3, -0.2, 0.1, 1.0], [1.7, 0.4, -0.2, 1.3]
    c, d = [0.1, 0.9, 0.0, 1.1], [0.2, -0.9, 0.3, 0.9]
    clip = np.array([a, b, c, d])
    out = clip_triangles(clip, np.array([[0, 1, 2], [1, 0, 3]]), precision=precision)
    first = {tuple(v) for v in out.clip[out.source == 0].reshape(-1, 4)}
    second = {tuple(v) for v in out.clip[out.source == 1].reshape(-1, 4)}
    shared = first & second
    # a itself and the one point where a-b leaves the volume are common.
    assert tuple(a) in shared and len(shared) == 2


def test_all_six_planes_clip_in_llvmpipe_policy_but_not_guard_band():
    clip = _tri([-3, -0.5, 0, 1], [3, -0.5, 0, 1], [0, 0.5, 0, 1])
    assert len(clip_triangles(clip, np.array([[0, 1, 2]]), policy="llvmpipe")) > 1
    out = clip_triangles(clip, np.array([[0, 1, 2]]), policy="guard_band", width=64, height=64)
    assert len(out) == 1 and not out.generated.any()


# ----------------------------------------------------------------------------- the compiled clipper


def _reference_clip(clip, indices, precision="gl", planes=FRUSTUM_PLANES):
    """`clip_polygon` (the readable loop) per triangle, as `clip_triangles`
    uses it (by default gl precision, the llvmpipe policy's planes): each
    triangle with a vertex outside one of planes (6, 4) (distance < 0, in
    float32 for "gl") is clipped against those planes and fanned (v[k-1],
    v[k], v[0]); triangles outside one plane or with a non-finite vertex are
    dropped, the others passed through.  Returns clip (T, 3, 4), weights
    (T, 3, 3), source (T,)."""
    outside = plane_distances(clip, planes, precision) < 0
    out_clip, out_weights, out_source = [], [], []
    for t, tri in enumerate(indices):
        if outside[tri].all(axis=0).any() or not np.isfinite(clip[tri]).all():
            continue
        mask = outside[tri].any(axis=0)
        if not mask.any():                                        # passed through as it is
            out_clip.append(clip[tri])
            out_weights.append(np.eye(3))
            out_source.append(t)
            continue
        points, weights = clip_polygon(clip[tri], np.eye(3), planes[mask], precision)
        for k in range(2, len(points)):
            out_clip.append(points[[k - 1, k, 0]])
            out_weights.append(weights[[k - 1, k, 0]])
            out_source.append(t)
    return np.array(out_clip).reshape(-1, 3, 4), np.array(out_weights).reshape(-1, 3, 3), np.array(out_source, int)


def _crossing_triangles(rng, n):
    """(3n, 4) clip-space vertices (float32 values) and (n, 3) indices: triangles
    through every plane, some vertices exactly on a plane, some 1e7 outside,
    w from -1 to 3, some edges with opposite distances d, -d to a plane."""
    w = rng.uniform(-1, 3, size=(n, 3, 1))
    xyz = rng.uniform(-2.5, 2.5, size=(n, 3, 3)) * np.abs(w)
    on_plane = rng.random((n, 3)) < 0.15                          # x, y or z = +-w exactly
    axis = rng.integers(3, size=(n, 3))
    xyz[on_plane, axis[on_plane]] = (rng.choice([-1, 1], size=(n, 3)) * w[..., 0])[on_plane]
    huge = rng.random((n, 3)) < 0.1
    xyz[huge] *= 10.0 ** rng.uniform(5, 7, size=(int(huge.sum()), 1))
    clip = np.concatenate([xyz, w], axis=2).astype(np.float32).astype(np.float64)
    # A quarter: vertex 1 the mirror image of vertex 0 in a plane (distances
    # d and -d exactly, on a 1/1024 grid), so the clipper's choice of start
    # vertex on a tie decides the new vertex's bits.
    mirror = np.nonzero(rng.random(n) < 0.25)[0]
    axis, sign = rng.integers(3, size=len(mirror)), rng.choice([-1.0, 1.0], size=len(mirror))
    grid = np.round(clip[mirror, 0] * 1024) / 1024
    grid[:, 3] = np.abs(grid[:, 3]) + 0.25
    clip[mirror, 0] = grid
    clip[mirror, 1, 3] = grid[:, 3]
    clip[mirror, 1, axis] = -grid[np.arange(len(mirror)), axis] - 2 * sign * grid[:, 3]
    return clip.reshape(-1, 4), np.arange(3 * n).reshape(n, 3)


def test_compiled_clipper_equals_clip_polygon():
    """gl precision, llvmpipe policy: `clip_triangles` (the compiled kernel
    `_clip_kernel`) and `triangle_list_gl` (the fast path's) give the
    triangles, weights and order of `clip_polygon` bit for bit, on 2,000
    triangles through all six planes (vertices on planes, 1e7 outside, w < 0,
    edges whose ends lie at distances d and -d from a plane)."""
    rng = np.random.default_rng(20261124)
    clip, indices = _crossing_triangles(rng, 2000)
    ref_clip, ref_weights, ref_source = _reference_clip(clip, indices)
    outside = plane_distances(clip, FRUSTUM_PLANES, "gl") < 0
    crossing = outside[indices].any(axis=(1, 2)) & ~outside[indices].all(axis=1).any(axis=1)
    assert crossing.sum() > 1200 and len(ref_source) > 2000          # most triangles are clipped
    assert (np.abs(clip) > 1e5).sum() > 200
    d = plane_distances(clip, FRUSTUM_PLANES, "gl")
    opposite = (d[indices[:, 0]] == -d[indices[:, 1]]) & (d[indices[:, 0]] != 0)
    assert opposite.any(axis=1).sum() > 400                          # ties for the clipper's start vertex
    out = clip_triangles(clip, indices, precision="gl", policy="llvmpipe")
    np.testing.assert_array_equal(out.source, ref_source)
    np.testing.assert_array_equal(out.clip, ref_clip)
    np.testing.assert_array_equal(out.weights, ref_weights)
    source, slot, fan_clip, fan_weights = triangle_list_gl(clip, indices)
    np.testing.assert_array_equal(source, ref_source)
    passed = slot < 0
    np.testing.assert_array_equal(clip[indices[source[passed]]], ref_clip[passed])
    np.testing.assert_array_equal(fan_clip[slot[~passed]], ref_clip[~passed])
    np.testing.assert_array_equal(fan_weights[slot[~passed]], ref_weights[~passed])
    assert (ref_weights[passed] == np.eye(3)).all()


@pytest.mark.parametrize("bad", [None, np.nan, np.inf])
def test_triangle_list_of_a_draw_inside_the_planes(bad):
    """`triangle_list_gl` returns early when every vertex is inside every
    plane (every triangle passes through): it gives `clip_triangles`' list.
    The same draw with one vertex not finite (NaN or inf: the clipper culls
    its triangles) takes the whole classification and gives its list too."""
    rng = np.random.default_rng(20261129)
    w = rng.uniform(0.5, 2.0, size=(300, 1))
    clip = np.hstack([rng.uniform(-0.9, 0.9, size=(300, 3)) * w, w])
    indices = rng.integers(300, size=(500, 3))
    if bad is not None:
        clip[indices[7, 1], 0] = bad
    out = clip_triangles(clip, indices, precision="gl", policy="llvmpipe")
    source, slot, fan_clip, fan_weights = triangle_list_gl(clip, indices)
    np.testing.assert_array_equal(source, out.source)
    assert (slot == -1).all() and len(fan_clip) == len(fan_weights) == 0
    np.testing.assert_array_equal(clip[indices[source]], out.clip)
    assert len(source) == (500 if bad is None else 500 - (indices == indices[7, 1]).any(axis=1).sum())


def _wild_triangles(rng, n, planes):
    """`_crossing_triangles`, made wilder: (V, 4) clip-space vertices and
    (n, 3) indices.  Some vertices have float64 values (not float32 ones),
    w near 0 (0, -0, 1e-30, 1e-300, the smallest subnormal, either sign),
    all four coordinates 1e-38 to 1e-320 (float32 distances underflow to
    +-0), a coordinate 1e30 to 1e308 (float32 distances and points
    overflow: inf and NaN), or an inf or NaN coordinate (culled); in some
    triangles vertex 1 lies at distance -d (1 + 1e-9 e), |e| < 1, from one
    of planes (P, 4), vertex 0 at d (a tie for the clipper's start vertex in
    float32, not in float64); some triangles are scaled to coordinates up
    to 2e307 to 1.7e308 (float64 distances and differences overflow too); a
    quarter of the triangles share vertices (random indices, some repeated:
    degenerate triangles)."""
    clip, indices = _crossing_triangles(rng, n)
    v = len(clip)
    noisy = rng.random(v) < 0.4
    clip[noisy] *= 1 + rng.uniform(-1e-3, 1e-3, size=(int(noisy.sum()), 4))
    near_tie = indices[rng.random(n) < 0.2]                       # (T, 3) vertex 1 almost mirrors vertex 0
    plane = planes[rng.integers(len(planes), size=len(near_tie))]
    d0 = (clip[near_tie[:, 0]] * plane).sum(axis=1, keepdims=True)
    factor = 2 + 1e-9 * rng.uniform(-1, 1, size=(len(near_tie), 1))
    clip[near_tie[:, 1]] = clip[near_tie[:, 0]] - factor * d0 * plane / (plane * plane).sum(axis=1, keepdims=True)
    small = rng.random(v) < 0.03
    clip[small] *= 10.0 ** -rng.uniform(38, 320, size=(int(small.sum()), 1))
    tiny = np.nonzero(rng.random(v) < 0.1)[0]
    clip[tiny, 3] = rng.choice([0.0, -0.0, 1e-30, -1e-30, 1e-300, -1e-300, 5e-324, -5e-324, 1e-8, -1e-8], len(tiny))
    far = np.nonzero(rng.random(v) < 0.04)[0]
    with np.errstate(over="ignore", invalid="ignore"):             # (a few overflow to inf: culled)
        clip[far, rng.integers(4, size=len(far))] *= 10.0 ** rng.uniform(30, 308, size=len(far))
        brink = indices[rng.random(n) < 0.05]                     # whole triangles near float64's largest
        largest = np.maximum(np.abs(clip[brink]).max(axis=(1, 2), keepdims=True), 1.0)
        clip[brink] *= rng.uniform(0.2, 1.7, size=(len(brink), 1, 1)) * (1e308 / largest)
    bad = np.nonzero(rng.random(v) < 0.02)[0]
    clip[bad, rng.integers(4, size=len(bad))] = rng.choice([np.inf, -np.inf, np.nan], len(bad))
    shared = rng.random(n) < 0.25
    indices[shared] = rng.integers(v, size=(int(shared.sum()), 3))
    return clip, indices


def _polygon_loop(clip, indices, precision, planes):
    """`clip_triangles` with the crossing triangles through the module's
    reference loop `_clip_with_polygons` instead of its kernel."""
    outside = plane_distances(clip, planes, precision) < 0
    keep, crossing = np.empty(len(indices), bool), np.empty(len(indices), bool)
    _classify(outside, np.isfinite(clip).all(axis=1), indices, keep, crossing)
    cross = np.nonzero(crossing)[0]
    return _clip_with_polygons(clip, indices, keep, cross, outside[indices[cross]].any(axis=1), planes, precision)


def _same_bits(ours, reference, what):
    """ours and reference equal in shape, value (NaN where NaN) and sign bit."""
    assert ours.shape == reference.shape, f"{what}: shape {ours.shape} != {reference.shape}"
    assert np.array_equal(ours, reference, equal_nan=True), f"{what}: {int((ours != reference).sum())} values differ"
    assert np.array_equal(np.signbit(ours), np.signbit(reference)), f"{what}: sign bits differ"


@pytest.mark.parametrize("policy", ["llvmpipe", "guard_band"])
@pytest.mark.parametrize("precision", ["gl", "exact"])
def test_compiled_clipper_equals_clip_polygon_in_every_precision_and_policy(precision, policy):
    """`clip_triangles` (the compiled `_clip_kernel`) and the module's
    reference loop `_clip_with_polygons` give the triangles, sources and
    weights of `clip_polygon` per triangle bit for bit, sign bits of zeros
    and NaNs included, in either precision and policy: 30 meshes of
    200 triangles (`_wild_triangles`: through every plane, vertices on planes
    and 1e7 to 1e308 outside, w near 0 or negative, inf and NaN, overflowing
    distances), each on a viewport whose guard band is 1 to 32 times the
    view (scales such as 16.4 and 27.26, whose products with w round)."""
    crossing = generated = nonfinite = negative_zeros = 0
    for seed in range(30):
        rng = np.random.default_rng([20261126, seed])
        width, height = [(512, 512), (999, 601), (16384, 20000), (3000, 7000)][seed % 4]
        planes = clip_planes(policy, width, height)
        clip, indices = _wild_triangles(rng, 200, planes)
        with np.errstate(all="ignore"):
            ref_clip, ref_weights, ref_source = _reference_clip(clip, indices, precision, planes)
            out = clip_triangles(clip, indices, precision=precision, policy=policy, width=width, height=height)
            loop = _polygon_loop(clip, indices, precision, planes)
            outside = plane_distances(clip, planes, precision)[indices] < 0
        for result, name in ((out, "clip_triangles"), (loop, "_clip_with_polygons")):
            _same_bits(result.source, ref_source, f"seed {seed}, {name}: source")
            _same_bits(result.clip, ref_clip, f"seed {seed}, {name}: clip")
            _same_bits(result.weights, ref_weights, f"seed {seed}, {name}: weights")
        crossing += (outside.any(axis=(1, 2)) & ~outside.all(axis=1).any(axis=1)
                     & np.isfinite(clip[indices]).all(axis=(1, 2))).sum()
        generated += out.generated.sum()
        nonfinite += (~np.isfinite(out.clip)).any(axis=(1, 2)).sum()
        negative_zeros += ((out.clip == 0) & np.signbit(out.clip)).sum()
    assert crossing > 1500 and generated > 3000                   # the kernel, not the pass-through, decides
    assert negative_zeros > 0
    assert nonfinite > 0                                          # overflow (inf, NaN) reached the kernel


@pytest.mark.parametrize("precision", ["gl", "exact"])
def test_clip_kernel_equals_clip_polygon_for_any_planes(precision):
    """`_clip_kernel` itself, against planes whose four coefficients are all
    inexact (so the order of the distance's sum and any fused multiply-add
    would show, unlike with the frustum and guard-band planes): 20 sets of
    six random planes, 100 `_wild_triangles` (the finite ones) each, each
    triangle clipped against a random subset of them in order; the fan
    sizes, corners and weights are `clip_polygon`'s bit for bit."""
    generated = 0
    for seed in range(20):
        rng = np.random.default_rng([20261127, seed])
        planes = rng.standard_normal((6, 4))
        planes[:, 3] = np.abs(planes[:, 3]) + 0.5                    # the origin (0, 0, 0, 1) inside
        clip, indices = _wild_triangles(rng, 100, planes)
        corners = clip[indices][np.isfinite(clip[indices]).all(axis=(1, 2))]
        mask = rng.random((len(corners), 6)) < 0.6
        with np.errstate(all="ignore"):
            counts = _clip_kernel(corners, mask, planes, precision == "gl", np.zeros(len(corners), np.int64),
                                  np.zeros((0, 3, 4)), np.zeros((0, 3, 3)), False)
            fans_clip, fans_weights = np.empty((counts.sum(), 3, 4)), np.empty((counts.sum(), 3, 3))
            _clip_kernel(corners, mask, planes, precision == "gl", counts, fans_clip, fans_weights, True)
            ref_counts, ref_clip, ref_weights = [], [np.zeros((0, 3, 4))], [np.zeros((0, 3, 3))]
            for triangle, planes_used in zip(corners, mask):
                points, weights = clip_polygon(triangle, np.eye(3), planes[planes_used], precision)
                fan = [[k - 1, k, 0] for k in range(2, len(points))]
                ref_counts.append(len(fan))
                ref_clip += [points[fan]] if fan else []
                ref_weights += [weights[fan]] if fan else []
        _same_bits(counts, np.array(ref_counts, np.int64), f"seed {seed}: fan sizes")
        _same_bits(fans_clip, np.concatenate(ref_clip), f"seed {seed}: clip")
        _same_bits(fans_weights, np.concatenate(ref_weights), f"seed {seed}: weights")
        generated += (fans_weights.max(axis=2) != 1).sum()
    assert generated > 2000


# ----------------------------------------------------------------------------- the viewport transform's rounding


NEAR, FAR = 0.5, 4.0
# clip = P (x, y, z, 1) = (x, y, A z + B, -z): position (x_c, y_c, -w_c) has clip x_c, y_c, w_c.
PERSPECTIVE = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, -(FAR + NEAR) / (FAR - NEAR), -2 * FAR * NEAR / (FAR - NEAR),
               0, 0, -1, 0]
IDENTITY = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]


def _pass_scene(positions, width, height):
    """Triangles (n, 3, 3) as nodes, triangle k adding 2^(k mod 8)/255 to channel k // 8."""
    nodes = [{"name": f"t{k}", "mesh": {"positions": tri.tolist(), "indices": [[0, 1, 2]]},
              "material": {"color": [float(c == k // 8) * (1 << (k % 8)) / 255 for c in range(3)] + [1.0]},
              "blend": "add", "depth_test": False} for k, tri in enumerate(positions)]
    return {"softras_scene": 1, "width": width, "height": height, "background": [0, 0, 0, 1],
            "camera": {"projection_matrix": PERSPECTIVE, "view_matrix": IDENTITY}, "nodes": nodes}


def _stage_fragments(clip, width, height, other_form=None):
    """(triangle, x, GL row) of the pixels the triangles (n, 3, 4) cover through
    the stages: input vertices through the fused viewport transform and new
    ones through the unfused one, as softras does; other_form "input" or
    "new": those vertices through the other form."""
    n = len(clip)
    offsets, unit = setup.sample_offsets(np.array([[0.5, 0.5]]), "gl")
    clipped = clip_triangles(clip.reshape(-1, 4), np.arange(3 * n).reshape(n, 3), precision="gl")
    unfused = {None: clipped.generated, "new": np.zeros_like(clipped.generated),
               "input": np.ones_like(clipped.generated)}[other_form]
    tris = setup.setup_triangles(clipped.clip, width, height, offsets=offsets, unit=unit, generated=unfused)
    frags = rasterize.rasterize(tris, offsets, unit)
    return clipped.source[tris.triangle[frags.tri]], frags.x, frags.y


def _signatures(fragments, n, width):
    """(n, 3) per triangle: covered pixels, sum and sum of squares of their
    index y * width + x (equal for two coverages only if they are equal, here)."""
    triangle, x, y = fragments
    key = (y * width + x).astype(float)
    return np.stack([np.bincount(triangle, weights, n) for weights in (None, key, key * key)], axis=1)


def _masks(fragments, n, width, height):
    """(n, H, W) bool, row 0 = top."""
    triangle, x, y = fragments
    masks = np.zeros((n, height, width), bool)
    masks[triangle, height - 1 - y, x] = True
    return masks


@pytest.mark.gl
@pytest.mark.parametrize("vertices", ["input", "new"])
def test_viewport_transform_is_fused_for_input_vertices_unfused_for_new_ones_like_llvmpipe(vertices):
    """llvmpipe's vertex code computes x_w = fma(x / w, W/2, W/2) with one
    rounding; vertices made by the clipper go through Mesa's C viewport
    transform, product and sum rounded separately (README, the ``fused``
    argument of `setup.viewport_transform`).  Among random triangles on a
    999 x 601 viewport (W/2 and H/2 not powers of two, so the product
    rounds) -- 3,000 inside the view for "input", 10,000 through the near and
    side planes for "new" -- those whose coverage the other form for these
    vertices would change (input: 19, new: 26), the first 12: GL draws every one as
    softras does, the other form differs from GL on each, and the fast path
    and render_scene(fast_path=False) draw them as GL."""
    import softras
    from softras.pipeline import vertex
    from softras.renderer import render_scene

    width, height, n = 999, 601, 10000 if vertices == "new" else 3000
    rng = np.random.default_rng(20261125)
    if vertices == "new":
        w = rng.uniform(0.1, 3.0, size=(n, 3, 1))                  # w < NEAR: through the near plane
        xy = rng.uniform(-1.3, 1.3, size=(n, 3, 2)) * w
    else:
        w = rng.uniform(0.6, 3.0, size=(n, 3, 1))
        xy = rng.uniform(-0.98, 0.98, size=(n, 3, 2)) * w
    positions = np.concatenate([xy, -w], axis=2)
    mvp = np.array(PERSPECTIVE, float).reshape(4, 4)
    clip = vertex.to_clip(positions.reshape(-1, 3), mvp, "gl").reshape(n, 3, 4)
    # Candidates: a vertex of the kind whose snapped position depends on the form.
    clipped = clip_triangles(clip.reshape(-1, 4), np.arange(3 * n).reshape(n, 3), precision="gl")
    snapped = [setup.snap(setup.viewport_transform(clipped.clip, width, height, "gl", fused)[0][..., :2])
               for fused in (True, False)]
    kind = clipped.generated if vertices == "new" else ~clipped.generated
    moved = ((snapped[0] != snapped[1]).any(axis=2) & kind).any(axis=1)
    candidates = np.unique(clipped.source[moved])
    ours, other = (_signatures(_stage_fragments(clip[candidates], width, height, f), len(candidates), width)
                   for f in (None, vertices))
    differ = candidates[(ours != other).any(axis=1)]
    assert len(differ) >= 12, (f"{len(differ)} of the {len(candidates)} triangles with a vertex whose snapped "
                               f"position depends on the form change coverage: does setup_triangles use `generated`?")
    chosen = differ[:12]
    scene = softras.load_scene(_pass_scene(positions[chosen], width, height))
    gl = softras.render(scene, backend="gl")
    gl_masks = np.stack([(gl[..., k // 8] >> (k % 8)) & 1 for k in range(12)]).astype(bool)
    ours, other = (_masks(_stage_fragments(clip[chosen], width, height, f), 12, width, height)
                   for f in (None, vertices))
    assert (ours == gl_masks).all(axis=(1, 2)).all(), chosen[(ours != gl_masks).any(axis=(1, 2))]
    assert (other != gl_masks).any(axis=(1, 2)).all(), chosen[(other == gl_masks).all(axis=(1, 2))]
    for path, image in (("fast path", softras.render(scene)), ("stages", render_scene(scene, fast_path=False))):
        assert (image == gl).all(), f"{path}: {int((image != gl).any(axis=2).sum())} pixels differ from GL"
