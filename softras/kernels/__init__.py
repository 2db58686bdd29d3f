"""The compiled path: numba kernels that fuse the stages of `softras.pipeline`.

For the scenes they support (gl precision, RGBA8, GL's sample positions; see
`draw.unsupported`) one kernel per draw does set-up, binning, coverage,
interpolation, texturing, the depth test and blending, and gives the same
bytes as the readable stages (tests/test_fastpath.py).  Each module mirrors
the stage it speeds up and names the readable function it must equal.
"""
