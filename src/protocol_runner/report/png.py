"""A rendered figure's pixels as PNG bytes: 8-bit RGB (RGBA when a pixel is not opaque), no row filter, the
image data deflated by ISA-L at level 1 (the `isal` package: the standard zlib stream PNG specifies, written
several times faster than zlib's level 1), the resolution in a `pHYs` chunk and nothing else (no time or
software tag: the same pixels give the same bytes).

Lossless like matplotlib's own PNG output (Pillow's), and much faster to encode: the report's figures are
opaque, so the alpha channel is dropped, and Pillow's per-row filter search buys little on flat plot
images.
"""

from __future__ import annotations

import struct
import zlib

import numpy as np
from isal import isal_zlib

SIGNATURE = b"\x89PNG\r\n\x1a\n"
INCH_M = 0.0254


def _chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def _opaque(rgba: np.ndarray) -> bool:
    """Whether every pixel's alpha is 255 (read as little-endian 32-bit words: alpha is the high byte)."""
    if rgba.flags.c_contiguous:
        return bool((rgba.view("<u4") >= 0xFF000000).all())
    return bool((rgba[..., 3] == 0xFF).all())


def png_bytes(rgba: np.ndarray, dpi: float) -> bytes:
    """Encode an (height, width, 4) uint8 RGBA image, top row first, at `dpi` dots per inch."""
    height, width, _ = rgba.shape
    opaque = _opaque(rgba)
    channels = 3 if opaque else 4
    rows = np.empty((height, 1 + width * channels), dtype=np.uint8)
    rows[:, 0] = 0  # filter type 0 (none) on every row
    pixels = rows[:, 1:].reshape(height, width, channels)
    for channel in range(channels):  # one byte-strided copy each: several times faster than one RGB copy
        pixels[..., channel] = rgba[..., channel]
    header = struct.pack(">IIBBBBB", width, height, 8, 2 if opaque else 6, 0, 0, 0)
    per_metre = int(dpi / INCH_M + 0.5)
    return b"".join(
        (
            SIGNATURE,
            _chunk(b"IHDR", header),
            _chunk(b"pHYs", struct.pack(">IIB", per_metre, per_metre, 1)),
            _chunk(b"IDAT", isal_zlib.compress(rows.tobytes(), 1)),
            _chunk(b"IEND", b""),
        )
    )
