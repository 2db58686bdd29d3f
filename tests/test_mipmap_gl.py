"""softras's mip chain against GL's glGenerateMipmap, read back level by level.

glref uploads level 0 and lets GL generate the rest, so what softras samples
at levels >= 1 is only GL's texels if `softras.scene.texels.mip_chain` makes the
same bytes.  On Mesa llvmpipe it must, byte for byte (the reduction is a
bilinear blit in 8.8 fixed point: `softras.scene.texels.llvmpipe_blit_coordinates`).
Other GL implementations generate differently (the GL specification
requires no particular filter), so the comparison runs on llvmpipe only.
"""

from __future__ import annotations

import numpy as np
import pytest

from softras.scene import texels

# Every size in 1..20 x 1..20 (POT, NPOT, odd, 1xN and Nx1, 1x1), the
# examples of the task, and sizes where a detail of llvmpipe's arithmetic
# shows: 158x475 and 618x207 put a texel centre exactly on the blit's
# diagonal where the two triangles' t differ (the upper-right one owns it);
# 1421x1167, 999x777 and 220x1435 differ without the fused multiply-add of
# the attribute interpolation; 1023x207 and 7x231 where the two triangles'
# t differ off the diagonal; 2047x5 and 1x1000 are thin and long.
SIZES = ([(w, h) for h in range(1, 21) for w in range(1, 21)]
         + [(37, 23), (64, 64), (256, 256), (255, 129), (158, 475), (618, 207), (1421, 1167),
            (999, 777), (220, 1435), (1023, 207), (7, 231), (2047, 5), (1, 1000)])


def _contents(width: int, height: int, rng) -> list[np.ndarray]:
    """Premultiplied (H, W, 4) uint8 level-0 contents: noise with random
    alpha, black and white with alpha 0 or 255, and a diagonal ramp."""
    noise = texels.premultiply_rgba8(rng.integers(0, 256, (height, width, 4), dtype=np.uint8))
    binary = texels.premultiply_rgba8((rng.integers(0, 2, (height, width, 4)) * 255).astype(np.uint8))
    x, y = np.meshgrid(np.arange(width), np.arange(height))
    ramp = np.stack([(x * 7 + y * 13) % 256, (x * 255 // max(1, width - 1)),
                     (y * 255 // max(1, height - 1)), np.full_like(x, 255)], axis=-1).astype(np.uint8)
    return [noise, binary, ramp]


@pytest.fixture(scope="module")
def gl_levels():
    """(size, level-0 contents, GL's levels) for every size and content; llvmpipe only."""
    import glref
    info = glref.info()
    if "llvmpipe" not in (info["GL_RENDERER"] or ""):
        pytest.skip(f"softras reproduces llvmpipe's glGenerateMipmap, not {info['GL_RENDERER']}'s")
    if info["env"].get("GALLIVM_PERF"):
        pytest.skip(f"GALLIVM_PERF={info['env']['GALLIVM_PERF']} may change llvmpipe's sampling")
    rng = np.random.default_rng(20)
    return [((w, h), level0, glref.generate_mipmaps(level0))
            for w, h in SIZES for level0 in _contents(w, h, rng)]


def _mismatches(gl_levels, chain) -> list[str]:
    """One line per (size, content) whose ``chain(level0)`` differs from GL's levels anywhere."""
    lines = []
    for (w, h), level0, gl in gl_levels:
        soft = chain(level0)
        assert [lvl.shape for lvl in soft] == [lvl.shape for lvl in gl]
        for i, (a, b) in enumerate(zip(soft, gl)):
            if not np.array_equal(a, b):
                diff = np.abs(a.astype(int) - b.astype(int))
                lines.append(f"{w}x{h} level {i} ({a.shape[1]}x{a.shape[0]}): "
                             f"{(diff.max(-1) > 0).sum()} texels differ, max {diff.max()}")
                break
    return lines


@pytest.mark.gl
def test_mip_chain_equals_llvmpipe_generate_mipmap(gl_levels):
    """Every level of every size and content, byte for byte, with mip_chain's
    default method (the chain `softras.scene.Texture.levels` holds)."""
    assert len(gl_levels) == 3 * len(SIZES)
    wrong = _mismatches(gl_levels, texels.mip_chain)
    assert not wrong, f"{len(wrong)} chains differ from GL's, e.g.\n" + "\n".join(wrong[:10])


@pytest.mark.gl
def test_box_chain_is_not_llvmpipe(gl_levels):
    """The rounded 2x2 box (softras's reduction before GL generated the
    levels) differs from llvmpipe on NPOT sizes by up to a colour's range and
    on POT sizes by 1/255: the comparison above can tell them apart."""
    wrong = _mismatches(gl_levels, lambda level0: texels.mip_chain(level0, method="box"))
    assert len(wrong) > len(gl_levels) // 2
    assert any(line.startswith("4x4 ") for line in wrong)


@pytest.mark.gl
def test_glref_texture_levels_are_generated(monkeypatch):
    """glref's textures take levels >= 1 from glGenerateMipmap by default,
    not from softras's chain: a chain of solid colours (level 0 red) is
    ignored unless ``mipmaps="upload"``."""
    import glref
    from conftest import SCENES
    from softras.scene import load_scene

    real_chain = texels.mip_chain

    def solid(level0, premultiply=False, method="llvmpipe"):
        chain = real_chain(level0, premultiply, method)
        for k, level in enumerate(chain):
            level[...] = (255, 0, 0, 255) if k == 0 else (0, 0, 255, 255)
        return chain

    monkeypatch.setattr(texels, "mip_chain", solid)
    scene = load_scene(SCENES / "texture_mip_level_colors.json")
    generated = glref.render(scene)
    uploaded = glref.render(scene, mipmaps="upload")
    blue = lambda image: ((image[..., 2] > 200) & (image[..., 0] < 50)).mean()     # noqa: E731
    assert blue(generated) == 0
    assert blue(uploaded) > 0.05
    with pytest.raises(ValueError):
        glref.render(scene, mipmaps="box")
