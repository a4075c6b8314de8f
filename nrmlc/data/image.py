"""Turning an image array into the float32 gray frame every part of nrmlc works on."""
from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import threading

import cv2
import numpy as np

from nrmlc.errors import ParameterError

_INTEGER_SCALE = {np.dtype(np.uint8): 1.0 / 255.0, np.dtype(np.uint16): 1.0 / 65535.0}


def to_gray_float32(image: np.ndarray) -> np.ndarray:
    """A gray, gray+alpha, BGR or BGRA image as a C-contiguous float32 gray frame.

    uint8 is divided by 255 and uint16 by 65535 (so the frame is in [0, 1]);
    other numeric types keep their values. Colour is converted with OpenCV's
    luma weights in float, after the scaling, so no precision is lost to
    integer rounding; integer inputs are clipped to [0, 1] afterwards because
    float rounding of the weights can overshoot 1 slightly. A float32 gray
    image is returned without a copy when it is already C-contiguous.

    Parameters
    ----------
    image : (H, W), (H, W, 1), (H, W, 2), (H, W, 3) or (H, W, 4) numeric array
        The caller checks the dtype and shape (see ``Sequence.raw_frame`` and
        ``nrmlc.tracker.algorithm.as_gray_frame``).

    Returns
    -------
    frame : (H, W) float32
    """
    if image.ndim == 3 and image.shape[2] in (1, 2):  # gray, or gray + alpha (the alpha is of no use)
        image = image[:, :, 0]
    scale = _INTEGER_SCALE.get(image.dtype)
    gray = image.astype(np.float32, copy=False)
    if scale is not None:
        gray = gray * np.float32(scale)
    if gray.ndim == 3:
        code = cv2.COLOR_BGR2GRAY if gray.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        gray = cv2.cvtColor(np.ascontiguousarray(gray), code)
        if scale is not None:
            np.clip(gray, 0.0, 1.0, out=gray)
    return np.ascontiguousarray(gray)


# ------------------------------------------------------- C libraries' messages
_native_lock = threading.RLock()
_native_fd: int | None = None
_native_pid: int | None = None


@contextlib.contextmanager
def native_messages():
    """Collect what C libraries (libjpeg, libpng, FFmpeg) write to file descriptor 2 in the block.

    Yields a list that holds their lines once the block ends; nothing of
    theirs reaches the terminal, so our one-line error or warning stands
    alone. Python's own ``sys.stderr`` is flushed first and is not affected
    except for its writes inside the block (which are collected too). A lock
    keeps threads of one process from redirecting at once (each would
    restore the other's redirection). Cost: about 13 us per use on Linux,
    against 2-5 ms per frame for tracking.

    Where file descriptor 2 cannot be redirected (no real descriptor), the
    block runs as it is and the list stays empty.
    """
    global _native_fd, _native_pid
    messages: list[str] = []
    with _native_lock:
        try:
            if _native_fd is None or _native_pid != os.getpid():  # a forked child gets its own
                _native_fd = _anonymous_file()
                _native_pid = os.getpid()
            sys.stderr.flush()
            saved = os.dup(2)
        except (OSError, ValueError, AttributeError):
            yield messages
            return
        try:
            os.dup2(_native_fd, 2)
            yield messages
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            size = os.lseek(_native_fd, 0, os.SEEK_CUR)
            if size:
                os.lseek(_native_fd, 0, os.SEEK_SET)
                text = os.read(_native_fd, min(size, 65536)).decode("utf-8", errors="replace")
                messages.extend(line.strip() for line in text.splitlines() if line.strip())
                os.ftruncate(_native_fd, 0)
                os.lseek(_native_fd, 0, os.SEEK_SET)


def _anonymous_file() -> int:
    """A file descriptor of a file with no name (nothing to leave behind)."""
    if hasattr(os, "memfd_create"):
        return os.memfd_create("nrmlc-native-stderr")
    fd, name = tempfile.mkstemp(prefix=".tmp-nrmlc-stderr-")
    os.unlink(name)
    return fd


def native_summary(messages: list[str]) -> str:
    """The C library's lines as one short clause for our messages."""
    text = "; ".join(dict.fromkeys(messages))  # in order, without repeats
    return text if len(text) <= 200 else text[:197] + "..."


def as_gray_frame(image: np.ndarray) -> np.ndarray:
    """Any numpy image (gray, gray+alpha, BGR, BGRA; uint8, uint16 or float) as a C-contiguous
    float32 gray frame. Intensity scale does not matter: patches are normalised.

    Returns
    -------
    frame : (height, width) float32
    """
    if _is_pil_image(image):
        # PIL images are RGB (got10k's Tracker.track passes them): let PIL make the gray.
        image = np.asarray(image.convert("L") if image.mode not in ("L", "I;16", "I", "F") else image)
    if not isinstance(image, np.ndarray):
        raise ParameterError(f"frame must be a numpy array or a PIL image, got {type(image).__name__}")
    channels = image.shape[2] if image.ndim == 3 else 1
    if image.ndim not in (2, 3) or channels not in (1, 2, 3, 4) or image.shape[0] < 2 or image.shape[1] < 2:
        raise ParameterError(f"frame must be a gray or BGR(A) image of at least 2x2 pixels, got shape {image.shape}")
    if not np.issubdtype(image.dtype, np.number) or np.issubdtype(image.dtype, np.complexfloating):
        raise ParameterError(f"frame has unsupported dtype {image.dtype}")
    if image.dtype.kind == "f" and image.dtype.itemsize > 4:
        # Checked before float32 would turn a finite 1e300 into inf (with numpy's overflow warning).
        if not np.all(np.isfinite(image)):
            raise ParameterError("frame contains NaN or infinite values")
        largest = float(np.abs(image).max())
        if largest > float(np.finfo(np.float32).max):
            raise ParameterError(f"frame values reach {largest:.3g}, beyond float32's range (3.4e38); "
                                 f"scale the image")
    frame = to_gray_float32(image)
    if not np.all(np.isfinite(frame)):
        raise ParameterError("frame contains NaN or infinite values")
    return frame


def _is_pil_image(image) -> bool:
    """True for a PIL.Image without importing PIL (it is not a dependency)."""
    return type(image).__module__.startswith("PIL.") and hasattr(image, "convert") and hasattr(image, "mode")
