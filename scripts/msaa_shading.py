"""How often a GL runs the fragment shader in a multisampled pixel, and at what LOD.

softras shades a pixel once at any sample count (one fragment a pixel, its
colour written to every covered sample), as llvmpipe does; GL 4.6 section
14.3.1.1 asks for at least that. This script asks the GL: glref's unlit
textured shader writes, per invocation, the number of samples it covers
(``gl_SampleMaskIn``, ARB_gpu_shader5), ``dFdx(gl_FragCoord.x)`` (1 when
neighbouring invocations are a pixel apart) and the texture's computed LOD
(``textureQueryLOD``), into an rgba32f picture at every sample count the GL
draws up to 16; the resolve averages each pixel's samples, so an interior
pixel reads the samples per invocation directly.

    python scripts/msaa_shading.py [--out FILE.npz]

Prints one JSON line per scene and count: interior pixels, samples per
invocation and dFdx (5th, 50th, 95th percentiles), the median LOD.
docs/verification.md ("On a GPU") has an NVIDIA H200's answer.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import glref  # noqa: E402
import softras  # noqa: E402

SCENES = ("texture_mip_level_colors", "texture_floor_trilinear")


# Per invocation: the samples it covers / 16, dFdx(gl_FragCoord.x), the texture's LOD, 1.
PROBE = ("vec4(float(bitCount(gl_SampleMaskIn[0])) / 16.0, dFdx(gl_FragCoord.x), "
         "textureQueryLOD(u_texture, v_uv).y, 1.0)")


def measure() -> tuple[dict, dict]:
    """({scene@count: figures}, {scene@count: (H, W, 4) float32 picture})."""
    from glref.render import fragment_probe

    figures, pictures = {}, {}
    with fragment_probe(PROBE, shader="unlit.frag", when="HAS_TEXTURE",
                        extensions=("GL_ARB_gpu_shader5", "GL_ARB_texture_query_lod")):
        for name in SCENES:
            scene = softras.load_scene(REPO / "scenes" / f"{name}.json")
            scene = dataclasses.replace(scene, background=np.zeros(4))
            for count in [s for s in glref.info()["sample_counts"] if s <= 16]:
                picture = glref.render(scene, samples=count, framebuffer="rgba32f")
                inside = picture[..., 3] > 0.999           # every sample covered
                key = f"{name}@{count}"
                pictures[key] = picture
                figures[key] = {
                    "pixels": int(inside.sum()),
                    "samples_per_invocation": [float(np.percentile(picture[..., 0][inside], q)) * 16
                                               for q in (5, 50, 95)],
                    "dFdx_fragcoord": [float(np.percentile(picture[..., 1][inside], q)) for q in (5, 50, 95)],
                    "lod_median": float(np.median(picture[..., 2][inside]))}
    return figures, pictures


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", metavar="FILE", help="also save the pictures (.npz)")
    args = parser.parse_args(argv)
    print(glref.info()["GL_RENDERER"])
    figures, pictures = measure()
    for key, row in figures.items():
        print(key, json.dumps(row))
    if args.out:
        np.savez_compressed(args.out, **pictures)
    return 0


if __name__ == "__main__":
    sys.exit(main())
