"""Normal, bump and displacement mapping: tangent frames (softras.scene.meshes),
perturbed normals (softras.pipeline.fragment), displacement (softras.scene.displace)."""

import numpy as np
import pytest

from softras.scene import displace, meshes
from softras.pipeline import fragment, vertex
from softras.scene.texels import mip_chain
from softras.pipeline.texture import MipTexture


def height_texture(heights: np.ndarray, wrap: str = "clamp_to_edge", min_filter: str = "linear") -> MipTexture:
    """A grey height texture (H, W) of bytes, alpha 255, as `texture.prepare` would make it."""
    texels = np.empty(heights.shape + (4,), np.uint8)
    texels[..., :3] = np.asarray(heights, np.uint8)[..., None]
    texels[..., 3] = 255
    return MipTexture("h", mip_chain(texels), wrap, wrap, min_filter, "linear", 1.0)


# --------------------------------------------------------------------------- tangents


def test_grid_tangent_is_x_and_bitangent_follows_t_downwards():
    # grid: s grows along +x, t grows DOWN (-y) and the normal is +z, so
    # T = +x and cross(N, T) = +y points against dP/dt = -y: w = -1.
    grid = meshes.grid(3, 2, size=(2, 1))
    tangents = meshes.vertex_tangents(grid.positions, grid.normals, grid.uvs, grid.indices)
    np.testing.assert_allclose(tangents[:, :3], np.tile([1.0, 0.0, 0.0], (len(tangents), 1)), atol=1e-15)
    np.testing.assert_array_equal(tangents[:, 3], -1.0)


def test_mirrored_uvs_flip_the_handedness():
    grid = meshes.grid(1, 1)
    uvs = grid.uvs.copy()
    uvs[:, 1] = 1.0 - uvs[:, 1]                      # t now grows up (+y): cross(N, T) = +y
    tangents = meshes.vertex_tangents(grid.positions, grid.normals, uvs, grid.indices)
    np.testing.assert_array_equal(tangents[:, 3], 1.0)
    uvs[:, 0] = 1.0 - uvs[:, 0]                      # s grows along -x as well
    tangents = meshes.vertex_tangents(grid.positions, grid.normals, uvs, grid.indices)
    np.testing.assert_allclose(tangents[:, :3], np.tile([-1.0, 0.0, 0.0], (4, 1)), atol=1e-15)
    np.testing.assert_array_equal(tangents[:, 3], -1.0)


def test_sphere_tangents_are_unit_perpendicular_and_follow_the_azimuth():
    segments, rings = 12, 8
    sphere = meshes.sphere(segments, rings)
    tangents = meshes.vertex_tangents(sphere.positions, sphere.normals, sphere.uvs, sphere.indices)
    np.testing.assert_allclose(np.linalg.norm(tangents[:, :3], axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(np.einsum("nk,nk->n", tangents[:, :3], sphere.normals), 0.0, atol=1e-14)
    # dP/ds of the true sphere at azimuth phi is along (cos phi, 0, -sin phi).
    phi = 2 * np.pi * (np.arange(len(tangents)) % (segments + 1)) / segments
    expected = np.stack([np.cos(phi), np.zeros_like(phi), -np.sin(phi)], axis=1)
    rows = np.arange(len(tangents)) // (segments + 1)
    equator = rows == rings // 2                      # symmetric triangles around it: exact
    np.testing.assert_allclose(tangents[equator, :3], expected[equator], atol=1e-12)
    inner = (rows >= 2) & (rows <= rings - 2)         # chords: a few degrees off near the poles
    assert np.abs(tangents[inner, :3] - expected[inner]).max() < 0.15
    np.testing.assert_array_equal(tangents[inner, 3], -1.0)   # t grows from +y down to -y


def test_uv_degenerate_vertex_gets_a_perpendicular_fallback():
    positions = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    normals = np.tile([0.0, 0.0, 1.0], (3, 1))
    uvs = np.zeros((3, 2))                           # no uv area: no dP/ds
    tangents = meshes.vertex_tangents(positions, normals, uvs, np.array([[0, 1, 2]]))
    # normal's smallest component: x (first on ties) -> normalize(cross(x, z)) = -y
    np.testing.assert_allclose(tangents, np.tile([0.0, -1.0, 0.0, 1.0], (3, 1)))


def test_world_tangents_follow_the_matrix_and_a_mirror_flips_w():
    tangents = np.array([[1.0, 0.0, 0.0, -1.0]])
    rotate = np.identity(4)
    rotate[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]      # 90 degrees about z
    np.testing.assert_allclose(vertex.world_tangents(tangents, rotate), [[0, 1, 0, -1]], atol=1e-15)
    mirror = np.diag([-1.0, 1.0, 1.0, 1.0])
    np.testing.assert_allclose(vertex.world_tangents(tangents, mirror), [[-1, 0, 0, 1]])


# --------------------------------------------------------------------------- perturbed normals

FRAME_NORMAL = np.array([[0.0, 0.0, 1.0]])
FRAME_TANGENT = np.array([[1.0, 0.0, 0.0, -1.0]])   # the grid's frame: B = -cross(N, T) = -y


@pytest.mark.parametrize("precision", ["gl", "exact"])
def test_flat_height_map_leaves_the_normal_unchanged(precision):
    tex = height_texture(np.full((16, 16), 77))
    rng = np.random.default_rng(3)
    st = rng.uniform(0, 1, (50, 2))
    d = np.full((50, 2), 1e-3)
    mapped = fragment.bump_normals(tex, st, d, d, 40.0, precision)
    np.testing.assert_array_equal(mapped, np.tile([0.0, 0.0, 1.0], (50, 1)))
    normal = np.tile([0.3, -0.2, 0.9], (50, 1))
    tangent = np.tile([0.1, 1.0, 0.0, 1.0], (50, 1))
    np.testing.assert_allclose(fragment.perturb_normals(normal, tangent, mapped),
                               normal / np.linalg.norm(normal, axis=1, keepdims=True), atol=1e-15)


@pytest.mark.parametrize("precision", ["gl", "exact"])
@pytest.mark.parametrize("axis", [0, 1])
def test_known_slope_tilts_the_normal_by_the_hand_computed_angle(precision, axis):
    # Height 4 bytes per texel along one axis: the central difference over
    # +-1 texel is 8/255, n = (-scale 4/255, 0, 1); scale = 255/4 gives 45 degrees.
    ramp = 4 * np.arange(64)
    heights = np.tile(ramp, (64, 1)) if axis == 0 else np.tile(ramp[:, None], (1, 64))
    tex = height_texture(heights)
    centres = (np.arange(5, 59) + 0.5) / 64               # texel centres away from the clamped edges
    st = np.stack([centres, np.full_like(centres, 0.5 + 0.5 / 64)], axis=1)
    if axis == 1:
        st = st[:, ::-1].copy()
    d = np.full_like(st, 0.25 / 64)                        # magnified: level 0, bilinear
    scale = 255 / 4
    mapped = fragment.bump_normals(tex, st, d, d, scale, precision)
    expected = np.zeros_like(mapped)
    expected[:, axis] = -1.0
    expected[:, 2] = 1.0
    np.testing.assert_allclose(mapped, expected, atol=1e-12)
    world = fragment.perturb_normals(np.tile(FRAME_NORMAL, (len(st), 1)), np.tile(FRAME_TANGENT, (len(st), 1)),
                                     mapped)
    # Height grows along +x (s) -> the normal leans to -x; along t, i.e. -y on
    # the grid -> it leans to +y.  45 degrees either way.
    lean = [-1 / np.sqrt(2), 0, 1 / np.sqrt(2)] if axis == 0 else [0, 1 / np.sqrt(2), 1 / np.sqrt(2)]
    np.testing.assert_allclose(world, np.tile(lean, (len(st), 1)), atol=1e-12)
    # A smaller scale: tilt = atan(scale * 4/255).
    world = fragment.perturb_normals(np.tile(FRAME_NORMAL, (len(st), 1)), np.tile(FRAME_TANGENT, (len(st), 1)),
                                     fragment.bump_normals(tex, st, d, d, 10.0, precision))
    np.testing.assert_allclose(np.degrees(np.arccos(world[:, 2])), np.degrees(np.arctan(40 / 255)), atol=1e-9)


def test_normal_map_texels_decode_as_2c_minus_1():
    texel = np.array([[128, 128, 255, 255], [255, 0, 128, 255]]) / 255.0
    np.testing.assert_allclose(fragment.normal_map_normals(texel), [[1 / 255, 1 / 255, 1], [1, -1, 1 / 255]])


def test_perturb_normals_uses_the_frame_and_the_sign_of_w():
    n = np.array([[0.0, 0.0, 2.0], [0.0, 0.0, 2.0]])
    t = np.array([[3.0, 0.0, 0.5, 0.2], [3.0, 0.0, 0.5, -0.2]])   # not unit, not perpendicular
    out = fragment.perturb_normals(n, t, np.array([[0.0, 1.0, 0.0], [0.0, 1.0, 0.0]]))
    np.testing.assert_allclose(out, [[0, 1, 0], [0, -1, 0]], atol=1e-15)     # B = +-cross(z, x) = +-y
    out = fragment.perturb_normals(n, t, np.array([[1.0, 0.0, 1.0], [1.0, 0.0, 1.0]]))
    np.testing.assert_allclose(out, np.tile([1 / np.sqrt(2), 0, 1 / np.sqrt(2)], (2, 1)), atol=1e-15)


# --------------------------------------------------------------------------- displacement


def test_vertex_heights_bilinear_in_level_0_with_the_wrap_mode():
    # Two texels 0 and 255: centres at s = 0.25, 0.75; u = 2 s - 1/2.
    heights = np.array([[0, 255]])
    uvs = np.array([[0.25, 0.5], [0.5, 0.5], [0.375, 0.5], [0.0, 0.5]])
    np.testing.assert_allclose(displace.vertex_heights(height_texture(heights, "clamp_to_edge"), uvs),
                               [0, 0.5, 0.25, 0])
    # repeat: s = 0 is halfway between texel 1 (wrapped) and texel 0.
    np.testing.assert_allclose(displace.vertex_heights(height_texture(heights, "repeat"), uvs)[3], 0.5)


def test_constant_height_moves_every_vertex_by_scale_h_along_its_normal():
    tex = height_texture(np.full((8, 8), 200), "repeat")
    h = 200 / 255
    sphere = meshes.sphere(16, 8, radius=1.5)
    normals = sphere.normals * 3.0                         # length must not matter
    moved, new_normals = displace.displace(sphere.positions, normals, sphere.uvs, sphere.indices, tex, 0.4)
    np.testing.assert_allclose(moved, sphere.positions + 0.4 * h * sphere.normals, atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(moved, axis=1), 1.5 + 0.4 * h, atol=1e-14)
    # Recomputed normals: unit, close to radial, and equal across the welded seam.
    np.testing.assert_allclose(np.linalg.norm(new_normals, axis=1), 1.0, atol=1e-14)
    assert np.einsum("nk,nk->n", new_normals, sphere.normals).min() > 0.97
    seam_start = np.arange(9) * 17
    np.testing.assert_array_equal(new_normals[seam_start], new_normals[seam_start + 16])

    grid = meshes.grid(4, 4)
    moved, new_normals = displace.displace(grid.positions, grid.normals, grid.uvs, grid.indices, tex, -2.0)
    np.testing.assert_allclose(moved[:, 2], -2.0 * h)
    np.testing.assert_array_equal(new_normals, grid.normals)


def test_displaced_ramp_tilts_the_recomputed_normals():
    # Height 0..255 linearly across 256 texels on a unit grid: z = scale * s
    # (clamped ends aside), so the inner normals are normalize(-scale, 0, 1).
    tex = height_texture(np.tile(np.arange(256), (4, 1)), "clamp_to_edge")
    grid = meshes.grid(8, 2)
    inner = (grid.uvs[:, 0] > 0.2) & (grid.uvs[:, 0] < 0.8)   # both neighbours off the clamped ends
    moved, normals = displace.displace(grid.positions, grid.normals, grid.uvs, grid.indices, tex, 0.5)
    slope = 0.5 * 256 / 255                               # d(scale h)/dx: h = (256 s - 1/2) / 255
    np.testing.assert_allclose(normals[inner], np.tile([-slope, 0, 1] / np.hypot(slope, 1), (inner.sum(), 1)),
                               atol=1e-12)


def test_bumps_procedural_heights_by_hand():
    from softras.scene.texels import procedural_texels
    texels = procedural_texels("bumps", (8, 8), {"cells": 2})
    assert texels.shape == (8, 8, 4) and (texels[..., 3] == 255).all()
    np.testing.assert_array_equal(texels[..., 0], texels[..., 1])
    # Cell 0 spans texels 0..3; texel 1 has f = (1.5/8 * 2 mod 1) - 1/2 = -0.125 on
    # both axes: radius 2 * 0.125 * sqrt(2), h = (1 + cos(pi r)) / 2.
    r = 2 * np.hypot(0.125, 0.125)
    assert texels[1, 1, 0] == round(255 * (1 + np.cos(np.pi * r)) / 2)
    # Corner texel 0: f = -0.375 -> r = 2 * 0.53 > 1 -> height 0; the pattern repeats per cell.
    assert texels[0, 0, 0] == 0
    np.testing.assert_array_equal(texels[:4, :4], texels[4:, 4:])
    np.testing.assert_array_equal(texels[:4, :4, 0], texels[:4, :4, 0].T)   # round: symmetric


def test_llvmpipe_pow_hand_values_and_error_bound():
    # log2 of a power of two is exact (mantissa 1 -> z = 0), exp2 of an
    # integer is exact (fraction 0 -> P(0) = 1): 0.5^2 = 0.25, 1^y = 1, 0^y = 0.
    out = fragment.llvmpipe_pow(np.array([0.5, 1.0, 0.0, 0.25]), 2.0)
    np.testing.assert_array_equal(out, np.array([0.25, 1.0, 0.0, 0.0625], np.float32))
    # Elsewhere a relative error of about 1.3e-7 per unit of the exponent
    # (measured 4.5e-6 at 32, 1.3e-4 at 1024) plus a few float32 ulps
    # (3.3e-7 at y = 1).
    x = np.linspace(0.05, 1.0, 20001)
    for y in (1.0, 32.0, 1024.0):
        exact = x.astype(np.float32).astype(np.float64) ** y
        normal = exact > 1e-37             # below float32's normal range exp2 flushes to 0
        relative = np.abs(fragment.llvmpipe_pow(x, y) - exact)[normal] / exact[normal]
        assert relative.max() < 2e-7 * y + 6e-7, (y, relative.max())
