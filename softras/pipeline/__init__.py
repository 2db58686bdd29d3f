"""The readable pipeline: one module per stage, pure functions on arrays.

In data-flow order, one draw at a time:

1. `vertex`: object -> world -> eye -> clip space (the vertex shader);
2. `clip`: the six frustum planes (Sutherland-Hodgman), or a guard band;
3. `setup`: perspective division, the viewport transform, snapping to 1/256
   of a pixel, culling, edge functions and the fill rule;
4. `rasterize`: which samples each triangle covers (`lines`: the diamond-exit
   rule for line segments; `sampling`: sample patterns; `coverage`: exact
   area coverage, for measuring the patterns);
5. `interpolate`: barycentrics, perspective-correct weights, depth, screen
   derivatives;
6. `texture`: LOD, wrap, filters and mipmaps as GL does them
   (`texture_beyond`: ripmap and EWA, softras's own; `texture_bounds`: the
   range of results a conformant GL may return, for the verifier);
7. `fragment`: Blinn-Phong shading, normal and bump maps, the texture
   combine;
8. `ops`: depth test, blending, the framebuffer and the MSAA resolve.

`render` wires them together (`render_stages`).  The compiled path in
`softras.kernels` must give the same bytes; `softras.renderer` chooses.
"""

from softras.pipeline import numba_fixes

# Before any stage or kernel compiles: numba's compile, faster (the same code).
numba_fixes.install()
