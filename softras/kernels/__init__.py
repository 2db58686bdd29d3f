"""The compiled path: numba kernels that fuse the stages of `softras.pipeline`.

For the scenes they support (gl precision, RGBA8, GL's sample positions; see
`draw.unsupported`) one kernel per draw does set-up, binning, coverage,
interpolation, texturing, the depth test and blending, and gives the same
bytes as the readable stages (tests/test_fastpath.py).  Each module mirrors
the stage it speeds up and names the readable function it must equal:

- `setup`: `softras.pipeline.setup` (and the corner attributes);
- `rasterize`: binning and `softras.pipeline.rasterize`'s coverage tests;
- `interpolate`: `softras.pipeline.interpolate` and the unlit colour;
- `light`: Blinn-Phong per pixel, per vertex and per face
  (`softras.pipeline.fragment.blinn_phong`);
- `lines`: the per-fragment work of line draws (`softras.pipeline.lines`);
- `texture`: `softras.pipeline.texture.sample`;
- `ops`: `softras.pipeline.ops` (depth test, blending, the writes);
- `lanes`, `rgba8`, `scratch`: the kernels' own representations (lane rows,
  RGBA8 words in 16-bit lanes, reused buffers);
- `threads`: the tile drivers' shares on threads, and the compiler that
  gives them ``noalias``;
- `draw`: the per-draw fusion of them all, and the dispatch (`unsupported`,
  `render_samples`).

Imports only go down (tests/test_layers.py): `draw` imports the stage
modules, which import `lanes`, `rgba8` and each other without circles.
"""
