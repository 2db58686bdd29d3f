"""Line stage: Bresenham by hand, the diamond-exit rule on hand-picked lines,
clipping by hand, interpolation, and the rasterizer's candidate search.

The expected diamond-rule pixels were worked out by hand from the rule and
agree with llvmpipe (tests/test_random_lines.py checks thousands more
against glref).  Pixels are (x, y) in GL's y-up window space.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from softras.pipeline import lines

MSAA4 = np.array([[0.375, 0.125], [0.875, 0.375], [0.125, 0.625], [0.625, 0.875]])


def pixels(seg, width=8, height=8, precision="gl"):
    frags, _ = lines.rasterize_lines(np.array([seg], float), width, height, precision)
    return sorted(zip(frags.x.tolist(), frags.y.tolist()))


# --------------------------------------------------------------------------- Bresenham


@pytest.mark.parametrize("end, expected", [
    # slope 2/5: the ideal y at x = 0..5 is 0, .4, .8, 1.2, 1.6, 2
    ((5, 2), [(0, 0), (1, 0), (2, 1), (3, 1), (4, 2), (5, 2)]),
    ((-5, 2), [(0, 0), (-1, 0), (-2, 1), (-3, 1), (-4, 2), (-5, 2)]),
    ((-5, -2), [(0, 0), (-1, 0), (-2, -1), (-3, -1), (-4, -2), (-5, -2)]),
    ((5, -2), [(0, 0), (1, 0), (2, -1), (3, -1), (4, -2), (5, -2)]),
    # steep: the same with x and y swapped
    ((2, 5), [(0, 0), (0, 1), (1, 2), (1, 3), (2, 4), (2, 5)]),
    ((-2, 5), [(0, 0), (0, 1), (-1, 2), (-1, 3), (-2, 4), (-2, 5)]),
    ((-2, -5), [(0, 0), (0, -1), (-1, -2), (-1, -3), (-2, -4), (-2, -5)]),
    ((2, -5), [(0, 0), (0, -1), (1, -2), (1, -3), (2, -4), (2, -5)]),
], ids=["octant1", "octant4", "octant5", "octant8", "octant2", "octant3", "octant6", "octant7"])
def test_bresenham_octants_by_hand(end, expected):
    assert lines.bresenham(0, 0, *end) == expected


def test_bresenham_axes_diagonals_and_a_point():
    assert lines.bresenham(2, 3, 6, 3) == [(2, 3), (3, 3), (4, 3), (5, 3), (6, 3)]
    assert lines.bresenham(2, 3, 2, 0) == [(2, 3), (2, 2), (2, 1), (2, 0)]
    assert lines.bresenham(0, 0, 3, 3) == [(0, 0), (1, 1), (2, 2), (3, 3)]
    assert lines.bresenham(0, 0, -3, 3) == [(0, 0), (-1, 1), (-2, 2), (-3, 3)]
    assert lines.bresenham(7, -4, 7, -4) == [(7, -4)]


def test_bresenham_ties_do_not_step_so_direction_matters():
    # (0,0)-(2,1): at x = 1 the ideal y is exactly 0.5.
    assert lines.bresenham(0, 0, 2, 1) == [(0, 0), (1, 0), (2, 1)]
    assert lines.bresenham(2, 1, 0, 0) == [(2, 1), (1, 1), (0, 0)]


def test_bresenham_is_integer_only():
    with pytest.raises(TypeError):
        lines.bresenham(0.5, 0, 3, 1)
    with pytest.raises(TypeError):
        lines.bresenham(0, 0, True, 1)
    assert lines.bresenham(np.int64(0), np.int32(0), 2, 0) == [(0, 0), (1, 0), (2, 0)]


@settings(max_examples=200, deadline=None)
@given(st.integers(-40, 40), st.integers(-40, 40), st.integers(-40, 40), st.integers(-40, 40))
def test_bresenham_properties(x0, y0, x1, y1):
    path = lines.bresenham(x0, y0, x1, y1)
    major = max(abs(x1 - x0), abs(y1 - y0))
    assert len(path) == major + 1
    assert path[0] == (x0, y0) and path[-1] == (x1, y1)
    for (ax, ay), (bx, by) in zip(path, path[1:]):        # 8-connected, one major step each
        assert max(abs(bx - ax), abs(by - ay)) == 1
    if major:
        for px, py in path:                                 # within half a pixel of the ideal line
            if abs(x1 - x0) >= abs(y1 - y0):
                ideal = y0 + (px - x0) * (y1 - y0) / (x1 - x0)
                assert abs(py - ideal) <= 0.5
            else:
                ideal = x0 + (py - y0) * (x1 - x0) / (y1 - y0)
                assert abs(px - ideal) <= 0.5


# --------------------------------------------------------------------------- diamond-exit rule


def test_horizontal_line_between_pixel_centres_draws_start_not_end():
    # The start point is the centre of pixel 0: inside its diamond, drawn.
    # The end point is the centre of pixel 4: the line never leaves that
    # diamond, so pixel 4 is not drawn.  Reversed, the roles swap.
    assert pixels([[0.5, 0.5], [4.5, 0.5]]) == [(0, 0), (1, 0), (2, 0), (3, 0)]
    assert pixels([[4.5, 0.5], [0.5, 0.5]]) == [(1, 0), (2, 0), (3, 0), (4, 0)]


def test_vertical_and_diagonal_lines_from_a_pixel_centre():
    assert pixels([[0.5, 0.5], [0.5, 4.5]]) == [(0, 0), (0, 1), (0, 2), (0, 3)]
    assert pixels([[0.5, 0.5], [3.5, 3.5]]) == [(0, 0), (1, 1), (2, 2)]
    assert pixels([[3.5, 3.5], [0.5, 0.5]]) == [(1, 1), (2, 2), (3, 3)]
    assert pixels([[0.5, 2.5], [2.5, 0.5]]) == [(0, 2), (1, 1)]


def test_llvmpipe_22_drops_the_start_of_y_major_lines_running_down_from_a_centre():
    # Mesa 22.3's "will_draw_start" sign test is wrong when the start y is
    # exactly a pixel centre and the line runs down (GL y-up): the start pixel
    # (0, 4) is not drawn, although the diamond rule says it should be.
    assert pixels([[0.5, 4.5], [0.5, 0.5]]) == [(0, 1), (0, 2), (0, 3)]
    assert pixels([[0.5, 0.5], [0.5, 4.5]]) == [(0, 0), (0, 1), (0, 2), (0, 3)]
    # Exact precision applies the rule as written (later Mesa's tests).
    assert pixels([[0.5, 4.5], [0.5, 0.5]], precision="exact") == [(0, 1), (0, 2), (0, 3), (0, 4)]


def test_start_outside_its_diamond_is_not_drawn():
    # (0.95, 0.95) is in pixel (0, 0) but outside its diamond (0.45 + 0.45 >
    # 0.5), and the horizontal line to the right never enters that diamond.
    # The end (4.5, 0.95) lies inside pixel 4's diamond: not drawn either.
    assert pixels([[0.95, 0.95], [4.5, 0.95]]) == [(1, 0), (2, 0), (3, 0)]


def test_end_inside_or_past_the_last_diamond():
    assert pixels([[0.5, 0.5], [4.9, 0.5]]) == [(0, 0), (1, 0), (2, 0), (3, 0)]
    # Past pixel 4's diamond into pixel 5's: the line exits diamond 4.
    assert pixels([[0.5, 0.5], [5.05, 0.5]]) == [(0, 0), (1, 0), (2, 0), (3, 0), (4, 0)]


def test_segment_inside_one_diamond_draws_nothing():
    assert pixels([[2.4, 2.5], [2.6, 2.5]]) == []
    assert pixels([[2.5, 2.3], [2.5, 2.7]]) == []


def test_lines_on_pixel_borders_take_the_lower_and_left_pixels():
    assert pixels([[0.5, 1.0], [4.5, 1.0]]) == [(0, 0), (1, 0), (2, 0), (3, 0)]
    assert pixels([[1.0, 0.5], [1.0, 4.5]]) == [(0, 0), (0, 1), (0, 2), (0, 3)]
    # Corner to corner: the diagonal passes through the diamonds' corners.
    assert pixels([[0, 0], [4, 4]]) == [(0, 0), (1, 1), (2, 2), (3, 3)]
    assert pixels([[4, 4], [0, 0]]) == [(0, 0), (1, 1), (2, 2), (3, 3)]


def test_zero_length_and_empty_input():
    assert pixels([[2.25, 2.25], [2.25, 2.25]]) == []
    frags, t = lines.rasterize_lines(np.zeros((0, 2, 3)), 8, 8)
    assert len(frags) == 0 and len(t) == 0


def test_fragments_are_clipped_to_the_framebuffer_and_in_line_order():
    window = np.array([[[-3.2, 1.5], [10.7, 2.5]], [[1.5, 9.5], [2.5, -4.5]]])
    frags, _ = lines.rasterize_lines(window, 6, 5)
    assert (frags.x >= 0).all() and (frags.x < 6).all() and (frags.y >= 0).all() and (frags.y < 5).all()
    assert (np.diff(frags.tri) >= 0).all() and set(frags.tri.tolist()) == {0, 1}


@settings(max_examples=80, deadline=None)
@given(st.lists(st.floats(0, 24, allow_nan=False), min_size=4, max_size=4),
       st.sampled_from(["gl", "exact"]))
def test_one_pixel_per_major_step(coords, precision):
    """A diamond line draws at most one pixel per column (x-major) or row (y-major),
    and those columns or rows are contiguous."""
    x0, y0, x1, y1 = coords
    frags, _ = lines.rasterize_lines(np.array([[[x0, y0], [x1, y1]]]), 24, 24, precision)
    f = np.float32 if precision == "gl" else np.float64
    xmajor = abs(f(x1) - f(x0)) >= abs(f(y1) - f(y0))
    major = frags.x if xmajor else frags.y
    assert len(set(major.tolist())) == len(major)
    if len(major):
        assert major.max() - major.min() + 1 == len(major)


# --------------------------------------------------------------------------- quads, candidates, MSAA


def test_quad_of_a_horizontal_line_by_hand():
    # (0.5, 0.5)-(4.5, 0.5): x-major; v1 is swapped to be the right end; the
    # corners are snapped (v - 0.5) * 256, y +- 128.  The left end (pixel 0's
    # centre, X = 0) is an inclusive edge.  The end point is pixel 4's centre:
    # not to be drawn, and Mesa 22.3's sign test believes the quad would draw
    # it (x2diff == 0 counts as "drawn"), so it moves the right end back half
    # a pixel, to window x = 4.0 (X = 896); exclusive anyway.
    qx, qy, ok = lines.line_quads(np.array([[[0.5, 0.5], [4.5, 0.5]]]))
    assert ok[0]
    assert qx[0].tolist() == [896, 0, 0, 896]
    assert qy[0].tolist() == [-128, -128, 128, 128]
    qx, _, _ = lines.line_quads(np.array([[[0.5, 0.5], [4.5, 0.5]]]), precision="exact")
    assert qx[0].tolist() == [1024, 0, 0, 1024]


def test_subpixel_snap_rounds_half_away_from_zero():
    # x = 0.5 + 1.5/256: (x - 0.5) * 256 = 1.5 -> 2 (half-even would give 2 too);
    # x = 0.5 + 2.5/256 -> 3 (half-even: 2).  A vertical line keeps x exact.
    for k, expected in [(1.5, 2), (2.5, 3), (-2.5, -3)]:
        x = 0.5 + k / 256
        qx, _, _ = lines.line_quads(np.array([[[x, 0.5], [x, 6.5]]]))
        assert qx[0, 0] + 128 == expected


def brute_force(qx, qy, offsets, region):
    """All samples of all pixels in region tested against the four planes (pure numpy)."""
    x0, x1, y0, y1 = region
    px, py = np.meshgrid(np.arange(x0, x1 + 1), np.arange(y0, y1 + 1), indexing="xy")
    covered = {}
    for s, (ox, oy) in enumerate(offsets):
        X = px * 256.0 + ox
        Y = py * 256.0 + oy
        inside = np.ones(X.shape, bool)
        for i in range(4):
            j = (i + 1) % 4
            dcdx, dcdy = qy[i] - qy[j], qx[i] - qx[j]
            e = dcdx * (qx[i] - X) + dcdy * (Y - qy[i])
            inclusive = dcdx < 0 or (dcdx == 0 and dcdy > 0)
            inside &= (e > 0) | ((e == 0) & inclusive)
        for x, y in zip(px[inside].tolist(), py[inside].tolist()):
            covered[(x, y)] = covered.get((x, y), 0) | (1 << s)
    return covered


def assert_candidates_cover_every_sample(x0, y0, x1, y1, width, height, msaa):
    """The line (x0, y0)-(x1, y1)'s fragments from `rasterize_lines` (its
    per-row candidate search, then the plane tests) are a brute-force test
    of every sample in llvmpipe's binned region, at 1 sample or MSAA4."""
    window = np.array([[[x0, y0], [x1, y1]]])
    positions = MSAA4 if msaa else np.array([[0.5, 0.5]])
    frags, _ = lines.rasterize_lines(window, width, height, sample_positions=positions)
    got = {(x, y): m for x, y, m in zip(frags.x.tolist(), frags.y.tolist(), frags.mask.tolist())}
    qx, qy, ok = lines.line_quads(window, rectangular=msaa)
    region = np.zeros(4, np.int64)
    if not ok[0] or not lines._binned_region(qx[0], qy[0], 0, msaa, width, height, region):
        assert got == {}, (x0, y0, x1, y1, msaa)
        return
    offsets = np.rint((positions - (0.0 if msaa else 0.5)) * 256)
    assert got == brute_force(qx[0], qy[0], offsets, region), (x0, y0, x1, y1, msaa)


@settings(max_examples=120, deadline=None)
@given(st.lists(st.floats(-6, 30, allow_nan=False), min_size=4, max_size=4), st.booleans())
def test_candidate_search_finds_every_covered_sample(coords, msaa):
    """The per-row candidate search of the numba kernel misses nothing: it
    equals a brute-force test of every sample in llvmpipe's binned region."""
    assert_candidates_cover_every_sample(*coords, 24, 20, msaa)


def test_candidate_search_on_pixel_centres_level_and_long_lines():
    """The candidate search (`_row_span`: at one sample a row's slice between
    the quad's edge lines) misses nothing where its bounds fall exactly on
    samples: end points on pixel centres and borders (halves), level and
    upright lines and ones 1e-9 off them, and lines thousands of pixels
    long crossing the picture; every sample of the binned region tested,
    1 and 4 samples."""
    rng = np.random.default_rng(20261129)
    windows = [np.round(rng.uniform(-10, 70, 4) * 2) / 2 for _ in range(20)]
    for _ in range(20):
        x, y = rng.uniform(0, 60, 2)
        windows.append(np.array([x, y, x + rng.choice([0, 1e-9, 30]), y + rng.choice([0, 1e-9, 25])]))
    windows += [rng.uniform(-3000, 3000, 4) for _ in range(20)]
    for window in windows:
        for msaa in (False, True):
            assert_candidates_cover_every_sample(*window, 64, 48, msaa)


def test_msaa_rectangular_line_by_hand():
    # (0.5, 1)-(4.5, 1) with 4x MSAA: the rectangle x in [0.5, 4.5], y in
    # [0.5, 1.5].  Samples (x, y) within a pixel: s0 (.375,.125) s1 (.875,.375)
    # s2 (.125,.625) s3 (.625,.875); row 0 holds s2 and s3, row 1 s0 and s1,
    # and the ends cut pixels 0 and 4 in half.
    frags, t = lines.rasterize_lines(np.array([[[0.5, 1.0], [4.5, 1.0]]]), 8, 8, "exact",
                                     sample_positions=MSAA4)
    got = {(x, y): m for x, y, m in zip(frags.x.tolist(), frags.y.tolist(), frags.mask.tolist())}
    expected = {(0, 0): 0b1000, (4, 0): 0b0100, (0, 1): 0b0010, (4, 1): 0b0001}
    for x in (1, 2, 3):
        expected[(x, 0)] = 0b1100
        expected[(x, 1)] = 0b0011
    assert got == expected
    # Exact precision: t at the pixel centres; gl shifts it like llvmpipe.
    np.testing.assert_allclose(t[frags.x == 2], 0.5)
    _, t_gl = lines.rasterize_lines(np.array([[[0.5, 1.0], [4.5, 1.0]]]), 8, 8, "gl", sample_positions=MSAA4)
    np.testing.assert_allclose(t_gl[frags.x == 2], 0.625)


def test_exact_and_gl_precision_mostly_agree():
    rng = np.random.default_rng(3)
    window = rng.uniform(0, 64, size=(300, 2, 2))
    a, _ = lines.rasterize_lines(window, 64, 64, "gl")
    b, _ = lines.rasterize_lines(window, 64, 64, "exact")
    sa = set(zip(a.tri.tolist(), a.x.tolist(), a.y.tolist()))
    sb = set(zip(b.tri.tolist(), b.x.tolist(), b.y.tolist()))
    assert len(sa ^ sb) <= 0.01 * len(sa)


def test_rasterize_lines_rejects_bad_arguments():
    with pytest.raises(ValueError):
        lines.rasterize_lines(np.zeros((1, 3, 2)), 4, 4)
    with pytest.raises(ValueError):
        lines.rasterize_lines(np.zeros((1, 2, 2)), 4, 4, "fast")
    with pytest.raises(ValueError):
        lines.rasterize_lines(np.zeros((1, 2, 2)), 4, 4, sample_positions=np.zeros((33, 2)))


# --------------------------------------------------------------------------- t, depth, attributes


def test_t_runs_along_the_major_axis_only():
    # x-major line from (0.5, 0.5) to (8.5, 3.5): t = (x + .5 - .5) / 8 in
    # every row, whatever the pixel's y.
    frags, t = lines.rasterize_lines(np.array([[[0.5, 0.5], [8.5, 3.5]]]), 10, 10)
    np.testing.assert_allclose(t, frags.x / 8.0)
    frags, t = lines.rasterize_lines(np.array([[[1.2, 0.5], [3.7, 8.5]]]), 10, 10)   # y-major
    np.testing.assert_allclose(t, frags.y / 8.0)


def test_depth_is_linear_in_t_and_per_sample():
    ends = np.array([[[0.5, 0.5, 0.0], [8.5, 0.5, 1.0]]])
    x = np.array([2, 3])
    z = lines.depth_at_samples(ends[[0, 0]], x, np.zeros(2, int), np.array([[0.5, 0.5]]))
    np.testing.assert_allclose(z[:, 0], [0.25, 0.375])
    z4 = lines.depth_at_samples(ends[[0]], np.array([2]), np.array([0]), MSAA4, "exact")
    np.testing.assert_allclose(z4[0], (2 + MSAA4[:, 0] - 0.5) / 8)     # projection of each sample


def test_interpolate_lines_is_perspective_correct():
    values = np.array([[[0.0], [1.0]]])
    t = np.array([0.5])
    np.testing.assert_allclose(lines.interpolate_lines(t, np.array([[1.0, 1.0]]), values), [[0.5]])
    # Half-way on screen between w = 1 and w = 3: q = (0.5, 0.5/3), b1 = 1/4.
    np.testing.assert_allclose(lines.interpolate_lines(t, np.array([[1.0, 1 / 3]]), values), [[0.25]])
    np.testing.assert_allclose(lines.interpolate_lines(t, np.array([[1.0, 1 / 3]]), values,
                                                       perspective=False), [[0.5]])


# --------------------------------------------------------------------------- clipping


def test_clip_line_crossing_the_right_plane_by_hand():
    clip = np.array([[0.0, 0, 0, 1], [2.0, 0, 0, 1]])
    out = lines.clip_lines(clip, [[0, 1]])
    # d1 = w - x = -1, d0 = 1: t1 = -1 / (-1 - 1) = 0.5 from v1.
    np.testing.assert_array_equal(out.clip[0], [[0, 0, 0, 1], [1, 0, 0, 1]])
    assert out.generated.tolist() == [[False, True]]
    np.testing.assert_allclose(out.weights[0], [[1, 0], [0.5, 0.5]])
    assert out.source.tolist() == [0]


def test_clip_lines_drops_what_is_outside():
    clip = np.array([[2.0, 0, 0, 1], [3.0, 0.5, 0, 1],        # both right of x = w
                     [1.5, 0.8, 0, 1], [0.8, 1.5, 0, 1],      # misses the corner: t0 + t1 > 1
                     [0.0, 0, 0, 1], [np.nan, 0, 0, 1],       # not finite
                     [0.1, 0.2, 0.3, 1], [-0.4, 0.5, -0.6, 1]])
    out = lines.clip_lines(clip, [[0, 1], [2, 3], [4, 5], [6, 7]])
    assert out.source.tolist() == [3]
    assert not out.generated.any()
    np.testing.assert_array_equal(out.clip[0], clip[6:8].astype(np.float32))   # gl: float32


def test_clip_line_through_the_near_plane():
    # v1 is behind the eye (w < 0): outside right, left, top, bottom (t = 0.5)
    # and near (z + w = -4: t = 0.8); the largest t wins.
    clip = np.array([[0.0, 0, 0, 1], [0.0, 0, -3, -1]])
    out = lines.clip_lines(clip, [[0, 1]], precision="exact")
    np.testing.assert_allclose(out.clip[0, 1], [0, 0, -0.6, 0.6])
    np.testing.assert_allclose(out.weights[0, 1], [0.8, 0.2])


def test_clip_lines_gl_precision_is_float32_and_keeps_order():
    rng = np.random.default_rng(0)
    clip = np.concatenate([rng.uniform(-2, 2, size=(40, 3)), np.ones((40, 1))], axis=1)
    out = lines.clip_lines(clip, np.arange(40).reshape(-1, 2))
    assert (np.diff(out.source) > 0).all()
    np.testing.assert_array_equal(out.clip, out.clip.astype(np.float32))
    inside = np.abs(out.clip[..., :3]) <= out.clip[..., 3:4] * (1 + 1e-6)
    assert inside.all()
    # Weights reproduce the clipped positions from the source vertices.
    src = clip[np.arange(40).reshape(-1, 2)[out.source]]
    np.testing.assert_allclose(np.einsum("lkj,ljc->lkc", out.weights, src), out.clip, atol=1e-6)


def test_guard_band_policy_does_not_clip_x_and_y():
    clip = np.array([[0.0, 0, 0, 1], [1.5, 0, 0, 1]])
    out = lines.clip_lines(clip, [[0, 1]], policy="guard_band", width=64, height=64)
    np.testing.assert_array_equal(out.clip[0], clip)


# --------------------------------------------------------------------------- one draw


def test_line_fragments_of_one_draw():
    # A horizontal line in an 8x4 viewport, red to green, from window
    # (0.5, 1.5, z 0.5) to (10, 1.5, z 0.75), clipped at x = 8.
    clip = np.array([[-0.875, -0.25, 0.0, 1.0], [1.5, -0.25, 0.5, 1.0]])
    colors = np.array([[1.0, 0, 0, 1], [0, 1.0, 0, 1]])
    lf = lines.line_fragments(clip, [[0, 1]], 8, 4, values=colors)
    frags = lf.fragments
    assert frags.x.tolist() == list(range(8)) and set(frags.y.tolist()) == {1}
    t = frags.x / 9.5                                # along the whole line, through the clipped end
    np.testing.assert_allclose(lf.values[:, 1], t, atol=1e-6)
    np.testing.assert_allclose(lf.z[:, 0], 0.5 + 0.25 * t, atol=1e-6)
    outside = lines.line_fragments(clip + [5, 0, 0, 0], [[0, 1]], 8, 4, values=colors)
    assert len(outside) == 0 and lf.values.shape[1] == 4 and outside.values.shape == (0, 4)
