"""The compiled path's row runs (`softras.kernels.rasterize._row_run`): at one
sample a pixel an untextured tile lists each row's covered pixels from three
integer divisions instead of testing every pixel (`_list_row`), and a
textured tile masks a partly covered block's quads with them
(`_list_quads`).  The pixels must be exactly those of the per-sample test
(`_inside3`, the test of
`softras.pipeline.rasterize._raster_triangle`), samples on an edge included:
a division rounded the wrong way loses or gains only such pixels, which the
scenes rarely have, so here they are made on purpose."""

from __future__ import annotations

import numpy as np
import pytest

from softras.kernels.lanes import _LF_CX, _LF_CY, _LI_COV, _LI_PX, _LI_PY, _LI_Z, _NLF, LANES
from softras.kernels.rasterize import Edge, Edges, _list_quads, _list_row


def _covered(edges, offsets, x0, x1, py):
    """The pixels x0..x1 of row py whose sample is inside all three edges,
    tested one by one (E - bias >= 0, as `_edge_at` and `_inside3`)."""
    sy = py * 256 + int(offsets[0, 1])
    out = []
    for px in range(x0, x1 + 1):
        sx = px * 256 + int(offsets[0, 0])
        if all(e.a * (sx - e.x0) + e.b * (sy - e.y0) - e.bias >= 0 for e in edges):
            out.append(px)
    return out


def _listed(edges, offsets, x0, x1, py, n=0):
    """`_list_row`'s lanes from lane n on: their pixels, after checking the
    row and mask of each."""
    li = np.full((_LI_Z + 1, 2 * LANES), -7, np.int64)
    end = _list_row(n, x0, x1, py, edges, offsets, li)
    assert (li[:, :n] == -7).all()                  # lanes before n untouched
    assert (li[_LI_PY, n:end] == py).all() and (li[_LI_COV, n:end] == 1).all()
    return li[_LI_PX, n:end].tolist()


def _quads(edges, offsets, bx, bx1, by, by1):
    """The quads `_list_quads` should list for pixels bx..bx1 x by..by1 of a
    block: every 2x2 quad (from even pixels) with a covered pixel, its four
    lanes' (px, py, mask), a pixel outside the block's part masked 0."""
    out = []
    for qy in range(by & -2, by1 + 1, 2):
        for qx in range(bx & -2, bx1 + 1, 2):
            lanes = []
            for k in range(4):
                px, py = qx + (k & 1), qy + (k >> 1)
                inside = bx <= px <= bx1 and by <= py <= by1 and px in _covered(edges, offsets, px, px, py)
                lanes.append((px, py, int(inside)))
            if any(mask for _, _, mask in lanes):
                out.extend(lanes)
    return out


def _edge_through(rng, sx, sy, target):
    """A random edge whose E - bias is exactly ``target`` at sample (sx, sy):
    b = +-1 and y0 solved for it; a often small (a zero step, or +-256 a
    pixel: the run's end then falls on a sample of the row)."""
    a = int(rng.choice([0, 1, -1, 2, -3])) if rng.random() < 0.5 else int(rng.integers(-3000, 3001))
    b, bias, x0 = int(rng.choice([-1, 1])), int(rng.integers(0, 2)), int(rng.integers(-20000, 60000))
    y0 = sy - b * (target + bias - a * (sx - x0))          # b (sy - y0) = target + bias - a (sx - x0)
    return Edge(a, b, x0, y0, bias)


@pytest.mark.parametrize("seed", range(6))
def test_a_row_run_is_the_per_sample_test(seed):
    rng = np.random.default_rng(seed)
    checked = on_edge = 0
    for _ in range(400):
        offsets = rng.integers(0, 256, size=(1, 2)).astype(np.int64)
        x0 = int(rng.integers(-40, 200))
        x1 = x0 + int(rng.integers(-2, 64))               # (empty rows too)
        py = int(rng.integers(-40, 200))
        sy = py * 256 + int(offsets[0, 1])
        picked = [int(rng.integers(x0 - 3, x1 + 4)) * 256 + int(offsets[0, 0]) for _ in range(3)]
        edges = []
        for k in range(3):
            if rng.random() < 0.6:      # through a sample: E - bias of -1, 0 or 1 there
                edges.append(_edge_through(rng, picked[k], sy, int(rng.integers(-1, 2))))
            else:
                edges.append(Edge(int(rng.integers(-3000, 3001)), int(rng.integers(-3000, 3001)),
                                  int(rng.integers(-20000, 60000)), int(rng.integers(-20000, 60000)),
                                  int(rng.integers(0, 2))))
        edges = Edges(*edges)
        want = _covered(edges, offsets, x0, x1, py)
        assert _listed(edges, offsets, x0, x1, py, n=int(rng.integers(0, LANES))) == want, (edges, x0, x1, py)
        checked += 1
        on_edge += any(e.a * (px * 256 + int(offsets[0, 0]) - e.x0) + e.b * (sy - e.y0) - e.bias == 0
                       for e in edges for px in range(x0, x1 + 1))
    assert checked == 400 and on_edge > 100       # the runs' ends on a sample, often


@pytest.mark.parametrize("seed", range(3))
def test_a_blocks_quads_at_one_sample_are_the_per_sample_test(seed):
    rng = np.random.default_rng(100 + seed)
    for _ in range(300):
        offsets = rng.integers(0, 256, size=(1, 2)).astype(np.int64)
        bx, by = 2 * int(rng.integers(-20, 100)), 2 * int(rng.integers(-20, 100))
        bx0, by0 = bx + int(rng.integers(0, 2)), by + int(rng.integers(0, 2))     # (a box edge inside the block)
        bx1, by1 = bx + int(rng.integers(0, 8)), by + int(rng.integers(0, 8))
        bx0, by0 = min(bx0, bx1), min(by0, by1)
        sy = by0 * 256 + int(offsets[0, 1])
        edges = Edges(*(_edge_through(rng, int(rng.integers(bx0 - 2, bx1 + 3)) * 256 + int(offsets[0, 0]),
                                      sy + 256 * int(rng.integers(0, by1 - by0 + 1)), int(rng.integers(-1, 2)))
                        for _ in range(3)))
        lf, li = np.full((_NLF, 2 * LANES), -7.0), np.full((_LI_Z + 1, 2 * LANES), -7, np.int64)
        start = 4 * int(rng.integers(0, LANES // 4))        # (appended after earlier blocks' quads)
        n = _list_quads(start, bx0, bx1, by0, by1, False, edges, offsets, 1, lf, li, 1)
        assert (li[:, :start] == -7).all() and (lf[:, :start] == -7).all()
        got = list(zip(li[_LI_PX, start:n].tolist(), li[_LI_PY, start:n].tolist(), li[_LI_COV, start:n].tolist()))
        assert got == _quads(edges, offsets, bx0, bx1, by0, by1), (edges, bx0, bx1, by0, by1)
        assert (lf[_LF_CX, start:n] == li[_LI_PX, start:n] + 0.5).all()
        assert (lf[_LF_CY, start:n] == li[_LI_PY, start:n] + 0.5).all()


def test_a_right_edge_through_a_sample_keeps_or_drops_it_by_its_bias():
    """A vertical edge x = 10.5 px bounding from the right (a < 0) through
    the samples of column 10: inclusive (bias 0) keeps column 10, exclusive
    (bias 1) drops it; a left edge (a > 0) the same way for its first column."""
    offsets = np.array([[128, 128]], np.int64)
    far_left, far_right = Edge(1, 0, -10_000, 0, 0), Edge(-1, 0, 10_000, 0, 0)
    right = lambda bias: Edge(-1, 0, 10 * 256 + 128, 0, bias)  # noqa: E731
    left = lambda bias: Edge(1, 0, 3 * 256 + 128, 0, bias)     # noqa: E731
    above = Edge(0, 1, 0, -10_000, 0)
    assert _listed(Edges(far_left, right(0), above), offsets, 0, 20, 5) == list(range(0, 11))
    assert _listed(Edges(far_left, right(1), above), offsets, 0, 20, 5) == list(range(0, 10))
    assert _listed(Edges(left(0), far_right, above), offsets, 0, 20, 5) == list(range(3, 21))
    assert _listed(Edges(left(1), far_right, above), offsets, 0, 20, 5) == list(range(4, 21))
    # A horizontal edge through the row's samples: inclusive keeps the row, exclusive drops it.
    for bias, want in ((0, list(range(0, 21))), (1, [])):
        assert _listed(Edges(far_left, far_right, Edge(0, 1, 0, 5 * 256 + 128, bias)), offsets, 0, 20, 5) == want
