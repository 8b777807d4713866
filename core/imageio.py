"""Image files: EXR through OpenEXR (linear float), PNG through matplotlib (display-referred).

Both imports are lazy: Blender writes its own images and needs neither.
"""
from __future__ import annotations

import numpy as np


def write_exr(path, rgba, layers=None):
    """Write (H, W, 4) linear RGBA, top row first, as a 32-bit float ZIP-compressed EXR; ``layers``
    (name -> (H, W) or (H, W, C) images, e.g. ``RenderResult.data``) beside it as channels
    ``name.R``, ``name.G``, ``name.B`` (and ``name.A``) of three- and four-channel images, ``name.V``
    of one-channel ones and ``name.0``, ``name.1``, ... of others."""
    import OpenEXR
    channels = {"RGBA": np.ascontiguousarray(rgba, np.float32)}
    for name, image in (layers or {}).items():
        image = np.asarray(image, np.float32)
        if image.ndim == 2:
            image = image[:, :, None]
        suffixes = "RGBA"[:image.shape[2]] if image.shape[2] in (3, 4) else (
            "V" if image.shape[2] == 1 else [str(i) for i in range(image.shape[2])])
        for i, suffix in enumerate(suffixes):
            channels[f"{name}.{suffix}"] = np.ascontiguousarray(image[:, :, i])
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, channels) as f:
        f.write(str(path))


def read_exr(path):
    """(H, W, 4) float32 RGBA of the first part of an EXR (RGB files get alpha 1)."""
    import OpenEXR
    with OpenEXR.File(str(path)) as f:
        ch = f.channels()
        if "RGBA" in ch:
            return np.asarray(ch["RGBA"].pixels, np.float32)
        rgb = np.asarray(ch["RGB"].pixels, np.float32)
        return np.concatenate([rgb, np.ones(rgb.shape[:2] + (1,), np.float32)], axis=2)


def linear_to_srgb(x):
    """The sRGB transfer curve of linear values ``x`` (>= 0), same shape."""
    x = np.asarray(x)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.maximum(x, 0.0031308) ** (1 / 2.4) - 0.055)


def to_display(rgba, exposure=0.0):
    """Linear RGBA to 8-bit-ready sRGB in [0, 1]: exposure, clip, the sRGB transfer curve."""
    rgb = np.clip(np.asarray(rgba, np.float64)[..., :3] * 2.0 ** exposure, 0.0, 1.0)
    srgb = linear_to_srgb(rgb)
    alpha = np.clip(np.asarray(rgba, np.float64)[..., 3:4], 0.0, 1.0)
    return np.concatenate([srgb, alpha], axis=-1)


def write_png(path, rgba, exposure=0.0):
    """Write a display-referred sRGB PNG (standard view, clipped) of linear RGBA."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.image
    matplotlib.image.imsave(str(path), to_display(rgba, exposure))
