"""Write the extreme conformance scenes, scenes/extreme_*.json (numerical
stability at the extremes: docs/numerics.md).

Each scene is generated here so that its numbers can be read as a formula
(sub-pixel grids, quads at exact eye distances); the JSON files are the
artefacts that tests and goldens use.  Run from the repository root:

    python3 scripts/make_extreme_scenes.py            # (re)write all of them
    python3 scripts/make_extreme_scenes.py near_far   # only extreme_near_far.json

After changing a scene, regenerate its golden image with
``softras golden --update scenes/extreme_<name>.json``.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def pixel_camera(width: int, height: int) -> dict:
    """Orthographic camera whose model units are GL window pixels (y up)."""
    return {"projection": "orthographic", "left": 0, "right": width, "bottom": 0, "top": height,
            "near": -1, "far": 1}


def quad(x0, y0, x1, y1, z=0.0) -> dict:
    """Axis-aligned rectangle as two counter-clockwise triangles (positions only)."""
    return {"positions": [[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]],
            "indices": [[0, 1, 2], [0, 2, 3]]}


# --------------------------------------------------------------------------- scenes


def near_far() -> dict:
    """Pairs of screen-parallel quads at eye distances d and d (1 + 1e-3)."""
    width, height, fov_y = 256, 96, 60.0
    aspect = width / height
    tan_half = math.tan(math.radians(fov_y) / 2)
    nodes = []
    for i, d in enumerate(NEAR_FAR_DISTANCES):
        centre = -0.8 + 0.4 * i                                      # x_ndc of the column
        k = 0.5 if d > 1000 else 1.0                                 # keep the last pair small
        for name, dist, half_x, half_y, color in (
                ("far", d * (1 + NEAR_FAR_SEPARATION), 0.05 * k, 0.2 * k, [1, 0, 0]),
                ("near", d, 0.025 * k, 0.1 * k, [0, 1, 0])):
            sx, sy = dist * tan_half * aspect, dist * tan_half         # eye units per NDC unit
            mesh = quad((centre - half_x) * sx, -half_y * sy, (centre + half_x) * sx, half_y * sy, -dist)
            mesh["colors"] = [color] * 4
            nodes.append({"name": f"{name}_{i}", "mesh": mesh})
    return {
        "softras_scene": 1,
        "description": (
            "Depth precision with near = 1e-5 and far = 1e5 (ratio 1e10). Five columns, each a red quad at "
            "eye distance d (1 + 1e-3) drawn first and a smaller green quad at d drawn second, for d = "
            + ", ".join(f"{d:g}" for d in NEAR_FAR_DISTANCES) + ". z_w = f/(f-n) (1 - n/d), so the pair is "
            "1e-8/d apart in z_w: resolved by the 24-bit depth buffer (2^-24 = 6e-8) for d = 3e-5, 1e-3 "
            "and 0.03 (green shows), z-fighting at d = 10 (both quads get the same 24-bit depth: red, drawn "
            "first, stays), and at d = 3000 both round to z_w = 1.0 and fail LESS against the cleared 1.0 "
            "(background). Exact precision (float64 depth) resolves every pair: the quads are small so that "
            "this legitimate difference stays under 2 % of the pixels."),
        "width": width, "height": height, "background": [0, 0, 0, 1],
        "camera": {"projection": "perspective", "fov_y": fov_y, "near": 1e-5, "far": 1e5},
        "nodes": nodes,
    }


NEAR_FAR_DISTANCES = (3e-5, 1e-3, 0.03, 10.0, 3000.0)
NEAR_FAR_SEPARATION = 1e-3


def eye_plane() -> dict:
    """Triangles with vertices on the eye plane (w = 0) and behind the eye."""
    tris = [
        ("floor_w0", [[-3, -1, 0], [3, -1, 0], [0, -1, -20]], [1, 0, 0]),
        ("ceiling_behind", [[-4, 0.5, 5], [4, 0.5, 5], [0.5, 0.5, -10]], [0, 1, 0]),
        ("wall_w0_vertex", [[2, 0.2, 0], [0.4, -0.3, -3], [0.6, 0.4, -2.5]], [0, 0, 1]),
        ("through_eye", [[0, 0, 0], [-2, -0.5, -6], [-2, 0.4, -6]], [1, 1, 0]),
        ("all_behind", [[-1, -1, 1], [1, -1, 1], [0, 1, 2]], [1, 0, 1]),
        ("left_w0_behind", [[-1.2, -0.6, 0], [-3, 0.3, 2], [-0.7, 0.25, -4]], [0, 1, 1]),
    ]
    nodes = [{"name": name, "mesh": {"positions": pos, "colors": [col] * 3}} for name, pos, col in tris]
    return {
        "softras_scene": 1,
        "description": (
            "Camera at the origin looking down -z (near 0.1, far 100). Triangles with vertices exactly on "
            "the eye plane z = 0 (clip w = 0: a floor, a small wall, a left wedge), vertices behind the eye "
            "(a ceiling from z = +5 to -10), one whose plane passes through the eye (seen edge-on: draws "
            "nothing) and one entirely behind (culled). All must be clipped by the near plane before the "
            "divide; tests/test_extremes.py checks coverage against ray casting."),
        "width": 128, "height": 96, "background": [0, 0, 0, 1],
        "camera": {"projection": "perspective", "fov_y": 60, "near": 0.1, "far": 100},
        "nodes": nodes,
    }


def huge_coordinates(side_wall: bool = False) -> dict:
    """``side_wall``: add a wall x = -3 with vertices 1e7 away, one on the eye
    plane.  float32 (GL and softras gl, bit for bit) places its edges up to
    ~3 px from float64's, more than tests/test_scenes.py's exact-vs-gl bar,
    so it is tested in tests/test_extremes.py instead of in the scene file."""
    big = 1e7
    tris = [
        ("floor", [[-big, -1, -1], [big, -1, -1], [0, -1, -big]], [1, 0, 0]),
        ("wall", [[0, 0.5, -5], [big, big, -5], [-big, big, -5]], [0, 1, 0]),
        ("ceiling_behind", [[-big, 4, big], [big, 4, big], [0, 4, -big]], [0, 0, 1]),
    ]
    if side_wall:
        tris.append(("side_wall", [[-3, -big, big], [-3, -big, -big], [-3, big, 0]], [1, 1, 0]))
    nodes = [{"name": name, "mesh": {"positions": pos, "colors": [col] * 3}} for name, pos, col in tris]
    return {
        "softras_scene": 1,
        "description": (
            "Coordinates up to 1e7 (exact in float32, 2^24 = 1.7e7): a floor reaching "
            "1e7 units in every direction (clipped by the side, near and far planes; far = 50), a wall "
            "with two vertices at (+-1e7, 1e7) and a ceiling whose vertices lie 1e7 behind and in front "
            "of the eye (at y = 4: it meets the walls only off screen, so no pixel depends on a depth tie, which float32 at 1e7 would decide differently from float64). Clipping happens before any fixed-point conversion, so the snapped coordinates "
            "stay inside the viewport and int64 edge functions cannot overflow."),
        "width": 128, "height": 96, "background": [0, 0, 0, 1],
        "camera": {"projection": "perspective", "fov_y": 60, "near": 0.5, "far": 50},
        "nodes": nodes,
    }


def sliver_fan() -> dict:
    return {
        "softras_scene": 1,
        "description": (
            "A full-turn fan of 2000 triangles (0.18 degrees each, 0.14 px wide at the rim), radius 45 px, "
            "centred exactly on the centre of pixel (64, 48), drawn with additive blending and no depth "
            "test in colour 0.25: a pixel covered once is 64, twice 128. Watertight means every pixel "
            "whose centre is inside the 2000-gon is 64 and none is 128, including the centre pixel where "
            "all 2000 triangles meet."),
        "width": 128, "height": 96, "background": [0, 0, 0, 1],
        "camera": pixel_camera(128, 96),
        "nodes": [{"name": "fan", "translate": [64.5, 48.5, 0],
                   "mesh": {"procedural": "fan", "count": 2000, "radius": 45},
                   "material": {"color": [0.25, 0.25, 0.25, 1]},
                   "depth_test": False, "blend": "add"}],
    }


def degenerate() -> dict:
    positions = [
        [4.5, 4.5, 0], [20.5, 20.5, 0], [36.5, 36.5, 0],          # 0-2 collinear through pixel centres
        [10, 30, 0], [50, 30, 0],                                 # 3-4
        [8.3, 40.7, 0], [40.3, 40.7, 0], [24.3, 40.7 + 1 / 1024, 0],  # 5-7 height 1/1024 px, snaps flat
        [30.5, 10.5, 0],                                          # 8
        [44.25, 8.5, 0], [60.25, 8.5, 0], [52.25, 8.5, 0],        # 9-11 horizontal on a row of centres
    ]
    indices = [[0, 1, 2], [3, 3, 4], [3, 4, 3], [8, 8, 8], [5, 6, 7], [9, 10, 11], [2, 1, 0]]
    return {
        "softras_scene": 1,
        "description": (
            "Degenerate triangles must draw nothing: three collinear vertices through pixel centres "
            "(both windings), repeated vertices (i, i, j), (i, j, i), (i, i, i), a horizontal zero-area "
            "triangle lying on a row of pixel centres, and a triangle 1/1024 px high that misses every "
            "centre (and snaps to zero area). The image is the background, exactly."),
        "width": 64, "height": 48, "background": [0.1, 0.2, 0.3, 1],
        "camera": pixel_camera(64, 48),
        "nodes": [{"name": "degenerate", "mesh": {"positions": positions, "indices": indices},
                   "material": {"color": [1, 1, 0, 1]}}],
    }


SUBPIXEL_ROWS = ("radius_0.05", "radius_0.012", "between_centres", "quad_diagonal_on_centre",
                 "fan_vertex_on_centre")


def subpixel_triangles():
    """Per row of the sub-pixel scene: (positions, indices, covered pixel centres)."""
    positions, indices, expected = [], [], []

    def add(points, tris):
        base = len(positions)
        positions.extend([[x, y, 0] for x, y in points])
        indices.extend([[base + a, base + b, base + c] for a, b, c in tris])

    for row, kind in enumerate(SUBPIXEL_ROWS):
        j = 4 + 8 * row
        for k, i in enumerate(range(4, 61, 8)):
            cx, cy = i + 0.5, j + 0.5
            spin = 0.37 * k                                         # vary the orientation
            if kind in ("radius_0.05", "radius_0.012"):
                r = 0.05 if kind == "radius_0.05" else 0.012
                add([(cx + r * math.cos(spin + a), cy + r * math.sin(spin + a))
                     for a in (0, 2 * math.pi / 3, 4 * math.pi / 3)], [(0, 1, 2)])
                expected.append((i, j))
            elif kind == "between_centres":
                ox, oy = i + 1.0, j + 1.0                           # a pixel corner
                r = 0.2
                add([(ox + r * math.cos(spin + a), oy + r * math.sin(spin + a))
                     for a in (0, 2 * math.pi / 3, 4 * math.pi / 3)], [(0, 1, 2)])
            elif kind == "quad_diagonal_on_centre":
                r = 0.05
                pts = [(cx + r * math.cos(spin + a), cy + r * math.sin(spin + a))
                       for a in (0, math.pi / 2, math.pi, 3 * math.pi / 2)]
                # Make the diagonal 0-2 pass exactly through the centre.
                pts[2] = (2 * cx - pts[0][0], 2 * cy - pts[0][1])
                add(pts, [(0, 1, 2), (0, 2, 3)])
                expected.append((i, j))
            else:
                r = 0.05
                pts = [(cx, cy)] + [(cx + r * math.cos(spin + a), cy + r * math.sin(spin + a))
                                    for a in (0, math.pi / 2, math.pi, 3 * math.pi / 2)]
                add(pts, [(0, 1, 2), (0, 2, 3), (0, 3, 4), (0, 4, 1)])
                expected.append((i, j))
    return positions, indices, expected


def subpixel() -> dict:
    positions, indices, _ = subpixel_triangles()
    return {
        "softras_scene": 1,
        "description": (
            "Sub-pixel triangles, additive colour 0.25 (a pixel covered once is 64, twice 128), one per "
            "8th pixel in five rows: circumradius 0.05 px and 0.012 px (3 subpixel units) around a pixel "
            "centre (covered once), radius 0.2 px around a pixel corner (covers nothing), two triangles of "
            "a tiny quad whose shared diagonal passes exactly through the centre, and four triangles meeting "
            "at a vertex exactly on the centre (each covered exactly once: the fill rule gives the centre "
            "to one triangle)."),
        "width": 64, "height": 48, "background": [0, 0, 0, 1],
        "camera": pixel_camera(64, 48),
        "nodes": [{"name": "tiny", "mesh": {"positions": positions, "indices": indices},
                   "material": {"color": [0.25, 0.25, 0.25, 1]}, "depth_test": False, "blend": "add"}],
    }


def texture_strip() -> dict:
    top = quad(0, 32, 128, 64)
    top["uvs"] = [[0, 1], [1, 1], [1, 0], [0, 0]]
    bottom = quad(0, 0, 128, 32)
    bottom["uvs"] = [[0.5, 0], [0.5, 1], [0.5, 1], [0.5, 0]]   # t runs along x
    strip = {"wrap_s": "clamp_to_edge", "wrap_t": "clamp_to_edge",
             "min_filter": "linear_mipmap_linear", "mag_filter": "linear"}
    return {
        "softras_scene": 1,
        "description": (
            "Textures at the largest size llvmpipe allows, 16384 x 1 and 1 x 16384 (15 mip levels), "
            "red-to-blue gradients, trilinear, clamped, each squeezed onto 128 pixels: rho = 128 texels "
            "per pixel, lambda = 7 (level 128 x 1). Top: the strip along s; bottom: the 1 x 16384 "
            "strip with t running along x. A box-filtered linear gradient stays linear, so the analytic "
            "answer is the gradient at the pixel centre."),
        "width": 128, "height": 64, "background": [0, 0, 0, 1],
        "camera": pixel_camera(128, 64),
        "textures": {
            "strip_s": {"procedural": "gradient", "size": [16384, 1], "direction": "horizontal",
                        "color0": [1, 0, 0, 1], "color1": [0, 0, 1, 1], **strip},
            "strip_t": {"procedural": "gradient", "size": [1, 16384], "direction": "vertical",
                        "color0": [1, 0, 0, 1], "color1": [0, 0, 1, 1], **strip},
        },
        "nodes": [{"name": "strip_s", "mesh": top, "material": {"texture": "strip_s"}},
                  {"name": "strip_t", "mesh": bottom, "material": {"texture": "strip_t"}}],
    }


TEXEL_1X1 = [0.2, 0.6, 0.9, 1.0]


def texture_1x1() -> dict:
    floor = quad(-50, -50, 50, 50)
    floor["positions"] = [[x, -1, -y] for x, y, _ in floor["positions"]]
    floor["indices"] = [[0, 2, 1], [0, 3, 2]]
    floor["uvs"] = [[-1000, -1000], [1000, -1000], [1000, 1000], [-1000, 1000]]
    card = {"positions": [[-0.6, 0.2, -3], [0.6, 0.2, -3], [0.6, 1.0, -3], [-0.6, 1.0, -3]],
            "indices": [[0, 1, 2], [0, 2, 3]], "uvs": [[0, 0], [0.001, 0], [0.001, 0.001], [0, 0.001]]}
    return {
        "softras_scene": 1,
        "description": (
            "A 1 x 1 texture (one mip level) under every level of detail: a floor 100 units wide with uvs "
            "from -1000 to 1000 (extreme minification towards the horizon, repeat) and a card with uvs 0 to "
            "0.001 (extreme magnification), trilinear. Every covered pixel is the texel colour, exactly."),
        "width": 128, "height": 96, "background": [0, 0, 0, 1],
        "camera": {"projection": "perspective", "fov_y": 60, "near": 0.1, "far": 200},
        "textures": {"one": {"procedural": "checker", "size": [1, 1], "squares": 1, "color0": TEXEL_1X1,
                             "min_filter": "linear_mipmap_linear", "mag_filter": "linear"},
                     "one_mirrored": {"procedural": "checker", "size": [1, 1], "squares": 1, "color0": TEXEL_1X1,
                                      "wrap_s": "mirrored_repeat", "wrap_t": "mirrored_repeat",
                                      "min_filter": "nearest_mipmap_nearest", "mag_filter": "nearest"}},
        "nodes": [{"name": "floor", "mesh": floor, "material": {"texture": "one"}},
                  {"name": "card", "mesh": card, "material": {"texture": "one_mirrored"}}],
    }


MAGNIFY = 1000.0          # pixels per texel
MAGNIFY_NEAREST_UV0 = (1.97, 2.98)      # texel coordinates at the left / bottom edge of the left quad
MAGNIFY_LINEAR_UV0 = (1.45, 0.45)


def texture_magnify() -> dict:
    size = 4
    left, right = quad(0, 0, 64, 96), quad(64, 0, 128, 96)

    def uvs(u0, v0):
        # texel coordinate u = u0 + x_local / MAGNIFY; v grows downwards in the image (v = 0 at the top row)
        du, dv = 64 / MAGNIFY, 96 / MAGNIFY
        return [[u0 / size, (v0 + dv) / size], [(u0 + du) / size, (v0 + dv) / size],
                [(u0 + du) / size, v0 / size], [u0 / size, v0 / size]]

    left["uvs"] = uvs(*MAGNIFY_NEAREST_UV0)
    right["uvs"] = uvs(*MAGNIFY_LINEAR_UV0)
    noise = {"procedural": "noise", "size": [size, size], "seed": 7, "min_filter": "linear_mipmap_linear"}
    return {
        "softras_scene": 1,
        "description": (
            "Magnification x1000: a 4 x 4 noise texture with one texel spread over 1000 x 1000 pixels. "
            "Left half: mag nearest, crossing a texel boundary at x = 30 and y = 20 px (a sharp edge). "
            "Right half: mag linear across a texel centre, a smooth bilinear ramp; llvmpipe (and softras gl) "
            "round texel coordinates to 1/256 texel, so the ramp moves in steps every ~4 px."),
        "width": 128, "height": 96, "background": [0, 0, 0, 1],
        "camera": pixel_camera(128, 96),
        "textures": {"nearest": {**noise, "mag_filter": "nearest"}, "linear": {**noise, "mag_filter": "linear"}},
        "nodes": [{"name": "nearest", "mesh": left, "material": {"texture": "nearest"}},
                  {"name": "linear", "mesh": right, "material": {"texture": "linear"}}],
    }


ALPHA_COLUMNS = (  # (alpha, blend) per 16-px column
    (0.0, "over"), (1e-9, "over"), (1e-3, "over"), (0.0019, "over"), (0.0021, "over"),
    (1e-9, "over_straight"), (0.0, "none"), (1e-9, "add"))


def alpha() -> dict:
    nodes = []
    for k, (a, blend) in enumerate(ALPHA_COLUMNS):
        mesh = quad(16 * k, 0, 16 * k + 16, 32)
        nodes.append({"name": f"alpha_{a:g}_{blend}", "mesh": mesh,
                      "material": {"color": [1, 1, 1, a]}, "blend": blend})
    return {
        "softras_scene": 1,
        "description": (
            "Alpha near 0 over a coloured background, one 16-px column each: white with alpha 0, 1e-9, "
            "1e-3, 0.0019 and 0.0021 (premultiplied 0.48 and 0.54 of a level: the two sides of rounding) "
            "blended 'over', alpha 1e-9 'over_straight', alpha 0 written with no blending (a transparent "
            "black pixel) and alpha 1e-9 'add'. Colours are premultiplied, nothing is ever divided by "
            "alpha, and no NaN may appear."),
        "width": 128, "height": 32, "background": [0.2, 0.4, 0.6, 1],
        "camera": pixel_camera(128, 32),
        "nodes": nodes,
    }


def overbright() -> dict:
    lit = quad(0, 0, 32, 48)
    lit["normals"] = [[0, 0, 1]] * 4
    lit["colors"] = [[0.5, 0.5, 0.5]] * 4
    nodes = [
        {"name": "lit_x4", "mesh": lit, "material": {"shading": "phong", "diffuse": 0.8, "specular": 0.5}},
        {"name": "add_a", "mesh": {**quad(32, 0, 64, 48), "colors": [[0.75, 0.5, 0.25]] * 4}},
        {"name": "add_b", "mesh": {**quad(32, 0, 64, 48), "colors": [[0.75, 0.75, 0.75]] * 4},
         "blend": "add", "depth_test": False},
        {"name": "sub_base", "mesh": {**quad(64, 0, 96, 48), "colors": [[0.25, 0.5, 0.75]] * 4}},
        {"name": "subtract", "mesh": {**quad(64, 0, 96, 48), "colors": [[0.5, 0.25, 1.0]] * 4},
         "blend": "subtract", "depth_test": False},
        {"name": "rsub_base", "mesh": {**quad(96, 0, 128, 48), "colors": [[0.25, 0.5, 0.75]] * 4}},
        {"name": "reverse_subtract", "mesh": {**quad(96, 0, 128, 48), "colors": [[0.5, 0.25, 1.0]] * 4},
         "blend": "reverse_subtract", "depth_test": False},
    ]
    return {
        "softras_scene": 1,
        "description": (
            "Colours outside [0, 1], clamped as GL does for an RGBA8 UNORM framebuffer: a Phong quad lit by "
            "a directional light of colour 4 (0.5 grey: ambient 0.05 + diffuse 1.6 + specular 2.0 per "
            "channel, stored as 255), 0.75 + 0.75 added (255), 0.5 - 0.25 'subtract' (src - dst: 0.25) and "
            "0.25 - 0.5 'reverse_subtract' (dst - src < 0: 0)."),
        "width": 128, "height": 48, "background": [0, 0, 0, 1],
        "camera": pixel_camera(128, 48),
        "lights": [{"type": "directional", "direction": [0, 0, -1], "color": [4, 4, 4]}],
        "nodes": nodes,
    }


def one_pixel() -> dict:
    return {
        "softras_scene": 1,
        "description": (
            "A 1 x 1 framebuffer: a triangle that covers the only pixel centre (0.5, 0.5) over one that "
            "misses it by 1/64 px; the pixel is the first triangle's colour."),
        "width": 1, "height": 1, "background": [0, 0, 0, 1],
        "camera": pixel_camera(1, 1),
        "nodes": [{"name": "covers", "mesh": {"positions": [[0.2, 0.1, 0.5], [0.9, 0.4, 0.5], [0.3, 0.95, 0.5]],
                                              "colors": [[0, 0.6, 1]] * 3}},
                  {"name": "misses", "mesh": {"positions": [[0.5 + 1 / 64, -5, 0], [6, 0.5, 0], [0.5 + 1 / 64, 6, 0]],
                                              "colors": [[1, 0, 0]] * 3}}],
    }


BUILDERS = {"near_far": near_far, "eye_plane": eye_plane, "huge_coordinates": huge_coordinates,
            "sliver_fan": sliver_fan, "degenerate": degenerate, "subpixel": subpixel,
            "texture_strip": texture_strip, "texture_1x1": texture_1x1,
            "texture_magnify": texture_magnify, "alpha": alpha, "overbright": overbright,
            "1x1": one_pixel}


def to_json(scene, indent: int = 0) -> str:
    """JSON with every list of numbers (or of such lists, if short) on one line."""
    pad, inner = "  " * indent, "  " * (indent + 1)
    if isinstance(scene, dict):
        items = [f"{inner}{json.dumps(k)}: {to_json(v, indent + 1)}" for k, v in scene.items()]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}" if items else "{}"
    if isinstance(scene, list):
        flat = json.dumps(scene)
        if all(not isinstance(v, (dict, list)) for v in scene) or len(flat) <= 100 and "{" not in flat:
            return flat
        return "[\n" + ",\n".join(inner + to_json(v, indent + 1) for v in scene) + "\n" + pad + "]"
    return json.dumps(scene)


def main(names: list[str]) -> None:
    for name in names or list(BUILDERS):
        path = SCENES / f"extreme_{name}.json"
        path.write_text(to_json(BUILDERS[name]()) + "\n")
        print(f"wrote {path}")


if __name__ == "__main__":
    main(sys.argv[1:])
