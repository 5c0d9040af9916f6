"""The versions that produced an output, recorded in ``placement.json`` and the manifest.

The same seed gives byte-identical output only with the same versions of the numeric
libraries below: the committed lock (``pylock.toml``) pins them for ``make``, and every output
says which ones made it. Read from the installed distributions' metadata, so nothing heavy
(open3d, cv2) is imported for it.
"""

from __future__ import annotations

import functools
from importlib import metadata

from . import __version__

__all__ = ["DEPENDENCIES", "versions"]

#: Distributions whose versions are recorded: the ones whose arithmetic reaches the output.
DEPENDENCIES = ("numpy", "open3d", "shapely", "opencv-python-headless", "trimesh", "scipy", "numba")


@functools.cache
def versions() -> dict[str, str]:
    """``{"aerial-synth": ..., "numpy": ..., ...}``; a distribution that is not installed
    (or is installed under another name, e.g. a source build of OpenCV) reads ``"absent"``."""
    out = {"aerial-synth": __version__}
    for name in DEPENDENCIES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "absent"
    return out
