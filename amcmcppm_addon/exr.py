"""A minimal OpenEXR writer: single-part scanline, uncompressed, 32-bit float RGBA.

Blender writes its own render output; this is only for images the engine saves
while it renders (snapshots), where no Blender image datablock may be created.
Layout per the OpenEXR file-format document: magic and version, header
attributes, an offset table with one entry per scanline, then each scanline as
(y, byte count, the pixels of every channel in alphabetical order A, B, G, R).
"""
from __future__ import annotations

import struct

import numpy as np

_MAGIC, _VERSION = 20000630, 2
_FLOAT = 2      # OpenEXR pixel type


def _attribute(name, type_name, payload):
    return name.encode() + b"\0" + type_name.encode() + b"\0" + struct.pack("<i", len(payload)) + payload


def write_exr(path, rgba):
    """Write (H, W, 4) linear RGBA, top row first, as an uncompressed float EXR."""
    img = np.asarray(rgba, np.float32)
    if img.ndim != 3 or img.shape[2] != 4:
        raise ValueError(f"expected an (H, W, 4) image, got shape {img.shape}")
    h, w = img.shape[:2]
    channels = b"".join(c.encode() + b"\0" + struct.pack("<iB3xii", _FLOAT, 0, 1, 1) for c in "ABGR") + b"\0"
    box = struct.pack("<4i", 0, 0, w - 1, h - 1)
    header = b"".join([
        struct.pack("<ii", _MAGIC, _VERSION),
        _attribute("channels", "chlist", channels),
        _attribute("compression", "compression", b"\0"),
        _attribute("dataWindow", "box2i", box),
        _attribute("displayWindow", "box2i", box),
        _attribute("lineOrder", "lineOrder", b"\0"),
        _attribute("pixelAspectRatio", "float", struct.pack("<f", 1.0)),
        _attribute("screenWindowCenter", "v2f", struct.pack("<2f", 0.0, 0.0)),
        _attribute("screenWindowWidth", "float", struct.pack("<f", 1.0)),
        b"\0",
    ])
    line_bytes = 4 * 4 * w
    block = 8 + line_bytes
    start = len(header) + 8 * h
    offsets = (start + block * np.arange(h, dtype=np.uint64)).astype("<u8")
    # Each scanline: y, byte count, then the A, B, G and R values of its pixels.
    lines = np.empty((h, block), np.uint8)
    prefix = np.zeros((h, 2), "<i4")
    prefix[:, 0] = np.arange(h)
    prefix[:, 1] = line_bytes
    lines[:, :8] = prefix.view(np.uint8).reshape(h, 8)
    planar = np.ascontiguousarray(img[:, :, [3, 2, 1, 0]].transpose(0, 2, 1), "<f4")   # (H, 4, W)
    lines[:, 8:] = planar.view(np.uint8).reshape(h, line_bytes)
    with open(path, "wb") as f:
        f.write(header)
        f.write(offsets.tobytes())
        f.write(lines.tobytes())
