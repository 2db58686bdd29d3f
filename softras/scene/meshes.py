"""Procedural meshes a scene can ask for instead of explicit arrays.

A scene node may say ``"mesh": {"procedural": "grid", "cols": 8, "rows": 6,
"size": [2, 1.5]}``; ``softras.scene`` validates the keys and calls the
function of the same name here.  Every function returns a :class:`MeshArrays`
tuple ``(positions, indices, colors, normals, uvs)``:

- ``positions``  (N, 3) float64, model space
- ``indices``    (M, 3) int64, counter-clockwise seen from +z (grid, fan) or
  from outside (sphere), i.e. GL front faces
- ``colors``     (N, 4) float64 RGBA in [0, 1], or None
- ``normals``    (N, 3) float64 unit vectors, or None
- ``uvs``        (N, 2) float64, v = 0 at the top row of the texture image

Sizes are capped (:data:`MAX_TRIANGLES`) so that a scene file cannot ask for
an unbounded amount of memory; :func:`triangle_count` gives the count before
anything is allocated.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

MAX_TRIANGLES = 4 * 1024 * 1024  # per scene (scene.py) and per mesh (here)


class MeshArrays(NamedTuple):
    positions: np.ndarray        # (N, 3) float64, model space
    indices: np.ndarray          # (M, 3) int64
    colors: np.ndarray | None    # (N, 4) float64 RGBA
    normals: np.ndarray | None   # (N, 3) float64, unit length, model space
    uvs: np.ndarray | None       # (N, 2) float64, v = 0 at the image top


def triangle_count(kind: str, **params) -> int:
    """Number of triangles ``kind`` makes with these parameters (no allocation)."""
    if kind == "grid":
        return 2 * int(params["cols"]) * int(params["rows"])
    if kind == "sphere":
        return int(params["segments"]) * (2 * int(params["rings"]) - 2)
    if kind == "fan":
        return int(params["count"])
    raise ValueError(f"unknown procedural mesh {kind!r}")


def _check_budget(kind: str, **params) -> None:
    count = triangle_count(kind, **params)
    if count > MAX_TRIANGLES:
        raise ValueError(f"{kind} would have {count} triangles, more than the limit {MAX_TRIANGLES}")


def grid(cols: int, rows: int, size=(1.0, 1.0), corner_colors=None) -> MeshArrays:
    """A plane of ``cols`` x ``rows`` cells in z = 0, centred at the origin.

    Vertex (i, j), i = column 0..cols (left to right), j = row 0..rows (top to
    bottom), lies at x = (i/cols − 1/2)·w, y = (1/2 − j/rows)·h and has
    uv = (i/cols, j/rows): v = 0 on the top row.  Each cell is split along its
    bottom-left to top-right diagonal into (bl, br, tr) and (bl, tr, tl), both
    counter-clockwise seen from +z.  Normals are +z.

    ``corner_colors``: optional 4 RGBA colours for the corners bottom-left,
    bottom-right, top-right, top-left (counter-clockwise), interpolated
    bilinearly over the grid.
    """
    if cols < 1 or rows < 1:
        raise ValueError("grid needs cols >= 1 and rows >= 1")
    _check_budget("grid", cols=cols, rows=rows)
    width, height = float(size[0]), float(size[1])
    u = np.arange(cols + 1, dtype=np.float64) / cols          # (cols+1,)
    v = np.arange(rows + 1, dtype=np.float64) / rows          # (rows+1,)
    uu, vv = np.meshgrid(u, v)                                 # (rows+1, cols+1), row j, column i
    positions = np.stack([(uu - 0.5) * width, (0.5 - vv) * height, np.zeros_like(uu)], axis=-1)
    positions = positions.reshape(-1, 3)
    uvs = np.stack([uu, vv], axis=-1).reshape(-1, 2)
    normals = np.zeros_like(positions)
    normals[:, 2] = 1.0

    top_left = (np.arange(rows)[:, None] * (cols + 1) + np.arange(cols)).ravel()     # cell (i, j), row-major
    cells = np.empty((rows * cols, 2, 3), dtype=np.int64)     # per cell (bl, br, tr), (bl, tr, tl)
    cells[:, 0, 0] = cells[:, 1, 0] = top_left + (cols + 1)
    cells[:, 0, 1] = top_left + (cols + 2)
    cells[:, 0, 2] = cells[:, 1, 1] = top_left + 1
    cells[:, 1, 2] = top_left
    indices = cells.reshape(-1, 3)

    colors = None
    if corner_colors is not None:
        bl, br, tr, tl = (np.asarray(c, dtype=np.float64) for c in corner_colors)
        s = uvs[:, 0:1]             # 0 at the left
        t = 1.0 - uvs[:, 1:2]       # 0 at the bottom
        colors = ((1 - s) * (1 - t) * bl + s * (1 - t) * br + s * t * tr + (1 - s) * t * tl)
    return MeshArrays(positions, indices, colors, normals, uvs)


def sphere(segments: int, rings: int, radius: float = 1.0, color_from_normal: bool = False) -> MeshArrays:
    """A UV sphere around the origin, poles on the y axis.

    ``segments`` slices around y (>= 3), ``rings`` bands from pole to pole
    (>= 2).  Vertex (s, r) has polar angle θ = π·r/rings from +y and azimuth
    φ = 2π·s/segments, position radius·(sin θ sin φ, cos θ, sin θ cos φ) (φ = 0
    faces +z), uv = (s/segments, r/rings); the seam column s = segments
    duplicates s = 0 so that u runs 0..1.  The triangles touching a pole are
    not emitted degenerate: the cap bands have one triangle per segment.
    Faces are counter-clockwise seen from outside.

    ``color_from_normal``: colours (n + 1)/2, alpha 1 (a quick visual aid).
    """
    if segments < 3 or rings < 2:
        raise ValueError("sphere needs segments >= 3 and rings >= 2")
    _check_budget("sphere", segments=segments, rings=rings)
    phi = 2.0 * np.pi * np.arange(segments + 1) / segments      # azimuth
    theta = np.pi * np.arange(rings + 1) / rings                 # polar angle from +y
    ph, th = np.meshgrid(phi, theta)                              # (rings+1, segments+1)
    normals = np.stack([np.sin(th) * np.sin(ph), np.cos(th), np.sin(th) * np.cos(ph)], axis=-1)
    normals = normals.reshape(-1, 3)
    # Exact poles (sin(pi) is 1.2e-16, not 0).
    normals[: segments + 1] = (0.0, 1.0, 0.0)
    normals[-(segments + 1):] = (0.0, -1.0, 0.0)
    positions = radius * normals
    s_idx, r_idx = np.meshgrid(np.arange(segments + 1), np.arange(rings + 1))
    uvs = np.stack([s_idx / segments, r_idx / rings], axis=-1).reshape(-1, 2).astype(np.float64)

    s, r = np.meshgrid(np.arange(segments), np.arange(rings))    # band r, slice s
    upper_left = (r * (segments + 1) + s).ravel()                 # nearer +y, smaller φ
    upper_right = upper_left + 1
    lower_left = upper_left + (segments + 1)
    lower_right = lower_left + 1
    band = r.ravel()
    # Seen from outside (looking towards the centre) +y is up and φ grows to the
    # right, so (upper_left, lower_left, lower_right) is counter-clockwise.
    # At the top band both upper vertices are the pole, at the bottom band both
    # lower ones: the triangle that would be degenerate there is left out.
    first = np.stack([upper_left, lower_left, lower_right], axis=-1)[band < rings - 1]
    second = np.stack([upper_left, lower_right, upper_right], axis=-1)[band > 0]
    indices = np.concatenate([first, second]).astype(np.int64)

    colors = None
    if color_from_normal:
        colors = np.concatenate([(normals + 1.0) / 2.0, np.ones((len(normals), 1))], axis=1)
    return MeshArrays(positions, indices, colors, normals, uvs)


def fan(count: int, radius: float = 1.0, angle: float = 360.0, center_color=None, rim_colors=None) -> MeshArrays:
    """``count`` thin triangles around the origin in z = 0, sharing edges.

    Vertex 0 is the centre; rim vertex k (k = 1, 2, ...) lies at angle
    (k−1)·angle/count degrees counter-clockwise from +x.  Triangle k is
    (0, k, k+1), counter-clockwise seen from +z.  A full turn (angle 360) reuses
    rim vertex 1 as the last one, so every edge is shared by two triangles;
    it needs count >= 3.  Normals are +z; uvs map the disc of ``radius`` onto
    the unit square (v = 0 at +y).

    Colours (optional): the centre gets ``center_color`` (default white), rim
    vertex k gets ``rim_colors[(k−1) % len(rim_colors)]`` (default white).
    """
    if count < 1:
        raise ValueError("fan needs count >= 1")
    if not 0.0 < angle <= 360.0:
        raise ValueError("fan angle must be in (0, 360] degrees")
    full_turn = angle == 360.0
    if full_turn and count < 3:
        raise ValueError("a full-turn fan needs count >= 3")
    _check_budget("fan", count=count)
    rim_count = count if full_turn else count + 1
    rim_angle = np.radians(angle) * np.arange(rim_count) / count
    positions = np.zeros((rim_count + 1, 3))
    positions[1:, 0] = radius * np.cos(rim_angle)
    positions[1:, 1] = radius * np.sin(rim_angle)
    k = np.arange(1, count + 1)
    following = k + 1
    if full_turn:
        following[-1] = 1
    indices = np.stack([np.zeros_like(k), k, following], axis=-1).astype(np.int64)
    normals = np.zeros_like(positions)
    normals[:, 2] = 1.0
    uvs = np.stack([0.5 + positions[:, 0] / (2 * radius), 0.5 - positions[:, 1] / (2 * radius)], axis=-1)

    colors = None
    if center_color is not None or rim_colors is not None:
        white = (1.0, 1.0, 1.0, 1.0)
        rim = np.asarray(rim_colors if rim_colors is not None else [white], dtype=np.float64)
        colors = np.empty((rim_count + 1, 4))
        colors[0] = center_color if center_color is not None else white
        colors[1:] = rim[np.arange(rim_count) % len(rim)]
    return MeshArrays(positions, indices, colors, normals, uvs)


def vertex_tangents(positions: np.ndarray, normals: np.ndarray, uvs: np.ndarray,
                    indices: np.ndarray) -> np.ndarray:
    """Per-vertex tangent frames for normal and bump mapping, (N, 4) float64.

    The standard per-triangle dP/du accumulation (Lengyel 2001): for a
    triangle (p0, p1, p2) with uvs (s_k, t_k), edges ``e1 = p1 - p0``,
    ``e2 = p2 - p0`` and ``(ds1, dt1)``, ``(ds2, dt2)`` their uv steps,

        dP/ds = (e1 dt2 - e2 dt1) / D,   dP/dt = (e2 ds1 - e1 ds2) / D,
        D = ds1 dt2 - ds2 dt1,

    summed (unweighted) into the triangle's three vertices; triangles with
    ``D == 0`` (no uv area) add nothing.  Each vertex then gets

    - ``xyz``: the sum of dP/ds made perpendicular to the vertex normal and
      normalised (Gram-Schmidt): ``T = normalize(S - N (N.S))``;
    - ``w``: the handedness, +1 when ``cross(N, T)`` points along the summed
      dP/dt, -1 where the uv map is mirrored (so that the bitangent
      ``B = w cross(N, T)`` follows increasing t, i.e. DOWN the image, since
      t = 0 is the top row of a texture).

    A vertex with no usable tangent (all its triangles uv-degenerate, or
    dP/ds parallel to N) gets ``normalize(cross(a, N))`` with ``a`` the
    coordinate axis along N's smallest component (the first on ties), w = +1.

    positions : (N, 3) model space; normals : (N, 3) model space (need not be
    unit); uvs : (N, 2) (s, t); indices : (M, 3) int triangles.
    Returns (N, 4) float64, model space: unit T (xyz) and w = +-1.
    Both renderers use exactly these values (glref uploads them as the
    vertex attribute ``in_tangent``).
    """
    positions = np.asarray(positions, np.float64)
    n = np.asarray(normals, np.float64)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    uvs = np.asarray(uvs, np.float64)
    indices = np.asarray(indices, np.int64).reshape(-1, 3)
    p0, p1, p2 = (positions[indices[:, k]] for k in range(3))
    w0, w1, w2 = (uvs[indices[:, k]] for k in range(3))
    e1, e2 = p1 - p0, p2 - p0
    d1, d2 = w1 - w0, w2 - w0
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    ok = det != 0
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)[:, None]
    dp_ds = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * inv              # (M, 3), zero where not ok
    dp_dt = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * inv
    s_sum = np.zeros_like(positions)
    t_sum = np.zeros_like(positions)
    for k in range(3):
        np.add.at(s_sum, indices[:, k], dp_ds)
        np.add.at(t_sum, indices[:, k], dp_dt)
    tangent = s_sum - n * np.einsum("nk,nk->n", n, s_sum)[:, None]
    length = np.linalg.norm(tangent, axis=1)
    scale = np.maximum(np.linalg.norm(s_sum, axis=1), 1e-300)
    bad = ~(length > 1e-12 * scale) | ~np.isfinite(length)
    if np.any(bad):
        axis = np.zeros((int(bad.sum()), 3))
        axis[np.arange(len(axis)), np.argmin(np.abs(n[bad]), axis=1)] = 1.0
        tangent[bad] = np.cross(axis, n[bad])
        length[bad] = np.linalg.norm(tangent[bad], axis=1)
    tangent = tangent / length[:, None]
    handedness = np.where(np.einsum("nk,nk->n", np.cross(n, tangent), t_sum) < 0, -1.0, 1.0)
    return np.concatenate([tangent, handedness[:, None]], axis=1)


PROCEDURAL = {"grid": grid, "sphere": sphere, "fan": fan}
