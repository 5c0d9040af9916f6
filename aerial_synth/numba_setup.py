"""Shared numba settings for every compiled kernel of the package.

Importing this module picks the threading layer (OpenMP, then numba's own work queue; TBB
last, since an old system TBB only raises a warning) before any parallel kernel runs.
"""

from __future__ import annotations

import os

# OpenMP worker threads busy-wait after every parallel region by default. With more busy
# threads than cores (other workers or processes, Embree's own threads in the next stage)
# the spinning takes the cores from the work that follows: on a loaded 2-core machine a
# frame cost 2.46x the bare primary cast with spinning, 1.84x without. Set before numba
# loads libgomp (at the first parallel kernel); a value already set is kept.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from numba import config  # noqa: E402

__all__ = ["KERNEL_OPTIONS"]

if config.THREADING_LAYER == "default":
    config.THREADING_LAYER_PRIORITY = ["omp", "workqueue", "tbb"]

#: Options of every ``@njit``: disk cache, no GIL, IEEE arithmetic (bit-reproducible).
KERNEL_OPTIONS = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")
