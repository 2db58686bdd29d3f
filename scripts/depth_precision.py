"""Where z-fighting starts: the smallest separation two quads need to resolve.

Two screen-filling quads face the camera: a red one at eye distance d + eps
drawn first and a green one at d drawn second, depth test LESS.  The pair is
*resolved* when every pixel is green, at each of 8 distances spread over
d .. 1.01 d (so that a lucky rounding boundary between the two depths does
not count).  For each near/far pair this finds the
smallest eps/d that resolves (bisection in log eps), for

* ``softras gl``: the gl-precision pipeline (float32 vertex math, 24-bit depth);
* ``glref``: OpenGL (llvmpipe) with its default GL_DEPTH_COMPONENT24 buffer;
* ``float32``: :func:`float32_depth_resolves` -- softras's gl-precision window
  depth (float32, as the pipeline computes it) stored as a float32 depth
  buffer (GL_DEPTH_COMPONENT32F; glref cannot create one: moderngl 5 has no
  format argument for depth attachments);
* ``exact``: softras exact precision (float64 depth, no rounding);
* ``predicted 24-bit``: one depth step, eps/d = d / (n (2^24 - 1)) (f - n) / f,
  from dz_w/dd = f n / ((f - n) d^2).

Run from the repository root (about a minute)::

    python3 scripts/depth_precision.py [--distance 10] [--markdown]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import softras  # noqa: E402
from softras.pipeline import setup, vertex  # noqa: E402
from softras.scene import perspective_matrix  # noqa: E402

CONFIGS = [(1.0, 1e3), (0.1, 1e3), (0.01, 1e3), (1e-3, 1e3), (1e-4, 1e3), (1e-5, 1e3),
           (0.1, 20.0), (0.1, 1e6), (1e-5, 1e5)]


def scene(near: float, far: float, d: float, eps: float) -> dict:
    """The two-quad scene (8 x 8 pixels, fov 60)."""
    half = 2 * (d + eps)                     # wider than the view at both distances
    nodes = []
    for dist, colour in ((d + eps, [1, 0, 0]), (d, [0, 1, 0])):
        nodes.append({"mesh": {"positions": [[-half, -half, -dist], [half, -half, -dist],
                                             [half, half, -dist], [-half, half, -dist]],
                               "indices": [[0, 1, 2], [0, 2, 3]], "colors": [colour] * 4}})
    return {"softras_scene": 1, "width": 8, "height": 8,
            "camera": {"projection": "perspective", "fov_y": 60, "near": near, "far": far},
            "nodes": nodes}


def resolves_by_render(backend: str, precision: str = "gl"):
    def check(near, far, d, eps) -> bool:
        options = {"precision": precision} if backend == "soft" else {}
        image = softras.render(scene(near, far, d, eps), backend=backend, **options)
        return bool((image[..., 1] == 255).all() and (image[..., 0] == 0).all())
    return check


def float32_depth_resolves(near: float, far: float, d: float, eps: float) -> bool:
    """The gl pipeline's window depth of both quads (float32 vertex transform
    and viewport transform, as `softras.pipeline.setup.viewport_transform`) compared
    as a float32 depth buffer would store them: no 24-bit rounding."""
    projection = perspective_matrix(60.0, 1.0, near, far)
    points = np.array([[0.0, 0.0, -d], [0.0, 0.0, -(d + eps)]])
    clip = vertex.to_clip(points, projection, "gl")
    window, _ = setup.viewport_transform(clip, 8, 8, "gl")
    z_near, z_far = np.float32(window[0, 2]), np.float32(window[1, 2])
    return bool(z_near < z_far and z_near < np.float32(1.0))


def predicted_24bit(near: float, far: float, d: float) -> float:
    return d / (near * (2 ** 24 - 1)) * (far - near) / far


def everywhere(check):
    """``check`` at 8 distances over d .. 1.01 d: resolved only if resolved at all of them."""
    def check_all(near, far, d, eps) -> bool:
        return all(check(near, far, d * (1 + 0.01 * k / 7), eps) for k in range(8))
    return check_all


def smallest_separation(check, near, far, d, lo=1e-12, steps=40) -> float:
    """Smallest eps/d in [lo, hi] (log bisection) at which ``check`` resolves; inf if even hi fails."""
    hi = min(1.0, 0.5 * (far / (1.01 * d) - 1))      # keep the far quad inside the far plane
    check = everywhere(check)
    if hi <= lo or not check(near, far, d, hi * d):
        return math.inf
    if check(near, far, d, lo * d):
        return lo
    for _ in range(steps):
        mid = math.sqrt(lo * hi)
        if check(near, far, d, mid * d):
            hi = mid
        else:
            lo = mid
    return hi


def table(d: float) -> list[dict]:
    methods = {"softras gl (24-bit)": resolves_by_render("soft"),
               "glref (24-bit)": resolves_by_render("gl"),
               "float32 depth": float32_depth_resolves,
               "exact (float64)": resolves_by_render("soft", "exact")}
    rows = []
    for near, far in CONFIGS:
        if d >= far:
            continue
        row = {"near": near, "far": far, "far/near": far / near,
               "predicted 24-bit": predicted_24bit(near, far, d)}
        for name, check in methods.items():
            row[name] = smallest_separation(check, near, far, d, steps=24 if "glref" in name else 40)
        rows.append(row)
    return rows


def markdown(rows: list[dict], d: float) -> str:
    keys = ["near", "far", "far/near", "predicted 24-bit", "softras gl (24-bit)", "glref (24-bit)",
            "float32 depth", "exact (float64)"]
    out = [f"Smallest relative separation eps/d that resolves two quads at eye distance d = {d:g}:",
           "", "| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    for row in rows:
        out.append("| " + " | ".join("never" if row[k] == math.inf else "< 1e-12" if row[k] <= 1e-12
                                     else f"{row[k]:.2g}" for k in keys) + " |")
    return "\n".join(out)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--distance", type=float, default=10.0, help="eye distance d of the quads (default 10)")
    args = parser.parse_args(argv)
    print(markdown(table(args.distance), args.distance))
    return 0


if __name__ == "__main__":
    sys.exit(main())
