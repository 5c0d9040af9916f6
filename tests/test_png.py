"""aerial_synth.png: the exported frames' PNG encoder (Average filter + ISA-L deflate)."""

from __future__ import annotations

import io
import struct
import zlib

import numpy as np
import pytest

from aerial_synth import png


def _images():
    rng = np.random.default_rng(11)
    noisy = rng.integers(0, 256, (37, 53, 3), dtype=np.uint8)
    smooth = np.zeros((40, 64, 3), np.uint8)
    smooth[..., 0] = np.arange(64, dtype=np.uint8)[None, :] * 4
    smooth[..., 1] = np.arange(40, dtype=np.uint8)[:, None] * 6
    smooth[..., 2] = 200
    extremes = np.where(rng.random((9, 7, 3)) < 0.5, 0, 255).astype(np.uint8)
    return [noisy, smooth, extremes, noisy[:1, :1], noisy[:1, :9], noisy[:6, :1]]


def _chunks(data: bytes):
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, out = 8, []
    while pos < len(data):
        (n,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + n]
        (crc,) = struct.unpack(">I", data[pos + 8 + n:pos + 12 + n])
        assert crc == zlib.crc32(kind + body) & 0xFFFFFFFF, kind
        out.append((kind, body))
        pos += 12 + n
    return out


def _unfilter_average(rows: np.ndarray, w: int) -> np.ndarray:
    """The PNG spec's reconstruction of Average-filtered scanlines (a plain reference)."""
    h = rows.shape[0]
    out = np.zeros((h, 3 * w), np.int64)
    for y in range(h):
        assert rows[y, 0] == 3
        for x in range(3 * w):
            left = out[y, x - 3] if x >= 3 else 0
            up = out[y - 1, x] if y > 0 else 0
            out[y, x] = (int(rows[y, x + 1]) + (left + up) // 2) % 256
    return out.reshape(h, w, 3).astype(np.uint8)


@pytest.mark.parametrize("k", range(6))
def test_png_structure_and_pixels_by_the_spec(k):
    """Signature, chunk CRCs, IHDR (8-bit RGB, no interlace), one zlib stream of
    Average-filtered rows that the spec's reconstruction turns back into the image."""
    img = _images()[k]
    h, w = img.shape[:2]
    chunks = _chunks(png.encode_png(img))
    kinds = [c[0] for c in chunks]
    assert kinds[0] == b"IHDR" and kinds[-1] == b"IEND" and set(kinds[1:-1]) == {b"IDAT"}
    assert struct.unpack(">IIBBBBB", chunks[0][1]) == (w, h, 8, 2, 0, 0, 0)
    raw = zlib.decompress(b"".join(body for kind, body in chunks if kind == b"IDAT"))
    rows = np.frombuffer(raw, np.uint8).reshape(h, 3 * w + 1)
    assert np.array_equal(_unfilter_average(rows, w), img)


@pytest.mark.parametrize("k", range(6))
def test_png_decodes_identically_in_opencv_and_pillow(k):
    import cv2
    from PIL import Image

    img = _images()[k]
    data = png.encode_png(img)
    back = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    assert np.array_equal(back[..., ::-1], img)
    assert np.array_equal(np.asarray(Image.open(io.BytesIO(data)).convert("RGB")), img)


def test_png_is_deterministic_and_takes_any_layout():
    """The same pixels give the same bytes, whatever the array's strides."""
    img = _images()[0]
    a = png.encode_png(img)
    assert png.encode_png(img.copy()) == a
    assert png.encode_png(np.asfortranarray(img)) == a
    big = np.zeros((img.shape[0], img.shape[1] * 2, 3), np.uint8)
    big[:, ::2] = img
    assert png.encode_png(big[:, ::2]) == a


def test_png_smaller_than_opencv_fast_settings_on_a_rendered_like_image():
    """The point of the encoder: deflate with matches beats Huffman-only coding on smooth
    content (the speed is measured by tools/bench_png.py, not asserted)."""
    import cv2

    img = np.repeat(_images()[1], 8, axis=0)
    ours = png.encode_png(img)
    ok, theirs = cv2.imencode(".png", img[..., ::-1].copy(), list(png.opencv_png_params()))
    assert ok and len(ours) < len(theirs.tobytes())


def test_png_without_isal_falls_back_to_opencv(monkeypatch):
    import cv2

    monkeypatch.setattr(png, "_isal", lambda: None)
    assert png.backend() == "opencv"
    img = _images()[0]
    back = cv2.imdecode(np.frombuffer(png.encode_png(img), np.uint8), cv2.IMREAD_UNCHANGED)
    assert np.array_equal(back[..., ::-1], img)


@pytest.mark.parametrize("shape", [(4, 4), (4, 4, 4), (0, 5, 3), (4, 0, 3)])
def test_png_refuses_other_shapes(shape):
    with pytest.raises(ValueError, match="RGB"):
        png.encode_png(np.zeros(shape, np.uint8))
