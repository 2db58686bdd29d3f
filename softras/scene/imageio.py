"""PNG input and output for softras.

Images are always handled as ``uint8`` arrays of shape ``(H, W, 4)`` (RGBA),
row 0 = the top of the picture, which is also the first row of a PNG file.
A float image (an rgba32f render) is not written as it is: :func:`to_uint8`
turns it into the 8-bit image an RGBA8 framebuffer would hold (clamp, round),
which is what the CLI writes to PNG; keep the array for exact values.

Writing is atomic: :func:`write_png_atomic` writes a temporary file in the
destination folder and renames it over the destination with
:func:`os.replace`, so a reader never sees a half-written file and an existing
file survives any failure.

Every failure is reported as :class:`ImageError`, whose message is one line of
the form ``"path: reason"``.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

__all__ = ["ImageError", "read_png", "to_uint8", "write_png_atomic"]


class ImageError(ValueError):
    """An image could not be read or written.

    ``str(error)`` is one line, ``"path: reason"``.
    """


def _one_line(text: object) -> str:
    """Collapse a message onto one line."""
    return " ".join(str(text).split())


def read_png(path: str | os.PathLike) -> np.ndarray:
    """Read a PNG file as RGBA.

    Parameters
    ----------
    path : str or os.PathLike
        The file to read.

    Returns
    -------
    numpy.ndarray
        ``uint8`` array of shape ``(H, W, 4)``, row 0 = top of the picture.
        RGB images get alpha 255; grayscale images are expanded to grey RGB
        (with their own alpha if they have one, else 255); palette images are
        converted through their palette. 16-bit images are reduced to 8 bits.

    Raises
    ------
    ImageError
        If the file is missing, unreadable or not a PNG image.
    """
    from PIL import Image, UnidentifiedImageError

    path = Path(path)
    if not path.exists():
        raise ImageError(f"{path}: no such file")
    if path.is_dir():
        raise ImageError(f"{path}: is a directory, not a PNG file")
    try:
        with Image.open(path) as image:
            if image.format != "PNG":
                raise ImageError(f"{path}: not a PNG file (found {image.format or 'unknown format'})")
            image.load()
            if image.mode in ("I", "I;16", "I;16B", "I;16L"):
                # 16-bit grayscale: Pillow's convert("RGBA") clips instead of
                # scaling, so reduce to 8 bits by hand.
                grey = np.asarray(image, dtype=np.uint32)
                grey8 = ((grey * 255 + 32767) // 65535).astype(np.uint8)
                rgba = np.empty(grey8.shape + (4,), dtype=np.uint8)
                rgba[..., :3] = grey8[..., None]
                rgba[..., 3] = 255
                return rgba
            rgba = np.asarray(image.convert("RGBA"), dtype=np.uint8)
    except ImageError:
        raise
    except UnidentifiedImageError:
        raise ImageError(f"{path}: not a PNG file (unrecognised image data)") from None
    except (OSError, SyntaxError, ValueError) as error:
        # Pillow reports truncated or corrupt data as OSError / SyntaxError /
        # ValueError depending on where decoding fails.
        raise ImageError(f"{path}: cannot read PNG: {_one_line(error)}") from None
    return np.ascontiguousarray(rgba)


def to_uint8(image: np.ndarray) -> np.ndarray:
    """A float image (an rgba32f render, colour units) as the uint8 an RGBA8
    framebuffer would hold: ``round_half_even(clamp(v, 0, 1) * 255)``.
    uint8 images are returned as they are."""
    array = np.asarray(image)
    if array.dtype.kind != "f":
        return array
    if not np.isfinite(array).all():
        raise ValueError("image has NaN or infinite values")
    return np.rint(np.clip(array, 0.0, 1.0) * 255.0).astype(np.uint8)


def _check_image(path: Path, image: np.ndarray) -> np.ndarray:
    """Validate an image to be written and return it as contiguous uint8."""
    array = np.asarray(image)
    if array.dtype != np.uint8:
        raise ImageError(f"{path}: image must be uint8, got {array.dtype}")
    if array.ndim == 2:
        return np.ascontiguousarray(array)
    if array.ndim != 3 or array.shape[2] not in (1, 3, 4):
        raise ImageError(f"{path}: image must have shape (H, W), (H, W, 3) or (H, W, 4), got {array.shape}")
    if array.shape[0] == 0 or array.shape[1] == 0:
        raise ImageError(f"{path}: image is empty (shape {array.shape})")
    if array.shape[2] == 1:
        array = array[..., 0]
    return np.ascontiguousarray(array)


def check_writable(path: str | os.PathLike) -> Path:
    """Check that a file can be created at ``path`` without writing anything.

    Parameters
    ----------
    path : str or os.PathLike
        The destination file.

    Returns
    -------
    pathlib.Path
        ``path`` as a :class:`~pathlib.Path`.

    Raises
    ------
    ImageError
        If the folder does not exist, is not a folder, is not writable, or
        ``path`` names an existing folder.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise ImageError(f"{path}: is a directory")
    if not folder.exists():
        raise ImageError(f"{path}: folder {folder} does not exist")
    if not folder.is_dir():
        raise ImageError(f"{path}: {folder} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ImageError(f"{path}: folder {folder} is not writable")
    return path


def write_png_atomic(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write an image as PNG, atomically.

    The image is encoded into a temporary file in the destination folder,
    flushed to disk, and renamed over ``path`` with :func:`os.replace`. On
    any failure the temporary file is removed and an existing ``path`` is left
    as it was.

    Parameters
    ----------
    path : str or os.PathLike
        The destination file. Its folder must exist and be writable.
    image : numpy.ndarray
        ``uint8`` array of shape ``(H, W, 4)`` (RGBA), ``(H, W, 3)`` (RGB) or
        ``(H, W)`` (grey), row 0 = top of the picture.  A float array (an
        rgba32f render) is refused: quantise it with `to_uint8` first.

    Raises
    ------
    ImageError
        If the image is not a valid uint8 image or the file cannot be written.
    """
    from PIL import Image

    path = check_writable(path)
    array = _check_image(path, image)
    _write_atomic(path, lambda handle: Image.fromarray(array).save(handle, format="PNG"), "PNG")


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write a UTF-8 text file atomically (same guarantees as `write_png_atomic`)."""
    path = check_writable(path)
    _write_atomic(path, lambda handle: handle.write(text.encode("utf-8")), "file")


def copy_file_atomic(source: str | os.PathLike, path: str | os.PathLike) -> None:
    """Copy a file byte for byte, atomically (same guarantees as `write_png_atomic`)."""
    path = check_writable(path)
    with open(source, "rb") as data:
        _write_atomic(path, lambda handle: shutil.copyfileobj(data, handle), "file")


def _write_atomic(path: Path, write, what: str) -> None:
    """Call ``write(binary_handle)`` on a temporary file, then rename it to ``path``."""
    folder = path.parent if str(path.parent) else Path(".")
    try:
        fd, temp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    except OSError as error:
        raise ImageError(f"{path}: cannot create a file in {folder}: {_one_line(error.strerror or error)}") from None
    try:
        with os.fdopen(fd, "wb") as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
        # mkstemp creates the file with mode 0600; give it the usual mode.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temp_name, 0o666 & ~umask)
        os.replace(temp_name, path)
    except BaseException as error:
        try:
            os.unlink(temp_name)
        except FileNotFoundError:
            pass
        if isinstance(error, OSError):
            raise ImageError(f"{path}: cannot write {what}: {_one_line(error.strerror or error)}") from None
        raise
