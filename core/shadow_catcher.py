"""Cycles' shadow catcher: objects that show only the shadows and light the others cast on them.

Cycles (``kernel/integrator/intersect_closest.h``, ``film/light_passes.h``, ``film/read.h``) splits
a camera path at its first hit on a catcher object (reached directly or through transparent
surfaces; a holdout is none): the path goes on as usual and writes Combined, while a copy sees
only the catcher objects (the lights and the world still light it) and writes the catcher's own
light, K.  What the paths bring before the split, and paths that meet no catcher first, also go
to the matte, M (a catcher hit counts as transparent there, with the path's throughput).  With
C - M the light of the split paths in the whole scene, a pixel's shadow is (C - M) / K per channel
(1 where no path met a catcher or K is 0), alpha-overed on white by Combined's alpha, and that is
the Shadow Catcher pass.  Combined becomes the matte: with the Shadow Catcher pass asked for, the
matte and its alpha a alone; without it, Cycles' approximate shadow catcher: on a transparent film
the matte with the shadow as alpha, (1 - a)(1 - mean shadow) + a, on an opaque film the matte over
the world seen through the catcher, (M + B (1 - that alpha), 1), B the world along the camera
rays that met a catcher or nothing (all checked against Blender 5.0's Cycles).

Here the eye pass marks the camera paths that met a catcher first (``MeasurementPoints.caught``):
their points' photons and the emission they see after the split make the light pass
``CATCHER_HIT`` (C - M, taken by the Accumulator as Cycles' light passes are), their throughput at
the catcher ``CATCHER_WEIGHT`` and the world along their rays ``CATCHER_BACKGROUND``.  K comes
from a second render (``integrator.CatcherRender``) of a scene of the catcher triangles and the
emissive ones alone, lit by the same lights and world, at the main render's points on the catchers
(their rays traced again, from just before the catcher, where the paths went on through a mirror
or glass catcher), with the same radii and edge coverage: the kernels' bias of the two largely
cancels in the ratio.  Its photons are the main render's uniform ones (the same numbers, sent from
the main scene's box), so that where nothing came between the two gather the same photons; with
the Markov chains the numerator of the ratio is those uniform photons traced in the main scene.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scene import SHADOW_CATCHER

# The light pass of the camera paths that met a catcher first (C - M, RenderSettings' data passes
# do not name it: the integrator asks for it), their throughput at the catcher (n_pixels,), and the
# world along the camera rays that met a catcher or nothing (n_pixels, 3); and Cycles' pass.
CATCHER_HIT = "catcher:hit"
CATCHER_WEIGHT = "catcher:weight"
CATCHER_BACKGROUND = "catcher:background"
SHADOW_CATCHER_PASS = "shadow_catcher"
# K's camera rays start this share of their distance to the catcher before it (at least
# START_MIN of the scene's extent).
START_BACK, START_MIN = 1e-4, 1e-6


@dataclass
class CatcherRays:
    """The camera rays of one eye pass whose first hit was a catcher and whose paths went on through
    its mirror or glass lobes (``integrator.CatcherRender`` traces them again)."""

    pixel_ids: np.ndarray   # (c,) int64
    origins: np.ndarray     # (c, 3) float64 where the ray started
    dirs: np.ndarray        # (c, 3) float64 unit
    t: np.ndarray           # (c,) float64 distance to the catcher
    footprint: np.ndarray   # (c,) float64 the camera ray's footprint (eye_pass radii)

    @property
    def count(self) -> int:
        return int(len(self.pixel_ids))

    @staticmethod
    def concatenate(parts) -> "CatcherRays":
        if not parts:
            return CatcherRays(np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0),
                               np.zeros(0))
        return CatcherRays(*(np.concatenate([getattr(p, f) for p in parts])
                             for f in CatcherRays.__dataclass_fields__))


def catcher_scene(scene, keep):
    """The scene K is rendered in: the triangles ``keep`` ((T,) bool: the catchers' and the
    emissive ones, whose light Cycles' catcher paths still sample), none of them a catcher any
    more; the lights and the world as they are."""
    out = scene.take_triangles(keep)
    if out.triangle_visibility is not None:
        out.triangle_visibility = out.triangle_visibility & np.uint8(~SHADOW_CATCHER & 0xFF)
    return out


def compose(image, hit, hit_raw, catcher, weight, background, shadow_pass, film_transparent):
    """Cycles' Combined and Shadow Catcher pass of a render with catchers (module docstring).

    image : (n, 4) the render's image (every object as it is); hit, hit_raw : (n, 3) its light of
    the paths that met a catcher first (C - M) with the image's bias correction and without;
    catcher : (n, 3) K (without); weight : (n,) those paths' mean throughput at their catchers;
    background : (n, 3) the world along the camera rays that met a catcher or nothing;
    shadow_pass : whether the Shadow Catcher pass is asked for (then Combined is the matte alone,
    its alpha without the shadow, as Cycles'); film_transparent : the film's.
    Returns (Combined (n, 4) float32, the Shadow Catcher pass (n, 3) float32).  (In float32, as the
    image: at 1920 x 1080 its temporaries in float64 took 380 MiB.)"""
    f32 = np.float32
    top = np.finfo(f32).max             # (sums beyond float32 stay at its largest, as the image's)
    hit, hit_raw, catcher, weight, background = (np.clip(a, -top, top).astype(f32)
                                                 for a in (hit, hit_raw, catcher, weight, background))
    alpha = image[:, 3].astype(f32)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        ratio = np.where(catcher != 0, hit_raw / catcher, 1.0)
    ratio = np.where((weight[:, None] > 0) & np.isfinite(ratio), ratio, 1.0)
    # (alpha-overed on white by Combined's alpha: 1 where the film shows nothing)
    shadow = (1.0 - alpha)[:, None] + alpha[:, None] * ratio
    matte = np.maximum(image[:, :3] - hit, 0.0)
    # The matte's alpha: a catcher hit is transparent to it, with the path's throughput.
    a = np.clip(alpha - weight, f32(0.0), f32(1.0))
    alpha_matte = (1.0 - a) * (1.0 - np.clip(shadow.mean(axis=1), f32(0.0), f32(1.0))) + a
    out = np.empty_like(image, dtype=f32)
    out[:, :3] = matte
    if shadow_pass:
        out[:, 3] = a
    elif film_transparent:
        out[:, 3] = alpha_matte
    else:
        out[:, :3] += background * (1.0 - alpha_matte)[:, None]
        out[:, 3] = 1.0
    return out, shadow.astype(f32, copy=False)
