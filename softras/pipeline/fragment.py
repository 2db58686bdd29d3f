"""Fragment stage: colour of each fragment.

Colours are linear RGBA in [0, 1].  A fragment's colour is
vertex colour x material colour, output premultiplied (rgb * a, a), which is
what the per-sample operations and the framebuffer hold (docs/design.md section 4).
"""

from __future__ import annotations

import numpy as np

from softras.pipeline import libm


def premultiply(rgba: np.ndarray) -> np.ndarray:
    """Straight (..., 4) RGBA -> premultiplied (rgb * a, a)."""
    out = rgba.copy()
    out[..., :3] *= rgba[..., 3:4]
    return out


def shade_unlit(vertex_color: np.ndarray, material_color: np.ndarray,
                texel: np.ndarray | None = None) -> np.ndarray:
    """Unlit shading: (F, 4) interpolated straight vertex colours, (4,) material
    colour, optional (F, 4) premultiplied texels -> (F, 4) premultiplied
    fragment colours: premultiply(vertex x material) x texel (the product of
    two premultiplied colours is the premultiplied product of the straight ones)."""
    rgba = premultiply(vertex_color * material_color)
    if texel is not None:
        rgba = rgba * texel
    return rgba


def alpha_test(alpha: np.ndarray, cutoff: float, precision: str = "gl") -> np.ndarray:
    """The alpha test of a material with ``alpha_cutoff`` (glTF's alphaMode
    MASK): (F,) final fragment alphas (premultiplied colour's alpha: vertex x
    material x texel, after lighting) -> (F,) bool, True where the fragment
    is kept, ``alpha >= cutoff`` (glTF 2.0 section 3.9.4: alpha below the
    cutoff is fully transparent).

    GL does this in the fragment shader (``if (f_color.a < u_alpha_cutoff)
    discard;``, glref's shaders), once per fragment -- also with MSAA, where
    the shader runs once per pixel and a discard drops every covered sample
    -- so the test acts on whole fragments, before the depth test and
    blending.  In gl precision both sides are rounded to float32 first, as
    the shader compares them.
    """
    if precision == "gl":
        return ~(np.asarray(alpha).astype(np.float32) < np.float32(cutoff))
    return ~(np.asarray(alpha, np.float64) < cutoff)


def _normalize(v: np.ndarray) -> np.ndarray:
    """(..., 3) vectors over their lengths ``sqrt((x^2 + y^2) + z^2)`` (numpy's
    norm sums the squares left to right; the compiled path's
    `softras.kernels.light._unit` does the same)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products of (N, 3) vectors, summed left to right:
    ``(a0 b0 + a1 b1) + a2 b2``.  (Written out, not ``einsum``: numpy's
    einsum sums three products in an order of its own, (p0 + p2) + p1 in
    numpy 2.4, which the compiled path would have to follow version by
    version.)"""
    return (a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]) + a[:, 2] * b[:, 2]


def light_vectors(lights) -> np.ndarray:
    """(L, 4) light vectors: (position, 1) for point lights, (-direction, 0) for
    directional ones, so that ``L = normalize(xyz - P * w)`` either way."""
    out = np.zeros((len(lights), 4))
    for i, light in enumerate(lights):
        if light.type == "point":
            out[i] = (*light.position, 1.0)
        else:
            out[i] = (*(-np.asarray(light.direction, np.float64)), 0.0)
    return out


def blinn_phong(base_rgb: np.ndarray, position: np.ndarray, normal: np.ndarray,
                eye: np.ndarray, lights, material) -> np.ndarray:
    """Blinn-Phong in world space (the same formula as glref's lighting.glsl).

    base_rgb : (N, 3) straight vertex colour x material colour.
    position : (N, 3) world positions; normal : (N, 3) unit world normals.
    eye : (3,) camera position.  lights : scene lights; material : Material.

    ``ambient * base + sum_lights [N.L > 0] light_colour * (diffuse (N.L) base
    + specular max(N.H, 0)^shininess)`` with ``L`` towards the light,
    ``V = normalize(eye - P)``, ``H = normalize(L + V)``.  No attenuation, no
    clamping (the framebuffer clamps).  Returns (N, 3).
    """
    view = _normalize(eye[None, :] - position)
    out = material.ambient * base_rgb
    for vector, light in zip(light_vectors(lights), lights):
        to_light = _normalize(vector[None, :3] - position * vector[3])
        n_dot_l = _dot(normal, to_light)
        half = _normalize(to_light + view)
        n_dot_h = np.maximum(_dot(normal, half), 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            spec = libm.power(n_dot_h, material.shininess)
        term = np.asarray(light.color)[None, :] * (material.diffuse * n_dot_l[:, None] * base_rgb
                                                    + material.specular * spec[:, None])
        out = out + np.where((n_dot_l > 0)[:, None], term, 0.0)
    return out


def face_normals(world_positions: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(T, 3) unit face normals ``normalize(cross(p1 - p0, p2 - p0))`` of
    triangles (T, 3) vertex indices into world positions (N, 3)."""
    p0, p1, p2 = (world_positions[triangles[:, k]] for k in range(3))
    return _normalize(np.cross(p1 - p0, p2 - p0))


# ----------------------------------------------------------------------------- normal and bump mapping
#
# Per fragment (Phong frequency only: a mapped normal needs a normal per
# fragment to perturb), in WORLD space, the same steps as glref's lit.frag:
#
#   N = normalize(interpolated normal)
#   T = normalize(t - N (N.t))            t: interpolated world tangent (xyz)
#   B = sign(w) cross(N, T)               w: interpolated handedness
#   n = tangent-space normal (normal map texel, or from a height map)
#   N' = normalize(n.x T + n.y B + n.z N)
#
# Tangent space: T follows increasing s, B increasing t (DOWN the image,
# since t = 0 is the top row): a normal map authored with green pointing down
# the image ("DirectX", "Y-") reads directly; one with green up ("OpenGL",
# "Y+") needs its green channel inverted.


def normal_map_normals(texel: np.ndarray) -> np.ndarray:
    """Tangent-space normals from normal-map texels: (F, 4) premultiplied RGBA
    in [0, 1] (alpha should be 1) -> (F, 3) ``2 rgb - 1`` (not normalised;
    :func:`perturb_normals` normalises).  A byte 128 decodes to 1/255, not 0."""
    return 2.0 * texel[:, :3] - 1.0


def bump_normals(height_texture, st: np.ndarray, ddx: np.ndarray, ddy: np.ndarray, scale: float,
                 precision: str = "gl", fixed_point: bool = True) -> np.ndarray:
    """Tangent-space normals from a height texture by central differences.

    The height h is the red channel of the texture sampled with its own
    filters (`softras.pipeline.texture.sample`, the uv's derivatives ``ddx``, ``ddy``
    for all four samples) one level-0 texel either side of the fragment's
    (s, t) = ``st`` (F, 2)::

        dh_s = h(s + 1/W, t) - h(s - 1/W, t),   dh_t = h(s, t + 1/H) - h(s, t - 1/H)
        n = (-scale dh_s / 2, -scale dh_t / 2, 1)

    i.e. the surface displaced by ``scale * h`` in units where one texel is
    one unit long: the usual height-to-normal-map conversion, ``scale`` its
    strength (0 leaves the normal alone; a slope of one byte per texel with
    scale 255 tilts it by 45 degrees).  In gl precision the offsets are added
    in float32, as glref's shader does.  Returns (F, 3), not normalised.
    """
    from softras.pipeline import texture as texture_stage
    width, height = height_texture.size
    st = np.asarray(st, np.float64)
    if precision == "gl":
        st32 = st.astype(np.float32)
        step = np.array([1.0 / width, 1.0 / height], np.float32)

        def shifted(axis, sign):
            out = st32.copy()
            out[:, axis] = st32[:, axis] + np.float32(sign) * step[axis]
            return out.astype(np.float64)
    else:
        step = np.array([1.0 / width, 1.0 / height])

        def shifted(axis, sign):
            out = st.copy()
            out[:, axis] += sign * step[axis]
            return out

    def height_at(coords):
        return texture_stage.sample(height_texture, coords, ddx, ddy, precision, fixed_point)[:, 0]

    dh_s = height_at(shifted(0, 1)) - height_at(shifted(0, -1))
    dh_t = height_at(shifted(1, 1)) - height_at(shifted(1, -1))
    return np.stack([-scale * dh_s * 0.5, -scale * dh_t * 0.5, np.ones_like(dh_s)], axis=1)


def perturb_normals(normal: np.ndarray, tangent: np.ndarray, tangent_normal: np.ndarray) -> np.ndarray:
    """Tangent-space normals to world space.

    normal : (F, 3) world normals (any length); tangent : (F, 4) world
    tangent xyz and handedness w (interpolated, any length; only the sign of
    w is used); tangent_normal : (F, 3) (x along T, y along B, z along N).
    Returns (F, 3) unit world normals ``normalize(x T + y B + z N)`` with the
    frame built as in the comment above.
    """
    n = _normalize(normal)
    t = tangent[:, :3]
    t = _normalize(t - n * _dot(n, t)[:, None])
    b = np.where(tangent[:, 3:4] < 0, -1.0, 1.0) * np.cross(n, t)
    x, y, z = (tangent_normal[:, k:k + 1] for k in range(3))
    return _normalize(x * t + y * b + z * n)


# ----------------------------------------------------------------------------- llvmpipe's pow (for measurement)

# gallivm lp_bld_arit.c (Mesa 22.3): LOG_POLY_DEGREE 4, EXP_POLY_DEGREE 5.
_LLVMPIPE_LOG2_POLY = (2.88539009343309178325, 0.961791550404184197881, 0.577440339438736392009,
                       0.403343858251329912514, 0.406718052498846252698)
_LLVMPIPE_EXP2_POLY = (1.0, 0.693153073200168932794, 0.240153617044375388211,
                       0.0558263180532956664775, 0.00898934009049466391101, 0.00187757667519147912699)


def _llvmpipe_polynomial(x: np.ndarray, coefficients) -> np.ndarray:
    """lp_build_polynomial in float32: even and odd terms by Horner in x^2,
    ``odd * x + even`` (multiply-adds emulated unfused)."""
    x2 = x * x
    even = odd = None
    for i in range(len(coefficients) - 1, -1, -1):
        c = np.float32(coefficients[i])
        if i % 2 == 0:
            even = c if even is None else x2 * even + c
        else:
            odd = c if odd is None else x2 * odd + c
    return odd * x + even


def llvmpipe_pow(x: np.ndarray, y: float) -> np.ndarray:
    """GLSL ``pow(x, y)`` as llvmpipe computes it (lp_build_pow): float32
    ``exp2(y * log2(x))``, 0 where x == 0.

    log2: exponent bits + ``z P(z^2)`` with z = (m - 1) / (m + 1) for the
    mantissa m in [1, 2).  exp2: x clamped to [-126.99999, 128],
    ``2^floor(x)`` in the exponent bits times a polynomial of the fraction.
    (N,) float in, (N,) float32 out.  softras's pipeline uses a float64 pow (`libm.power`);
    this emulation exists to measure what the approximation costs
    (docs/textures_and_lighting.md, "llvmpipe's pow").
    """
    x = np.asarray(x, np.float32)
    bits = x.view(np.int32)
    exponent = (((bits & 0x7F800000) >> 23) - 127).astype(np.float32)
    mantissa = ((bits & 0x007FFFFF) | np.float32(1).view(np.int32)).view(np.float32)
    z = (mantissa - np.float32(1)) / (mantissa + np.float32(1))
    log2 = z * _llvmpipe_polynomial(z * z, _LLVMPIPE_LOG2_POLY) + exponent
    t = np.clip(log2 * np.float32(y), np.float32(-126.99999), np.float32(128))
    whole = np.floor(t)
    scale = ((whole.astype(np.int32) + 127) << 23).view(np.float32)
    result = scale * _llvmpipe_polynomial(t - whole, _LLVMPIPE_EXP2_POLY)
    return np.where(x == 0, np.float32(0), result).astype(np.float32)
