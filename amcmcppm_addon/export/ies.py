"""IES light profiles (LM-63 photometric files) as Cycles reads them, tabulated for the core.

Cycles (``intern/cycles/util/ies.cpp``, ``kernel/util/ies.h``) parses the file's candela values
times its candela multiplier, ballast factor and ballast-lamp photometric factor, converts them
with 4 pi / 177.83 (the D65 luminous efficacy: an IES Texture of Strength 1 on a light's Emission
Strength makes candela values into that factor of the light's power), mirrors the angle ranges
the file leaves out (type C: one quadrant, half or all of the horizontal circle; type B:
converted), and looks a direction up with Catmull-Rom interpolation in both angles, 0 outside
the vertical range the file covers.  :func:`tabulate` samples that lookup on the core's regular
grid (``core.scene.Lights.profiles``): 1 degree steps in both angles.
"""
from __future__ import annotations

import math
import re

import numpy as np

CANDELA_TO_WATT = 0.0706650768394      # 4 pi / 177.83, as Cycles
TYPE_C, TYPE_B = 1, 2                   # LM-63 photometric types (A is 3)
GRID = (181, 361)                      # rows: v in [0, pi]; columns: h in [0, 2 pi]


class IESError(ValueError):
    """A file Cycles would not load (it then lights nothing)."""


def parse(text):
    """(type, v_angles, h_angles, intensity (h, v)) in degrees and Cycles' watts per steradian
    scale, from the text of an IES file (``IESFile::parse``)."""
    at = text.find("\nTILT=")
    if at < 0:
        raise IESError("no TILT= line")
    rest = text[at + 1:]
    if rest.startswith("TILT=INCLUDE"):
        numbers = _numbers(rest[len("TILT=INCLUDE"):])
        count = int(numbers[1])
        numbers = numbers[2 + 2 * count:]
    else:
        newline = rest.find("\n")
        if newline < 0:
            raise IESError("nothing after the TILT= line")
        numbers = _numbers(rest[newline + 1:])
    if len(numbers) < 13:
        raise IESError("the photometric header is incomplete")
    factor = numbers[2]
    v_num, h_num, kind = int(numbers[3]), int(numbers[4]), int(numbers[5])
    if kind not in (TYPE_B, TYPE_C):
        raise IESError(f"photometric type {kind} (only B and C are read)")
    factor *= numbers[10] * numbers[11] * CANDELA_TO_WATT
    body = numbers[13:]
    if v_num < 1 or h_num < 1 or len(body) < v_num + h_num + v_num * h_num:
        raise IESError("fewer angles or candela values than the header announces")
    v = np.array(body[:v_num], np.float64)
    h = np.array(body[v_num:v_num + h_num], np.float64)
    values = np.array(body[v_num + h_num:v_num + h_num + v_num * h_num], np.float64)
    return kind, v, h, (factor * values).reshape(h_num, v_num)


NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def _numbers(text):
    # Cycles replaces commas by spaces and reads numbers with strtod.
    return [float(x) for x in NUMBER.findall(text.replace(",", " "))]


def process(kind, v, h, intensity):
    """(v_angles, h_angles, intensity (h, v)) in radians over Cycles' ranges (``IESFile::process``)."""
    v, h, intensity = list(v), list(h), [list(row) for row in intensity]
    if kind == TYPE_B:
        v, h, intensity = _process_type_b(v, h, intensity)
    else:
        h, intensity = _process_type_c(v, h, intensity)
    v, h = np.radians(np.array(v, np.float64)), np.radians(np.array(h, np.float64))
    if (np.diff(v) <= 0).any() or (np.diff(h) <= 0).any():
        raise IESError("the angles do not increase")
    intensity = np.array(intensity, np.float64)
    if not np.isfinite(intensity).all():
        raise IESError("candela values that are not finite")
    return v, h, intensity


def _process_type_c(v, h, intensity):
    if h[0] == 90.0:
        h = [a - 90.0 for a in h]
    if h[0] != 0.0:
        raise IESError("type C horizontal angles must start at 0 or 90 degrees")
    if len(h) == 1:
        h, intensity = h + [360.0], intensity + [intensity[0]]
    if h[-1] == 90.0:
        for i in range(len(h) - 2, -1, -1):
            h.append(180.0 - h[i])
            intensity.append(intensity[i])
    if h[-1] == 180.0:
        for i in range(len(h) - 2, -1, -1):
            h.append(360.0 - h[i])
            intensity.append(intensity[i])
    if h[-1] != 360.0:
        last, first, gap = h[-1] - h[-2], h[1] - h[0], 360.0 - h[-1]
        if last == gap or first == gap:
            h, intensity = h + [360.0], intensity + [intensity[0]]
        else:
            raise IESError("type C horizontal angles do not close the circle")
    if v[0] == 90.0:
        if v[-1] != 180.0:
            raise IESError("type C vertical angles from 90 degrees must end at 180")
    elif v[0] != 0.0:
        raise IESError("type C vertical angles must start at 0 or 90 degrees")
    return h, intensity


def _process_type_b(v, h, intensity):
    # Type B swaps the roles of the angles; Cycles mirrors and shifts them into type C's ranges.
    intensity = [[intensity[j][i] for j in range(len(h))] for i in range(len(v))]
    h, v = v, h
    if h[-1] != 90.0:
        raise IESError("type B angles must end at 90 degrees")
    if h[0] == 0.0:
        n = len(h)
        h = [90.0 - h[i] for i in range(n - 1, 0, -1)] + [90.0 + h[i] for i in range(n)]
        intensity = [intensity[i] for i in range(n - 1, 0, -1)] + intensity
    elif h[0] == -90.0:
        h = [a + 90.0 for a in h]
    h, intensity = h + [360.0], intensity + [intensity[0]]
    if v[-1] != 90.0:
        raise IESError("type B angles must end at 90 degrees")
    if v[0] == 0.0:
        n = len(v)
        v = [90.0 - v[i] for i in range(n - 1, 0, -1)] + [90.0 + v[i] for i in range(n)]
        intensity = [row[-2::-1] + row for row in intensity]
    elif v[0] == -90.0:
        v = [a + 90.0 for a in v]
    return v, h, intensity


def cubic(a, b, c, d, x):
    """Cycles' ``cubic_interp`` (Catmull-Rom)."""
    return 0.5 * (((d + 3.0 * (b - c) - a) * x + (2.0 * a - 5.0 * b + 4.0 * c - d)) * x + (c - a)) * x + b


def lookup(v_angles, h_angles, intensity, v, h):
    """Cycles' ``kernel_ies_interp`` at angles ``v``, ``h`` (arrays of one shape, radians)."""
    v, h = np.broadcast_arrays(np.asarray(v, np.float64), np.asarray(h, np.float64))
    v_num, h_num = len(v_angles), len(h_angles)
    out = np.zeros(v.shape)
    inside = (v >= v_angles[0]) & (v < v_angles[-1]) & (h >= h_angles[0]) & (h < h_angles[-1])
    if v_num < 2 or h_num < 2 or not inside.any():
        return out
    vi, hi = v[inside], h[inside]
    wrap_h = h_angles[0] < 1e-7 and h_angles[-1] > 2.0 * math.pi - 1e-7
    wrap_vlow, wrap_vhigh = v_angles[0] < 1e-7, v_angles[-1] > math.pi - 1e-7
    h_i = np.minimum(np.searchsorted(h_angles[1:], hi, side="left"), h_num - 2)
    v_i = np.minimum(np.searchsorted(v_angles[1:], vi, side="left"), v_num - 2)
    h_frac = (hi - h_angles[h_i]) / (h_angles[h_i + 1] - h_angles[h_i])
    v_frac = (vi - v_angles[v_i]) / (v_angles[v_i + 1] - v_angles[v_i])

    def vertical(col):
        row = lambda k: intensity[col, k]                               # noqa: E731
        b, c = row(v_i), row(v_i + 1)
        a = np.where(v_i > 0, row(np.maximum(v_i - 1, 0)), row(np.full_like(v_i, 1)) if wrap_vlow else b)
        d = np.where(v_i + 2 < v_num, row(np.minimum(v_i + 2, v_num - 1)),
                     row(np.full_like(v_i, max(v_num - 2, 0))) if wrap_vhigh else c)
        return cubic(a, b, c, d, v_frac)

    b, c = vertical(h_i), vertical(h_i + 1)
    a = np.where(h_i > 0, vertical(np.maximum(h_i - 1, 0)),
                 vertical(np.full_like(h_i, h_num - 2)) if wrap_h else b)
    d = np.where(h_i + 2 < h_num, vertical(np.minimum(h_i + 2, h_num - 1)),
                 vertical(np.full_like(h_i, 1)) if wrap_h else b)
    out[inside] = np.maximum(cubic(a, b, c, d, h_frac), 0.0)
    return out


def tabulate(text):
    """(181, 361) float32: Cycles' lookup of the IES file ``text`` on the core's grid."""
    v_angles, h_angles, intensity = process(*parse(text))
    v = np.linspace(0.0, math.pi, GRID[0])[:, None]
    h = np.linspace(0.0, 2.0 * math.pi, GRID[1])[None, :]
    table = lookup(v_angles, h_angles, intensity, v, h)
    # Cycles' range tests exclude the last angle (v < v_high, h < h_high): the grid's last row
    # and column take the values just inside instead, as a lookup there would find them.
    eps = 1e-6
    table[-1] = lookup(v_angles, h_angles, intensity, math.pi - eps, h[0])
    table[:, -1] = lookup(v_angles, h_angles, intensity, v[:, 0], 2.0 * math.pi - eps)
    return table.astype(np.float32)
