"""The camera's own compiled ray generator (numba), used by :meth:`Camera.pixel_rays`.

Separate from :mod:`aerial_synth.camera` so that importing the camera model stays light
(numba is loaded on the first full-frame ray request), and separate from the renderer's
kernels so the camera depends on no later stage.
"""

from __future__ import annotations

from numba import njit, prange

from .numba_setup import KERNEL_OPTIONS

__all__ = ["grid_rays"]


@njit(parallel=True, **KERNEL_OPTIONS)
def grid_rays(center, rot, x, y, out):  # pragma: no cover - compiled
    """Fill ``out`` (h * w, 6) float32 with rays through every pixel centre, row-major.

    center : (3,) float32 camera centre, metres, world
    rot    : (3, 3) float32 camera-to-world rotation
    x      : (w,) float32 normalised image x of each column; y : (h,) float32 of each row
    The origin is ``center`` and the direction rot @ (x[col], y[row], 1), computed with the
    float32 operations of :meth:`aerial_synth.camera.Camera.pixel_rays` in the same order,
    so both give identical bits. Rows are independent: the result does not depend on the
    number of threads.
    """
    h = y.shape[0]
    w = x.shape[0]
    for r in prange(h):
        for c in range(w):
            i = r * w + c
            out[i, 0] = center[0]
            out[i, 1] = center[1]
            out[i, 2] = center[2]
            for k in range(3):
                out[i, 3 + k] = (rot[k, 0] * x[c] + rot[k, 1] * y[r]) + rot[k, 2]
