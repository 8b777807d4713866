"""The world's radiance as a function of direction: a constant, or a constant times an
equirectangular image (Blender's Environment Texture, optionally turned by a rotation: the
Mapping node on its vector).

Directions map to image coordinates as in Cycles (``direction_to_equirectangular``):
u = 1/2 - atan2(y, x) / (2 pi), v = 1 - acos(z) / pi, so the image centre faces +X, v = 1
(the top row; row 0 of the array is the bottom, v = 0) is the zenith.  Radiance is looked
up bilinearly (wrapping in u, clamped in v), as Cycles' default Linear interpolation.

Photons leave the world in directions drawn from the image: a pixel with probability in
proportion to its luminance times its solid angle (plus a small floor, so that no pixel that
can be seen is never emitted from), then a direction uniform in solid angle within the
pixel.  The density is known exactly, so every photon's flux is the radiance over it.
"""
from __future__ import annotations

import numpy as np

from . import sampling as smp
from .bsdf import bilinear

# Share of the pixel choice spread evenly over solid angle, so that dark pixels next to
# bright ones (which bilinear lookups blend in) still get photons.
UNIFORM_SHARE = 0.05


class Environment:
    """Radiance ``color`` x ``texture`` (H, W, 3) by direction; see the module docstring."""

    def __init__(self, color, texture, rotation=None):
        """``rotation`` (3, 3): the image is looked up at rotation @ d (Blender's Mapping node
        on the texture's vector), None for the identity."""
        self.rotation = None if rotation is None else np.asarray(rotation, np.float64)
        self.color = np.asarray(color, np.float64)
        self.texture = np.asarray(texture, np.float64)
        h, w = self.texture.shape[:2]
        self.height, self.width = h, w
        # Pixel rows from the bottom (v = 0, nadir) up: polar angle theta from pi down to 0.
        cos_edges = np.cos(np.pi * (1.0 - np.arange(h + 1) / h))            # (h + 1,) -1 .. 1
        self.cos_lo, self.cos_hi = cos_edges[:-1], cos_edges[1:]
        solid = (2.0 * np.pi / w) * (self.cos_hi - self.cos_lo)              # (h,) per pixel
        radiance = self.texture * self.color                                  # (h, w, 3)
        self.integral = (radiance * solid[:, None, None]).sum(axis=(0, 1))   # (3,) int L dw
        lum = np.maximum(smp.luminance(radiance), 0.0) * solid[:, None]
        total = lum.sum()
        uniform = np.broadcast_to(solid[:, None] / (4.0 * np.pi), (h, w))     # sums to 1
        p = (1.0 - UNIFORM_SHARE) * lum / total + UNIFORM_SHARE * uniform if total > 0 else uniform
        p = p / p.sum()
        self.pixel_prob = p.ravel()
        self.cdf = np.cumsum(self.pixel_prob)
        self.cdf[-1] = 1.0
        self.solid = solid

    # ------------------------------------------------------------------ lookups
    def uv(self, dirs):
        return equirectangular_uv(dirs if self.rotation is None else dirs @ self.rotation.T)

    def radiance(self, dirs):
        """(n, 3) radiance that a ray travelling along the unit directions ``dirs`` (n, 3) meets
        at infinity."""
        u, v = self.uv(dirs)
        return bilinear(self.texture, u, v, clamp_v=True) * self.color

    def pdf(self, dirs):
        """(n,) solid-angle density of :meth:`sample` at ``dirs``."""
        u, v = self.uv(dirs)
        j = np.minimum((np.mod(u, 1.0) * self.width).astype(np.int64), self.width - 1)
        i = np.clip((v * self.height).astype(np.int64), 0, self.height - 1)
        return self.pixel_prob.take(i * self.width + j) / self.solid.take(i)

    # ------------------------------------------------------------------ sampling
    def sample(self, u_pixel, u_a):
        """Unit directions (n, 3) towards the sky (where light arrives from) and their density
        (n,): a pixel by ``u_pixel`` (its remainder places phi within the pixel), cos theta
        within the pixel by ``u_a``."""
        k = np.minimum(np.searchsorted(self.cdf, u_pixel, side="right"), len(self.cdf) - 1)
        before = np.where(k > 0, self.cdf.take(np.maximum(k - 1, 0)), 0.0)
        prob = self.pixel_prob.take(k)
        rest = np.clip((u_pixel - before) / np.where(prob > 0, prob, 1.0), 0.0, 1.0)
        i, j = np.divmod(k, self.width)
        u = (j + rest) / self.width
        cos_t = self.cos_lo.take(i) + u_a * (self.cos_hi.take(i) - self.cos_lo.take(i))
        phi = np.pi - 2.0 * np.pi * u
        sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
        d = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=1)
        if self.rotation is not None:
            d = d @ self.rotation                   # image direction back to the world: R^T d
        return d, prob / self.solid.take(i)


def equirectangular_uv(dirs):
    """Image coordinates (u, v), (n,) each, of directions ``dirs`` (n, 3) (any length; zero: the
    image centre): u = 1/2 - atan2(y, x) / 2 pi, v = 1 - acos(z / |d|) / pi (module docstring)."""
    length = np.sqrt((dirs * dirs).sum(axis=1))
    z = np.where(length > 0, dirs[:, 2] / np.where(length > 0, length, 1.0), 0.0)
    u = 0.5 - np.arctan2(dirs[:, 1], dirs[:, 0]) / (2.0 * np.pi)
    v = 1.0 - np.arccos(np.clip(z, -1.0, 1.0)) / np.pi
    return u, v


def equirectangular_directions(width, height):
    """(height, width, 3) unit directions of the pixel centres of an equirectangular image in the
    layout above (row 0 = the bottom, v = (i + 1/2) / height; u = (j + 1/2) / width): the
    inverse of :func:`equirectangular_uv`."""
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    phi = np.pi - 2.0 * np.pi * u                      # u = 1/2 - phi / 2 pi
    theta = np.pi * (1.0 - v)                          # v = 1 - theta / pi
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    return np.stack([st * np.cos(phi)[None], st * np.sin(phi)[None], np.broadcast_to(ct, (height, width))],
                    axis=-1)
