"""The level of detail a GL computes for a texture lookup, against softras's lambda range.

GL 4.6 core section 8.14.1 lets an implementation replace the scale factor
rho = max(|d(u,v)/dx|, |d(u,v)/dy|) by any f with ``max(m_u, m_v) <= f <=
m_u + m_v``; `softras.pipeline.texture_bounds.lambda_range` turns that, the
derivative candidates (coarse or fine quad differences, the analytic
derivative) and the LOD precision into a range [lam_lo, lam_hi] per fragment,
which the spec profile's texture bounds are built on.

This script asks a GL which lambda it computed: the fragment shader of the
bump-mapped draws writes ``textureQueryLOD(u_bump_map, v_uv)``
(ARB_texture_query_lod; its y: the computed, unclamped lambda) into an
rgba32f picture. Per pixel it tells whether that lambda lies in softras's
range, and compares it with one more figure: log2 of the footprint's major
axis, the largest singular value sigma1 of the Jacobian d(u, v)/d(x, y)
(what elliptical filters use). sigma1 is not bounded by m_u + m_v: where the
two derivative vectors are parallel (at a silhouette, say) it is up to
sqrt(2) larger, 0.5 in log2.

    python scripts/lod_query.py                      # this machine's GL, judged here
    python scripts/lod_query.py --draw FILE.npz      # only draw (on a GPU machine, say)
    python scripts/lod_query.py --judge FILE.npz     # judge a drawing made elsewhere

The drawing holds one (H, W) float32 lambda per scene (NaN where the scene
has no fragment), row 0 = top. tests/recorded/nvidia_h200/lod.npz is an
NVIDIA H200's (docs/verification.md, "On a GPU"); tests/test_lod_query.py
judges it and this machine's llvmpipe.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import softras  # noqa: E402
from softras import bench  # noqa: E402
from softras.pipeline import texture_bounds  # noqa: E402
from softras.pipeline.render import render_stages  # noqa: E402

def scenes() -> dict:
    """The bump-mapped scenes: {name: Scene} (the bench's 8k-triangle sphere, scenes/bump_mapped_plane)."""
    found = {s.name: softras.load_scene(s.scene) for s in bench.scenes(full=True) if s.name == "bump_mapped_8k_512"}
    found["bump_mapped_plane"] = softras.load_scene(REPO / "scenes" / "bump_mapped_plane.json")
    return found


def draw(scenes_by_name: dict) -> dict:
    """{name: (H, W) float32 lambda} from this process's GL: glref's Phong
    shader writes the bump map's LOD query (`glref.render.fragment_probe`;
    background NaN)."""
    import dataclasses

    import glref
    from glref.render import fragment_probe

    out = {}
    with fragment_probe("vec4(textureQueryLOD(u_bump_map, v_uv), 0.0, 1.0)", shader="lit.frag", when="BUMP_MAP",
                        extensions=("GL_ARB_texture_query_lod",)):
        for name, scene in scenes_by_name.items():
            picture = glref.render(dataclasses.replace(scene, background=np.zeros(4)), samples=1,
                                   framebuffer="rgba32f")
            out[name] = np.where(picture[..., 3] > 0, picture[..., 1], np.nan).astype(np.float32)
    return out


@dataclass
class Ranges:
    """Per pixel of one scene's bump-mapped fragments (one fragment a pixel):
    lo, hi: softras's lambda range; sigma1_lo, sigma1_hi: log2 of the
    footprint's major axis over the derivative candidates; covered: (H, W) bool."""

    lo: np.ndarray
    hi: np.ndarray
    sigma1_lo: np.ndarray
    sigma1_hi: np.ndarray
    covered: np.ndarray


def ranges(scene) -> Ranges:
    """softras's lambda range per pixel for the scene's normal / bump map: the
    stage render with ``texture_bounds="lo"`` hands the map's derivative
    candidates (`texture_bounds.fragment_derivatives`, with the fragments'
    pixels) to `texture_bounds.variant_derivatives`; they are caught there.
    A pixel with two such fragments raises: the comparison needs one."""
    caught, maps = [], []
    original_fd, original_vd = texture_bounds.fragment_derivatives, texture_bounds.variant_derivatives

    def fragment_derivatives(vertices, inv_w, x, y, *args, **kwargs):
        candidates = original_fd(vertices, inv_w, x, y, *args, **kwargs)
        caught.append((x.copy(), y.copy(), candidates))
        return candidates

    def variant_derivatives(tex, candidates, where, precision="exact", lod=texture_bounds.LOD):
        x, y, _ = next(item for item in caught if item[2] is candidates)
        maps.append((x, y, candidates, tex.size))
        return original_vd(tex, candidates, where, precision, lod)

    texture_bounds.fragment_derivatives, texture_bounds.variant_derivatives = fragment_derivatives, variant_derivatives
    try:
        render_stages(scene, precision="gl", samples=1, texture_bounds="lo")
    finally:
        texture_bounds.fragment_derivatives, texture_bounds.variant_derivatives = original_fd, original_vd
    shape = (scene.height, scene.width)
    lo, hi, s_lo, s_hi = (np.full(shape, np.nan) for _ in range(4))
    count = np.zeros(shape, int)
    for x, y, candidates, size in maps:
        row = scene.height - 1 - y                      # window y up -> picture row
        lam_lo, lam_hi = texture_bounds.lambda_range(candidates, size)
        jacobian = np.stack([candidates.ddx, candidates.ddy], axis=3) * np.array(size, float)[:, None]
        sigma1 = np.log2(np.linalg.svd(jacobian, compute_uv=False)[..., 0])      # (K, F)
        lo[row, x], hi[row, x] = lam_lo, lam_hi
        s_lo[row, x], s_hi[row, x] = sigma1.min(axis=0), sigma1.max(axis=0)
        np.add.at(count, (row, x), 1)
    if count.max() > 1:
        raise ValueError("a pixel with two bump-mapped fragments: the per-pixel comparison needs one")
    return Ranges(lo, hi, s_lo, s_hi, count == 1)


def judge(lam: np.ndarray, r: Ranges) -> dict:
    """Figures for one scene: pixels compared (covered by both), below /
    above softras's range (which holds lambda's precision already) and the
    worst excesses, and of those above how many have a major axis sigma1 above
    the range too; plus lambda - log2 sigma1 (nearest candidate) percentiles."""
    both = r.covered & np.isfinite(lam)
    lam64 = lam.astype(np.float64)
    below = both & (lam64 < r.lo)
    above = both & (lam64 > r.hi)
    sigma1_above = above & (r.sigma1_hi > r.hi)
    off_sigma1 = np.where(lam64 < r.sigma1_lo, lam64 - r.sigma1_lo,
                          np.where(lam64 > r.sigma1_hi, lam64 - r.sigma1_hi, 0.0))[both]
    return {"pixels": int(both.sum()), "below": int(below.sum()), "above": int(above.sum()),
            "worst_below": float(np.max((r.lo - lam64)[below], initial=0.0)),
            "worst_above": float(np.max((lam64 - r.hi)[above], initial=0.0)),
            "above_where_sigma1_above": int(sigma1_above.sum()),
            "sigma1_offset_p1_p50_p99": [float(v) for v in np.percentile(off_sigma1, [1, 50, 99])]}


def report(drawing: dict, label: str, scenes_by_name: dict) -> list[dict]:
    rows = []
    for name, scene in scenes_by_name.items():
        row = judge(drawing[name], ranges(scene))
        rows.append({"scene": name, **row})
        print(f"| {label} | {name} | {row['pixels']} | {row['below']} ({row['worst_below']:.3f}) | "
              f"{row['above']} ({row['worst_above']:.3f}) | {row['above_where_sigma1_above']} | "
              f"{', '.join(f'{v:+.3f}' for v in row['sigma1_offset_p1_p50_p99'])} |")
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--draw", metavar="FILE", help="only draw this machine's GL lambdas into FILE (.npz)")
    parser.add_argument("--judge", metavar="FILE", help="judge a drawing made elsewhere")
    args = parser.parse_args(argv)
    scenes_by_name = scenes()
    if args.draw:
        np.savez_compressed(args.draw, **draw(scenes_by_name))
        return 0
    if args.judge:
        with np.load(args.judge) as data:
            drawing, label = {k: data[k] for k in data.files}, args.judge
    else:
        import glref
        drawing, label = draw(scenes_by_name), glref.info()["GL_RENDERER"].split("(")[0].strip()
    print("| GL | scene | pixels | below the range (worst) | above it (worst) | above, sigma1 above too | "
          "lambda - log2 sigma1: 1 %, median, 99 % |")
    print("|---|---|---|---|---|---|---|")
    report(drawing, label, scenes_by_name)
    return 0


if __name__ == "__main__":
    sys.exit(main())
