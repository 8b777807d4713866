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
    ns: np.ndarray          # (n, 3) float64 unit shading normal (equals ng for flat shading)
    mat_ids: np.ndarray     # (n,) int32 material index
    colors: np.ndarray      # (n, 4, 3) float64 lobe colours (textured diffuse albedo filled in)


class RenderContext:
    """Scene plus acceleration structure and shading tables, built once per render/worker."""

    def __init__(self, scene):
        self.scene = scene
        self.accel = Accel(scene)
        self.table = MaterialTable.from_materials(scene.materials)
        self.textures = Textures(scene.textures)
        self.lights = LightSampler(scene, self.accel, self.table)
        self.has_shading_normals = scene.shading_normals is not None
        # Per-triangle arrays gathered with take(), which copies a non-contiguous array first.
        self.material_ids = np.ascontiguousarray(scene.material_ids)
        self.shading_normals = (np.ascontiguousarray(scene.shading_normals) if self.has_shading_normals
                                else None)
        self.has_textures = bool((self.table.texture >= 0).any())

    def surface(self, prim_ids, b1, b2) -> Surface:
        """Surface data at hits given by triangle ids and barycentrics."""
        a = self.accel
        pos = a.hit_positions(prim_ids, b1, b2)
        ng = a.geometric_normals.take(prim_ids, axis=0)
        b0 = 1.0 - b1 - b2
        if self.has_shading_normals:
            sn = self.shading_normals.take(prim_ids, axis=0).astype(np.float64)
            ns = normalize(b0[:, None] * sn[:, 0] + b1[:, None] * sn[:, 1] + b2[:, None] * sn[:, 2])
            # Zero or NaN after interpolation: the geometric normal (columns: sum(axis=1) is slow).
            bad = np.flatnonzero(~(np.abs(ns[:, 0]) + np.abs(ns[:, 1]) + np.abs(ns[:, 2]) > 0))
            ns[bad] = ng[bad]
        else:
            ns = ng
        mat = self.material_ids.take(prim_ids)
        albedo = self.table.color[:, 0].take(mat, axis=0)
        if self.has_textures:
            tex = self.table.texture[mat]
            if (tex >= 0).any():
                uv = self.scene.uvs[prim_ids].astype(np.float64)
                uv = b0[:, None] * uv[:, 0] + b1[:, None] * uv[:, 1] + b2[:, None] * uv[:, 2]
                albedo = np.where((tex >= 0)[:, None],
                                  albedo * self.textures.lookup(tex, uv), albedo)
        return Surface(pos, ng, ns, mat, lobe_colors(self.table, mat, albedo))
