"""Writing a frame's files (atomically): rgb.png, instance.png (16-bit), instance_color.png,
semantic.png, depth.npy (float32 metres) or depth.png (16-bit centimetres), meta.json."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ..errors import RenderError
from ..io_utils import atomic_write_bytes, atomic_write_json

__all__ = ["instance_colors", "write_frame", "encode_png", "DEPTH_FORMATS"]

DEPTH_FORMATS = ("npy", "png")
_MULT = 0x9E3779  # odd: a bijection on 21-bit ids


def instance_colors(instance: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 RGB: black background, a distinct bright colour per vehicle id.

    The colour is a bijection of ``id mod 2**21`` (every channel >= 128), so vehicles in a
    frame never share a colour while ids stay below 2,097,152.
    """
    ids = np.asarray(instance).astype(np.int64)
    code = (ids * _MULT) & 0x1FFFFF
    rgb = np.empty(ids.shape + (3,), np.uint8)
    rgb[..., 0] = 128 | (code & 0x7F)
    rgb[..., 1] = 128 | ((code >> 7) & 0x7F)
    rgb[..., 2] = 128 | ((code >> 14) & 0x7F)
    rgb[ids == 0] = 0
    return rgb


def encode_png(img: np.ndarray) -> bytes:
    """PNG bytes of a (H, W) uint8/uint16 or (H, W, 3) uint8 RGB image (deterministic)."""
    import cv2

    a = np.ascontiguousarray(img)
    if a.ndim == 3:
        a = np.ascontiguousarray(a[..., ::-1])  # OpenCV writes BGR
    ok, buf = cv2.imencode(".png", a, [cv2.IMWRITE_PNG_COMPRESSION, 3])
    if not ok:  # pragma: no cover
        raise RenderError(f"could not encode a PNG of shape {a.shape} dtype {a.dtype}")
    return buf.tobytes()


def _npy_bytes(a: np.ndarray) -> bytes:
    bio = io.BytesIO()
    np.save(bio, np.ascontiguousarray(a), allow_pickle=False)
    return bio.getvalue()


def write_frame(frame, out_dir, depth_format: str = "npy", extra_meta: dict | None = None) -> dict:
    """Write one frame's files into ``out_dir`` (created); return {kind: file name}.

    instance.png holds ids as 16-bit; frames with ids above 65535 get instance.npy
    (uint32) instead. meta.json is written last, so its presence marks a complete frame.
    """
    if depth_format not in DEPTH_FORMATS:
        raise RenderError(
            f"depth format: expected one of {', '.join(DEPTH_FORMATS)}, got {depth_format!r}"
        )
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = {}
    atomic_write_bytes(out / "rgb.png", encode_png(frame.rgb))
    files["rgb"] = "rgb.png"
    if frame.instance.size and int(frame.instance.max()) > 0xFFFF:
        atomic_write_bytes(out / "instance.npy", _npy_bytes(frame.instance.astype(np.uint32)))
        files["instance"] = "instance.npy"
    else:
        atomic_write_bytes(out / "instance.png", encode_png(frame.instance.astype(np.uint16)))
        files["instance"] = "instance.png"
    atomic_write_bytes(out / "instance_color.png", encode_png(instance_colors(frame.instance)))
    files["instance_color"] = "instance_color.png"
    atomic_write_bytes(out / "semantic.png", encode_png(frame.semantic.astype(np.uint8)))
    files["semantic"] = "semantic.png"
    if depth_format == "npy":
        atomic_write_bytes(out / "depth.npy", _npy_bytes(frame.depth.astype(np.float32)))
        files["depth"] = "depth.npy"
    else:
        cm = np.clip(np.round(frame.depth.astype(np.float64) * 100.0), 0, 65535).astype(np.uint16)
        atomic_write_bytes(out / "depth.png", encode_png(cm))
        files["depth"] = "depth.png"
    meta = frame.to_meta()
    meta["files"] = dict(files)
    if depth_format == "png":
        meta["depth"] = "z-depth along the optical axis in centimetres (uint16); 0 = nothing hit"
    if extra_meta:
        meta.update(extra_meta)
    atomic_write_json(out / "meta.json", meta)
    files["meta"] = "meta.json"
    return files
