"""Cycles' light passes: the image split by the first scattering event of each camera path.

Cycles (``kernel/film/light_passes.h``) writes what a camera path sees to one of these passes:

* ``emission``, ``environment``: emitters (lights, emissive surfaces and volumes) and the world
  seen directly, through transparent surfaces only;
* ``diffuse_*``, ``glossy_*``, ``transmission_*``: light that reached the camera by a scattering
  event at its first surface, by that event's kind (diffuse, translucent, sheen and subsurface
  closures are diffuse; glossy closures and the reflection of glass are glossy; the refraction of
  glass is transmission), ``direct`` where it came from an emitter or the world straight to that
  surface, ``indirect`` otherwise;
* ``volume_direct``, ``volume_indirect``: the same for a first scattering event in a volume;
* ``diffuse_color``, ``glossy_color``, ``transmission_color``: the albedos of those kinds of
  closures at the first surface (through transparent surfaces, with what they let through).

The image is their sum, each direct or indirect pass times its colour.  Cycles writes the light
passes divided by their colour (:func:`divide_even_color`), and so does this module.

Here the camera paths end at a measurement point (their first non-delta vertex) after a chain of
delta events (mirrors, glass): a point with no delta event before it splits its photons by the
lobe that gathers them and by whether they are at their first vertex (direct: straight from the
emitter); a point behind a mirror or glass gives all its photons to the indirect pass of the kind
of the first delta event (``via``).  Emission seen through delta chains goes to that kind's
direct pass after one event, to its indirect pass after more.
"""
from __future__ import annotations

import numpy as np

# The passes photons add to, those the eye passes alone make, and the colours.
PHOTON_PASSES = ("diffuse_direct", "diffuse_indirect", "glossy_direct", "glossy_indirect",
                 "transmission_direct", "transmission_indirect", "volume_direct", "volume_indirect")
EYE_PASSES = ("emission", "environment")
COLOR_PASSES = ("diffuse_color", "glossy_color", "transmission_color")
LIGHT_PASSES = PHOTON_PASSES + EYE_PASSES + COLOR_PASSES
# A light group's pass (Cycles' Combined_<name>, RenderSettings.data_passes): this and its name.
LIGHTGROUP_PREFIX = "lightgroup:"
# The first scattering event of a camera path (MeasurementPoints.via): none yet, or the kind of its
# first delta event.
VIA_NONE, VIA_GLOSSY, VIA_TRANSMISSION = 0, 1, 2
_VIA_KIND = {VIA_GLOSSY: "glossy", VIA_TRANSMISSION: "transmission"}


def colour_of(name):
    """The colour pass a light pass is divided by (``diffuse_direct`` -> ``diffuse_color``), or None."""
    kind = name.split("_")[0]
    divided = kind in ("diffuse", "glossy", "transmission") and name in PHOTON_PASSES
    return f"{kind}_color" if divided else None


def wanted(names):
    """The light passes among ``names`` and what they need: (photon passes, eye passes, colours)
    each a tuple in this module's order; a divided pass needs its colour."""
    names = set(names)
    photon = tuple(n for n in PHOTON_PASSES if n in names)
    # (emission reaches the eye through delta events, glossy or transmission, or none)
    eye = tuple(n for n in PHOTON_PASSES[2:6] + EYE_PASSES if n in names)
    colours = tuple(c for c in COLOR_PASSES if c in names or any(colour_of(n) == c for n in photon))
    return photon, eye, colours


def light_groups(names, groups):
    """The light group passes among ``names`` (``LIGHTGROUP_PREFIX`` + a name) and, per group of
    ``groups`` (``Scene.light_groups``), the index of its pass among them or -1: (passes (tuple),
    blocks (len(groups),) int64).  Raises ValueError for a group the scene does not have."""
    passes = tuple(dict.fromkeys(n for n in names if n.startswith(LIGHTGROUP_PREFIX)))
    groups = tuple(groups)
    blocks = np.full(len(groups), -1, np.int64)
    for k, name in enumerate(passes):
        group = name[len(LIGHTGROUP_PREFIX):]
        if group not in groups:
            raise ValueError(f"the data pass {name!r} asks for a light group the scene does not have "
                             f"(its light groups: {', '.join(groups) or 'none'})")
        blocks[groups.index(group)] = k
    return passes, blocks


def photon_groups(groups, prob, blocks):
    """(derived, live): the light group pass whose photons' pairs need no copies (``DepositTarget``:
    it is what the points gathered less the other passes and the photons of no group asked for),
    or -1: that of the most photons (``prob`` (E,), each emitter's chance to send one; ``groups``
    (E,) their light groups, -1 none; ``blocks`` :func:`light_groups`'s), when it has more than
    the emitters in no pass together (a scene lit by one group's emitters then copies no pair);
    and the passes (int64 array) whose groups have emitters that send photons (the others have
    no pairs)."""
    if len(prob) == 0 or not (blocks >= 0).any():
        return -1, np.zeros(0, np.int64)
    passes = np.where(groups >= 0, blocks.take(np.maximum(groups, 0)), -1)
    share = np.bincount(passes + 1, weights=prob, minlength=int(blocks.max()) + 2)
    k = int(np.argmax(share[1:]))
    live = np.flatnonzero(share[1:] > 0)
    return (k if share[k + 1] > share[0] else -1), live


def divide_even_color(a, b):
    """``a / b`` per channel as Cycles' ``safe_divide_even_color`` (``util/color.h``): 0 where ``b``
    is 0, except that a channel whose ``b`` is 0 takes the mean of the other two quotients (or the
    one quotient left, where two are 0), so that a pass stays grey.  a, b: (..., 3)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    shape = np.broadcast_shapes(a.shape, b.shape)
    a, b = np.broadcast_to(a, shape).reshape(-1, 3), np.broadcast_to(b, shape).reshape(-1, 3)
    zero = b == 0
    out = np.where(zero, 0.0, a / np.where(zero, 1.0, b))
    count = zero.sum(axis=1)
    rows = np.flatnonzero((count == 1) | (count == 2))      # (only these need more than a quotient)
    if len(rows):
        q = np.where(zero[rows], 0.0, out[rows])
        x, y, z = q[:, 0], q[:, 1], q[:, 2]
        zx, zy, zz = zero[rows, 0], zero[rows, 1], zero[rows, 2]
        first_zero = [zx & zy, zx & zz, zx]
        out[rows] = np.stack([np.select(first_zero, [z, y, 0.5 * (y + z)], x),
                              np.select(first_zero + [zy & zz, zy], [z, y, y, x, 0.5 * (x + z)], y),
                              np.select(first_zero + [zy & zz, zy, zz], [z, y, z, x, z, 0.5 * (x + y)], z)],
                             axis=1)
    return out.reshape(shape)


class EyeLight:
    """The eye pass's part of the light passes: emission and the world seen by camera paths, by
    the paths' first scattering event, and the colour passes at their first surfaces.  ``sums``:
    name -> (n_pixels, 3) arrays this eye pass adds to (those asked for; float32 is enough for one
    pass's values, and at 1920 x 1080 each such array is 25 MB).  A call's pixels are those of
    distinct camera paths, one path per pixel: no pixel twice."""

    def __init__(self, sums, groups=None):
        """``groups``: None, or the light group passes in ``sums`` and the index of each of the
        scene's light groups among them (-1: not asked for), as :func:`light_groups` returns them."""
        self.sums = sums
        self.group_blocks = None
        self.group_sums = ()
        if groups is not None and groups[0]:
            self.group_blocks = groups[1]
            self.group_sums = [sums[name] for name in groups[0]]

    @property
    def has_groups(self) -> bool:
        """Whether some light group's pass is asked for."""
        return self.group_blocks is not None

    def add_group(self, pix, value, group):
        """Camera paths of pixels ``pix`` (k,) see ``value`` (k, 3) of emitters of light groups
        ``group`` (an int for all, or (k,); -1: none)."""
        if self.group_blocks is None:
            return
        if np.ndim(group) == 0:
            k = self.group_blocks[group] if group >= 0 else -1
            if k >= 0:
                self.group_sums[k][pix] += value
            return
        for g in np.flatnonzero(self.group_blocks >= 0):
            sel = np.flatnonzero(group == g)
            if len(sel):
                self.group_sums[self.group_blocks[g]][pix.take(sel)] += value.take(sel, axis=0)

    def add_split(self, pix, weight, split):
        """As :meth:`add_group` for ``split`` (G, k, 3): per light group of the scene, what the paths
        see of its emitters (before their weights ``weight`` (k, 3))."""
        for g in np.flatnonzero(self.group_blocks >= 0):
            lit = np.flatnonzero(split[g].any(axis=1))
            if len(lit):
                total = self.group_sums[self.group_blocks[g]]
                total[pix.take(lit)] += weight.take(lit, axis=0) * split[g, lit]

    def add(self, pix, value, depth, via=None, background=False):
        """Camera paths of pixels ``pix`` (k,) see ``value`` (k, 3) after ``depth`` delta events,
        the first of kinds ``via`` (k,) (none at depth 0); ``background``: the world."""
        if depth == 0:
            total = self.sums.get("environment" if background else "emission")
            if total is not None:
                total[pix] += value
            return
        part = "_direct" if depth == 1 else "_indirect"
        for code, kind in _VIA_KIND.items():
            total = self.sums.get(kind + part)
            if total is None:
                continue
            sel = np.flatnonzero(via == code)
            if len(sel):
                total[pix.take(sel)] += value.take(sel, axis=0)

    @property
    def colours(self):
        """The colour passes asked for (names)."""
        return tuple(c for c in COLOR_PASSES if c in self.sums)

    def add_colours(self, pix, albedos):
        """Camera paths of pixels ``pix`` met their first surface: ``albedos`` name -> (k, 3),
        what the surface's closures of each kind reflect or transmit, times the paths' weights."""
        for name, value in albedos.items():
            if name in self.sums:
                self.sums[name][pix] += value
