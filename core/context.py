"""Everything derived once from a scene for tracing: BVH, material table, emitters."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .accel import Accel
from .bsdf import MaterialTable, Textures, lobe_colors
from .lights import LightSampler
from .sampling import normalize


@dataclass
class Surface:
    """Shading data at n surface points."""

    position: np.ndarray    # (n, 3) float64, world
    ng: np.ndarray          # (n, 3) float64 unit geometric normal (front side of the triangle)
    ns: np.ndarray          # (n, 3) float64 unit shading normal (is ng for flat shading without normal maps)
    mat_ids: np.ndarray     # (n,) int32 material index
    colors: np.ndarray      # (n, 4, 3) float64 lobe colours (textured diffuse albedo filled in)
    nn: np.ndarray = None   # (n, 3) float64 shading normal before normal maps; None without normal maps


class RenderContext:
    """Scene plus acceleration structure and shading tables, built once per render/worker."""

    def __init__(self, scene):
        self.scene = scene
        self.accel = Accel(scene)
        self.table = MaterialTable.from_materials(scene.materials)
        self.textures = Textures(scene.textures)
        self.lights = LightSampler(scene, self.accel, self.table)
        # Normal maps: per-material image index (-1: none) and strength.
        self.normal_texture = np.ascontiguousarray(scene.materials.normal_texture, np.int32)
        self.normal_strength = np.asarray(scene.materials.normal_strength, np.float64)
        self.has_normal_maps = bool((self.normal_texture >= 0).any())
        self.has_shading_normals = scene.shading_normals is not None or self.has_normal_maps
        # Per-triangle arrays gathered with take(), which copies a non-contiguous array first.
        self.material_ids = np.ascontiguousarray(scene.material_ids)
        self.shading_normals = (np.ascontiguousarray(scene.shading_normals)
                                if scene.shading_normals is not None else None)
        self.has_textures = bool((self.table.texture >= 0).any())

    def surface(self, prim_ids, b1, b2) -> Surface:
        """Surface data at hits given by triangle ids and barycentrics."""
        a = self.accel
        pos = a.hit_positions(prim_ids, b1, b2)
        ng = a.geometric_normals.take(prim_ids, axis=0)
        b0 = 1.0 - b1 - b2
        mat = self.material_ids.take(prim_ids)
        if self.shading_normals is not None:
            sn = self.shading_normals.take(prim_ids, axis=0).astype(np.float64)
            ns = normalize(b0[:, None] * sn[:, 0] + b1[:, None] * sn[:, 1] + b2[:, None] * sn[:, 2])
            _replace_bad(ns, ng)
        else:
            ns = ng.copy() if self.has_normal_maps else ng
        nn = None
        if self.has_normal_maps:
            nn = ns.copy()
            self._apply_normal_maps(ns, prim_ids, b0, b1, b2, mat)
        albedo = self.table.color[:, 0].take(mat, axis=0)
        if self.has_textures:
            tex = self.table.texture[mat]
            if (tex >= 0).any():
                uv = self.scene.uvs[prim_ids].astype(np.float64)
                uv = b0[:, None] * uv[:, 0] + b1[:, None] * uv[:, 1] + b2[:, None] * uv[:, 2]
                albedo = np.where((tex >= 0)[:, None],
                                  albedo * self.textures.lookup(tex, uv), albedo)
        return Surface(pos, ng, ns, mat, lobe_colors(self.table, mat, albedo), nn)

    def _apply_normal_maps(self, ns, prim_ids, b0, b1, b2, mat):
        """Bend ``ns`` (n, 3) in place where the material has a tangent-space normal map.

        As Cycles' Normal Map node: c = 2 rgb - 1, (c_x, c_y) times the strength s and c_z
        blended from 1 by min(s, 1); N = normalize(c_x T + c_y B + c_z N0) with T the
        interpolated tangent, B = w (N0 x T) and N0 the interpolated shading normal (here unit
        length).  No tangent frame (zero tangent) or a degenerate result keeps N0.
        """
        tex = self.normal_texture.take(mat)
        sel = np.flatnonzero(tex >= 0)
        if len(sel) == 0:
            return
        p = prim_ids.take(sel)
        w0, w1, w2 = b0.take(sel)[:, None], b1.take(sel)[:, None], b2.take(sel)[:, None]
        uv = self.scene.uvs.take(p, axis=0).astype(np.float64)
        uv = w0 * uv[:, 0] + w1 * uv[:, 1] + w2 * uv[:, 2]
        tg = self.scene.tangents.take(p, axis=0).astype(np.float64)
        tg = w0 * tg[:, 0] + w1 * tg[:, 1] + w2 * tg[:, 2]                  # (k, 4): xyz and sign
        c = 2.0 * self.textures.lookup(tex.take(sel), uv) - 1.0
        s = self.normal_strength.take(mat.take(sel))
        n0 = ns.take(sel, axis=0)
        t = tg[:, :3]
        b = tg[:, 3:4] * np.cross(n0, t)
        cz = 1.0 + (c[:, 2] - 1.0) * np.minimum(s, 1.0)
        n = normalize((c[:, 0] * s)[:, None] * t + (c[:, 1] * s)[:, None] * b + cz[:, None] * n0)
        no_frame = ~(np.abs(t).sum(axis=1) > 0)
        n[no_frame] = n0[no_frame]
        _replace_bad(n, n0)
        ns[sel] = n


def _replace_bad(n, fallback):
    """Rows of ``n`` that are zero or NaN (e.g. after interpolation or normalising) take ``fallback``'s."""
    # Columns: sum(axis=1) is slow for (n, 3).
    bad = np.flatnonzero(~(np.abs(n[:, 0]) + np.abs(n[:, 1]) + np.abs(n[:, 2]) > 0))
    n[bad] = fallback[bad]
