"""Shared numba settings for every compiled kernel of the package.

Importing this module picks the threading layer (OpenMP, then numba's own work queue; TBB
last, since an old system TBB only raises a warning) before any parallel kernel runs.
"""

from __future__ import annotations

from numba import config

__all__ = ["KERNEL_OPTIONS"]

if config.THREADING_LAYER == "default":
    config.THREADING_LAYER_PRIORITY = ["omp", "workqueue", "tbb"]

#: Options of every ``@njit``: disk cache, no GIL, IEEE arithmetic (bit-reproducible).
KERNEL_OPTIONS = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")
