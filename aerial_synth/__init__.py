"""aerial-synth: synthetic nadir aerial images of vehicles with exact oriented-box labels.

The public API is small and imported lazily so ``aerial-synth --help`` stays instant.
"""

from __future__ import annotations

__version__ = "0.2.0"

__all__ = ["__version__"]
