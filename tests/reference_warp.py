"""Slow, obvious numpy reference for the warp kernel (the test oracle)."""
import numpy as np


def warp_patches_reference(frame, affines, patch_size=32):
    """Bilinear sampling with border replication, then unit-norm rows (float64)."""
    frame = np.asarray(frame, dtype=np.float64)
    height, width = frame.shape
    centre = (patch_size - 1) / 2.0
    rows, cols = np.mgrid[0:patch_size, 0:patch_size].astype(np.float64)
    grid = np.stack([cols.ravel() - centre, rows.ravel() - centre])  # (2, P*P)
    out = np.empty((len(affines), patch_size * patch_size))
    for k, matrix in enumerate(affines):
        x, y = matrix[:, :2] @ grid + matrix[:, 2:]
        x = np.clip(x, 0, width - 1)
        y = np.clip(y, 0, height - 1)
        x0 = np.minimum(np.floor(x).astype(int), max(width - 2, 0))
        y0 = np.minimum(np.floor(y).astype(int), max(height - 2, 0))
        x1 = np.minimum(x0 + 1, width - 1)
        y1 = np.minimum(y0 + 1, height - 1)
        fx, fy = x - x0, y - y0
        values = (frame[y0, x0] * (1 - fx) * (1 - fy) + frame[y0, x1] * fx * (1 - fy)
                  + frame[y1, x0] * (1 - fx) * fy + frame[y1, x1] * fx * fy)
        norm = np.linalg.norm(values)
        out[k] = values / norm if norm > 1e-12 else 1.0 / patch_size
    return out
