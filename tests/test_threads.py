"""The tile drivers' shares on threads (softras.kernels.threads): every share
runs once, an error reaches the caller after every share has ended, a
draw cut into shares gives the bytes of the same draw in one share, a
scene drawn in batches of draws the stages' bytes, and a share's lanes
may hold anything when a draw begins."""

from __future__ import annotations

import functools
import os
import threading
import time

import numpy as np
import pytest

import softras
from conftest import SCENES
from softras.kernels import draw, pool, threads


def test_every_share_runs_once_and_share_zero_on_the_calling_thread():
    seen, lock = [], threading.Lock()

    def share(r):
        with lock:
            seen.append((r, threading.get_ident()))

    pool.on_threads(share, 3)
    assert sorted(r for r, _ in seen) == [0, 1, 2]
    assert dict(seen)[0] == threading.get_ident()
    seen.clear()
    pool.on_threads(share, 1)
    assert seen == [(0, threading.get_ident())]


def test_an_error_reaches_the_caller_after_every_share_has_ended():
    ended = []

    def share(r):
        if r == 1:
            raise ValueError("share 1 failed")
        time.sleep(0.05)
        ended.append(r)

    with pytest.raises(ValueError, match="share 1 failed"):
        pool.on_threads(share, 3)
    assert sorted(ended) == [0, 2]


def test_the_pool_threads_run_off_the_calling_threads_cpu():
    """A share handed over must not be queued behind the caller's own
    (softras.kernels.pool): the pool's thread may run on every CPU this
    process may use but the one its caller was on (on all of them where
    there is one).  Tried a few times: the caller may move to another CPU
    between the hand-off and its share, and a new pool's thread is pinned
    from its second hand-off on."""
    allowed = os.sched_getaffinity(0)
    for attempt in range(6):
        seen = {}

        def share(r):
            seen[r] = pool._sched_getcpu() if r == 0 else os.sched_getaffinity(0)

        pool.on_threads(share, 2)
        expected = (allowed - {seen[0]}) or allowed
        if seen[1] == expected:
            break
    assert seen[1] == expected


@pytest.mark.parametrize("samples, pattern", [(1, "gl"), (4, "gl"), (8, "halton")])
def test_a_draw_in_shares_gives_the_bytes_of_one_share(samples, pattern, monkeypatch):
    """Blended layers without a depth test (a tile drawn twice would blend
    twice), textured and lit, at each tile driver's sample count: two and
    three shares against one."""
    scene = softras.load_scene(draw_scene())
    monkeypatch.setattr(draw, "shares", lambda batch, n_threads, extra=0.0: 1)
    one = softras.render(scene, samples=samples, pattern=pattern)
    monkeypatch.setattr(draw, "shares", lambda batch, n_threads, extra=0.0: n_threads)
    for n in (2, 3):
        monkeypatch.setattr(draw.numba, "get_num_threads", lambda n=n: n)
        assert np.array_equal(softras.render(scene, samples=samples, pattern=pattern), one), f"{n} shares"


@pytest.mark.parametrize("samples, pattern", [(1, "gl"), (4, "gl"), (8, "halton")])
def test_one_draw_with_its_tiles_taken_as_shares_ask_gives_the_bytes_of_one_share(samples, pattern, monkeypatch):
    """The shares take a batch's tiles as they reach them
    (`threads._owns`): the three layers as one draw, blended without a
    depth test (a tile drawn by two shares would blend twice, one drawn by
    none would keep the background), textured and lit, in two and three
    shares against one; every tile with triangles has one owner after."""
    data = draw_scene()
    layers = data["nodes"]
    positions = [[x + 0.1 * k, y + 0.05 * k, 0.1 * k] for k in range(3) for x, y, _ in layers[0]["mesh"]["positions"]]
    data["nodes"] = [dict(layers[0], name="layers", translate=[0, 0, 0],
                          mesh=dict(layers[0]["mesh"], positions=positions, uvs=layers[0]["mesh"]["uvs"] * 3,
                                    normals=layers[0]["mesh"]["normals"] * 3,
                                    indices=[[a + 4 * k, b + 4 * k, c + 4 * k] for k in range(3)
                                             for a, b, c in layers[0]["mesh"]["indices"]]))]
    scene = softras.load_scene(data)
    monkeypatch.setattr(draw, "shares", lambda batch, n_threads, extra=0.0: 1)
    one = softras.render(scene, samples=samples, pattern=pattern)
    monkeypatch.setattr(draw, "shares", lambda batch, n_threads, extra=0.0: n_threads)
    tables = []
    real_owners = draw.tile_owners

    def owners(batch, n_shares):
        tables.append((real_owners(batch, n_shares), batch[0].records[0][0]))
        return tables[-1][0]

    monkeypatch.setattr(draw, "tile_owners", owners)
    for n in (2, 3):
        monkeypatch.setattr(draw.numba, "get_num_threads", lambda n=n: n)
        assert np.array_equal(softras.render(scene, samples=samples, pattern=pattern), one), f"{n} shares"
        table, bin_start = tables[-1]
        with_triangles = bin_start[1:] > bin_start[:-1]
        owned = (table >= 0) & (table < n)
        # (At one sample the shares then copy every tile into the picture,
        # taking those without triangles too: `softras.kernels.ops._tiles_out`.)
        assert with_triangles.any() and (owned == (True if samples == 1 else with_triangles)).all(), table


def draw_scene() -> dict:
    quad = {"positions": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], "indices": [[0, 1, 2], [0, 2, 3]],
            "uvs": [[0, 0], [1, 0], [1, 1], [0, 1]], "normals": [[0, 0, 1]] * 4}
    nodes = [{"name": f"layer{k}", "mesh": quad, "translate": [0.1 * k, 0.05 * k, 0.1 * k], "blend": "over",
              "depth_test": False, "material": {"color": [1, 0.5, 0.2, 0.5], "texture": "checker", "shading": "phong"}}
             for k in range(3)]
    return {"softras_scene": 1, "width": 200, "height": 150, "background": [0, 0, 0, 1],
            "camera": {"projection": "perspective", "fov_y": 50, "near": 0.1, "far": 100, "eye": [0, 0, 3],
                       "target": [0, 0, 0]},
            "lights": [{"type": "point", "position": [1, 2, 3], "color": [1, 1, 1]}],
            "textures": {"checker": {"procedural": "checker", "size": [64, 64],
                                     "min_filter": "linear_mipmap_linear"}},
            "nodes": nodes}


@pytest.mark.parametrize("batch_triangles", [draw.BATCH_TRIANGLES, 5])
def test_a_scene_of_many_draws_in_batches_gives_the_stages_bytes(batch_triangles, monkeypatch):
    """Blended layers, a line draw after the third (the triangle draws
    before it are drawn first), then more than a batch holds
    (`draw.MAX_BATCH` draws, or `draw.BATCH_TRIANGLES` triangles: here
    also 5, two quads), every batch cut into two shares: the stages' bytes."""
    scene = draw_scene()
    quad = scene["nodes"][0]["mesh"]
    scene["nodes"] = [{"name": f"layer{k}", "mesh": quad, "translate": [0.03 * k - 0.3, 0.02 * k, 0.0],
                       "scale": [0.5, 0.5, 1.0], "blend": "over", "depth_test": False,
                       "material": {"color": [1, 0.1 * (k % 10), 0.2, 0.4], "texture": "checker" if k % 3 else None}}
                      for k in range(draw.MAX_BATCH + 8)]
    scene["nodes"].insert(3, {"name": "lines", "blend": "over", "depth_test": False,
                              "mesh": {"primitive": "lines", "positions": [[-1, -0.8, 0], [1, 0.9, 0], [-1, 0.2, 0],
                                                                          [1, 0.1, 0]], "indices": [[0, 1], [2, 3]]},
                              "material": {"color": [0.1, 1, 0.3, 0.7]}})
    scene = softras.load_scene(scene)
    monkeypatch.setattr(draw, "shares", lambda batch, n_threads, extra=0.0: n_threads)
    monkeypatch.setattr(draw, "BATCH_TRIANGLES", batch_triangles)
    monkeypatch.setattr(draw.numba, "get_num_threads", lambda: 2)
    for samples in (1, 4):
        assert np.array_equal(softras.render(scene, samples=samples),
                              softras.render(scene, samples=samples, fast_path=False)), f"{samples} samples"


def test_the_drivers_read_no_lane_they_have_not_written(monkeypatch):
    """A share's lanes are carried from draw to draw of a batch
    (`draw.draw_batch`): drawn with lanes full of junk, the textured and
    untextured scenes of this file at each driver's sample count give
    the bytes of zeroed lanes.  (The lane steps that run over whole
    vectors compute lanes past their count from such junk, and must not
    read outside the texture for them: the integer rows' junk is an
    address far beyond any texture.)"""
    zeroed = draw.lane_buffers

    def junk(integer_junk, n_samples):
        lanes = zeroed(n_samples)
        for rows, value in zip(lanes, (1.2345e300, integer_junk, 0xDEADBEEF, np.nan, -3)):
            rows[...] = value
        return lanes

    scenes = [softras.load_scene(draw_scene()), softras.load_scene(SCENES / "blend_equations.json"),
              softras.load_scene(SCENES / "bump_mapped_plane.json")]
    for samples, pattern in [(1, "gl"), (4, "gl"), (8, "halton")]:
        for scene in scenes:
            monkeypatch.setattr(draw, "lane_buffers", zeroed)
            expected = softras.render(scene, samples=samples, pattern=pattern)
            for integer_junk in (-7, 1 << 40):
                monkeypatch.setattr(draw, "lane_buffers", functools.partial(junk, integer_junk))
                assert np.array_equal(softras.render(scene, samples=samples, pattern=pattern), expected), \
                    f"{samples} samples, integer rows {integer_junk}"


@pytest.mark.parametrize("name, expected", [("parts_64x128_512", 2), ("textured_parts_64x128_512", 2),
                                            ("few_large_512", 2), ("scale_pixels_256", 2)])
def test_a_batch_takes_two_threads_where_its_work_outweighs_the_hand_off(name, expected, monkeypatch):
    """`draw.shares` on two threads, from the set-up's estimate of each
    draw's work (`draw.draw_work`): batches of 16 small unlit draws take
    two (half their work outweighs the hand-off and a trade of the GIL at
    each draw, since the shares take the tiles as they reach them: on two
    they drew 0.88-0.91x their time on one), as do the same draws textured
    and lit, one large quad and one draw of 2k small triangles; the three
    quads of a 128x96 scene stay on one (docs/speed.md, "Forty-third
    round", "Forty-fifth round")."""
    from softras import bench
    scenes = [softras.load_scene(next(item.scene for item in bench.scenes() if item.name == name)),
              softras.load_scene(SCENES / "culling_back.json")]
    for scene in scenes:            # (first: the kernels' preparation draws scenes of its own)
        softras.render(scene)
    decided = []
    decide = draw.shares
    monkeypatch.setattr(draw.numba, "get_num_threads", lambda: 2)
    monkeypatch.setattr(draw, "shares",
                        lambda batch, n_threads, extra=0.0: decided.append(decide(batch, n_threads, extra)) or 1)
    for scene, want in zip(scenes, (expected, 1)):
        decided.clear()
        softras.render(scene)
        assert decided and set(decided) == {want}, decided


def test_a_kernel_that_asks_for_an_aligned_stack_aligns_it():
    """`threads._aligned_stack` gives its caller LLVM's alignstack(64): the
    compiled function starts by rounding its stack pointer down to 64
    bytes (``and $-64, %rsp``), and a function without it does not.  (The
    attribute is lost if llvmlite is not made to write it: it writes a
    function's attributes only beside a named one.)"""
    import numba

    @numba.njit
    def aligned(a):
        threads._aligned_stack()
        return a.sum()

    @numba.njit
    def plain(a):
        return a.sum()

    asm = {}
    for name, f in (("aligned", aligned), ("plain", plain)):
        f(np.ones(4))
        asm[name] = f.inspect_asm(f.signatures[0])
    assert "andq\t$-64, %rsp" in asm["aligned"]
    assert "andq\t$-64, %rsp" not in asm["plain"]
