"""GL's matrix helpers: gluPerspective, glFrustum, glOrtho, gluLookAt and the
affine transforms of scene nodes, as float64 (4, 4) matrices in the column-vector
convention (clip = projection @ view @ world @ [x, y, z, 1])."""

from __future__ import annotations

import math

import numpy as np



def perspective_matrix(fov_y: float, aspect: float, near: float, far: float) -> np.ndarray:
    """gluPerspective: f = cot(fov_y/2); rows (f/aspect,0,0,0), (0,f,0,0),
    (0,0,(far+near)/(near−far), 2·far·near/(near−far)), (0,0,−1,0).  fov_y in degrees."""
    f = 1.0 / math.tan(math.radians(fov_y) / 2.0)
    return np.array([[f / aspect, 0, 0, 0],
                     [0, f, 0, 0],
                     [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)],
                     [0, 0, -1, 0]], dtype=np.float64)


def frustum_matrix(left, right, bottom, top, near, far) -> np.ndarray:
    """glFrustum."""
    return np.array([[2 * near / (right - left), 0, (right + left) / (right - left), 0],
                     [0, 2 * near / (top - bottom), (top + bottom) / (top - bottom), 0],
                     [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)],
                     [0, 0, -1, 0]], dtype=np.float64)


def orthographic_matrix(left, right, bottom, top, near, far) -> np.ndarray:
    """glOrtho."""
    return np.array([[2 / (right - left), 0, 0, -(right + left) / (right - left)],
                     [0, 2 / (top - bottom), 0, -(top + bottom) / (top - bottom)],
                     [0, 0, -2 / (far - near), -(far + near) / (far - near)],
                     [0, 0, 0, 1]], dtype=np.float64)


def look_at_matrix(eye, target, up) -> np.ndarray:
    """gluLookAt: f = normalize(target − eye), s = normalize(f × up), u = s × f;
    rows (s, 0), (u, 0), (−f, 0), (0, 0, 0, 1), times translate(−eye)."""
    eye = np.asarray(eye, dtype=np.float64)
    f = np.asarray(target, dtype=np.float64) - eye
    f = f / np.linalg.norm(f)
    s = cross3(f, np.asarray(up, dtype=np.float64))
    s = s / np.linalg.norm(s)
    u = cross3(s, f)
    rotation = np.identity(4)
    rotation[0, :3], rotation[1, :3], rotation[2, :3] = s, u, -f
    return rotation @ translate_matrix(-eye)


def cross3(a, b) -> np.ndarray:
    """a × b of two 3-vectors: the products and differences of np.cross (the
    same doubles) without its general-shape machinery (30 µs a call)."""
    a0, a1, a2 = (float(x) for x in a)
    b0, b1, b2 = (float(x) for x in b)
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def translate_matrix(offset) -> np.ndarray:
    """glTranslate."""
    matrix = np.identity(4)
    matrix[:3, 3] = offset
    return matrix


def rotate_matrix(angle_degrees: float, axis) -> np.ndarray:
    """glRotate: counter-clockwise by ``angle_degrees`` about the (normalised) axis."""
    x, y, z = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    c, s = math.cos(math.radians(angle_degrees)), math.sin(math.radians(angle_degrees))
    matrix = np.identity(4)
    matrix[:3, :3] = [[x * x * (1 - c) + c, x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
                      [y * x * (1 - c) + z * s, y * y * (1 - c) + c, y * z * (1 - c) - x * s],
                      [x * z * (1 - c) - y * s, y * z * (1 - c) + x * s, z * z * (1 - c) + c]]
    return matrix


def scale_matrix(factors) -> np.ndarray:
    """glScale."""
    return np.diag([*np.asarray(factors, dtype=np.float64), 1.0])


# --------------------------------------------------------------------------- value helpers
