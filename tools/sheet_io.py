"""Shared by the contact-sheet scripts in tools/: write an RGB sheet as a small PNG."""

from __future__ import annotations

import cv2
import numpy as np

from aerial_synth.io_utils import atomic_write_bytes


def save_sheet_png(sheet_rgb: np.ndarray, out) -> int:
    """Write ``sheet_rgb`` (H, W, 3) uint8 RGB to ``out`` atomically; returns the byte count.

    The two lowest bits of every channel are set to 0b10 (invisible at sheet size) so that
    the PNG stays around a megabyte."""
    sheet = (sheet_rgb & 0xFC) | 0x02
    ok, enc = cv2.imencode(".png", sheet[..., ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 9])
    if not ok:  # pragma: no cover - OpenCV failure
        raise RuntimeError("PNG encoding failed")
    data = enc.tobytes()
    atomic_write_bytes(out, data)
    print(f"wrote {out} ({len(data) / 1e6:.2f} MB)")
    return len(data)
