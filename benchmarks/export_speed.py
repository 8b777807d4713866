"""Depsgraph export speed: milliseconds per million triangles, against bpy's own reading cost.

Builds scenes of about a million triangles with the ``bpy`` module and times
``export_scene`` (the engine's export: instances, triangulation, normals, UVs,
materials, world-space transforms, ``Scene.validate``) on the evaluated depsgraph.
Two references are timed in the same run on the same meshes: the raw read (the
vertex positions and corner vertices through the attribute API, the least any exporter
must read) and Blender's own triangulation as an exporter would read it
(``loop_triangles.foreach_get("loops")``, which we avoid for triangles and quads).
Issue target: about 100 ms per million triangles.

    python benchmarks/export_speed.py [--triangles 1000000] [--repeats 3] [--json FILE]

Scenes:
    smooth      one grid mesh, smooth shaded (vertex normals), with a UV map, rotated and scaled
    mixed       the same with every other face flat (corner normals, Blender's slowest case)
    instances   1000 collection instances of one 1000-triangle mesh (per-instance cost)
    hair        a Curves object of strands of 16 points (Catmull-Rom), each a tube of 960 triangles
                (8 sides, 4 pieces a segment); its raw read is the points' positions and radii
    particles   a plane's hair particles, 10 interpolated children a parent, 5 keys a strand (the
                viewport's display steps), each a tube of 256 triangles; its raw read is every key
                through ParticleSystem.co_hair, the only way Python reads them
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE = "amcmcppm"

import bpy  # noqa: E402  (the bpy module from PyPI, or Blender's own Python)


def load_package():
    """The repository root as the package ``amcmcppm`` (as the tests load it)."""
    if PACKAGE in sys.modules:
        return sys.modules[PACKAGE]
    spec = importlib.util.spec_from_file_location(PACKAGE, os.path.join(ROOT, "__init__.py"),
                                                  submodule_search_locations=[ROOT])
    module = importlib.util.module_from_spec(spec)
    sys.modules[PACKAGE] = module
    spec.loader.exec_module(module)
    return module


def grid_mesh(name, n, flat_every_other=False):
    """An n x n grid of quads (2 n^2 triangles) with a UV map, built with foreach_set."""
    xs = np.linspace(-1.0, 1.0, n + 1)
    gx, gy = np.meshgrid(xs, xs, indexing="xy")
    co = np.stack([gx.ravel(), gy.ravel(), 0.05 * np.sin(7 * gx.ravel()) * np.cos(5 * gy.ravel())], axis=1)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="xy")
    v0 = (j * (n + 1) + i).ravel()
    quads = np.stack([v0, v0 + 1, v0 + n + 2, v0 + n + 1], axis=1)
    me = bpy.data.meshes.new(name)
    me.vertices.add(len(co))
    me.vertices.foreach_set("co", co.astype(np.float32).ravel())
    me.loops.add(quads.size)
    me.loops.foreach_set("vertex_index", quads.astype(np.int32).ravel())
    me.polygons.add(len(quads))
    me.polygons.foreach_set("loop_start", (4 * np.arange(len(quads))).astype(np.int32))
    smooth = np.ones(len(quads), bool)
    if flat_every_other:
        smooth[::2] = False
    me.polygons.foreach_set("use_smooth", smooth)
    uv = me.uv_layers.new(name="UVMap")
    uv.uv.foreach_set("vector", ((co[quads.ravel(), :2] + 1) / 2).astype(np.float32).ravel())
    me.update()
    if me.validate():
        raise RuntimeError(f"mesh {name} was invalid")
    return me


def empty_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    mat = bpy.data.materials.new("Diffuse")
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (0, 0, 4)
    scene.collection.objects.link(cam)
    scene.camera = cam
    light = bpy.data.objects.new("Light", bpy.data.lights.new("Light", "POINT"))
    light.location = (0, 0, 2)
    scene.collection.objects.link(light)
    return scene, mat


def build(kind, triangles):
    scene, mat = empty_scene()
    if kind == "instances":
        per = 1000
        count = max(1, triangles // per)
        me = grid_mesh("Piece", int(round(np.sqrt(per / 2))))
        me.materials.append(mat)
        coll = bpy.data.collections.new("Piece")
        coll.objects.link(bpy.data.objects.new("Piece", me))
        side = int(np.ceil(np.sqrt(count)))
        for k in range(count):
            empty = bpy.data.objects.new(f"Instance {k}", None)
            empty.instance_type = "COLLECTION"
            empty.instance_collection = coll
            empty.location = (2.1 * (k % side), 2.1 * (k // side), 0.0)
            scene.collection.objects.link(empty)
        meshes = [(me, count)]
    elif kind == "hair":
        strands = max(1, triangles // 960)
        rng = np.random.default_rng(0)
        roots = np.column_stack([rng.uniform(-1, 1, (strands, 2)), np.zeros(strands)])
        t = np.linspace(0.0, 1.0, 16)
        bend = rng.normal(0.0, 0.2, (strands, 1, 2))
        points = roots[:, None, :] + np.concatenate([bend * t[None, :, None] ** 2, 0.3 * t[None, :, None]
                                                     * np.ones((strands, 1, 1))], axis=2)
        cv = bpy.data.hair_curves.new("Hair")
        cv.add_curves([16] * strands)
        cv.attributes["position"].data.foreach_set("vector", points.astype(np.float32).ravel())
        cv.attributes.new("radius", "FLOAT", "POINT").data.foreach_set(
            "value", np.full(16 * strands, 0.002, np.float32))
        cv.materials.append(mat)
        scene.collection.objects.link(bpy.data.objects.new("Hair", cv))
        meshes = [(cv, 1)]
    elif kind == "particles":
        me = grid_mesh("Skin", 1)
        me.materials.append(mat)
        ob = bpy.data.objects.new("Skin", me)
        scene.collection.objects.link(ob)
        settings = ob.modifiers.new("Fur", "PARTICLE_SYSTEM").particle_system.settings
        settings.type, settings.count, settings.hair_length = "HAIR", max(1, triangles // 2560), 0.3
        settings.child_type, settings.child_percent, settings.display_step = "INTERPOLATED", 10, 2
        meshes = [(ob, 1)]
    else:
        me = grid_mesh("Grid", int(round(np.sqrt(triangles / 2))), flat_every_other=kind == "mixed")
        me.materials.append(mat)
        ob = bpy.data.objects.new("Grid", me)
        # Rotated and scaled unevenly, as objects usually are (normals need renormalising).
        ob.rotation_euler = (0.3, -0.2, 0.5)
        ob.scale = (1.5, 0.7, 1.0)
        scene.collection.objects.link(ob)
        meshes = [(me, 1)]
    depsgraph = bpy.context.evaluated_depsgraph_get()      # evaluation is not part of the export
    return depsgraph, meshes


def raw_read(meshes):
    """Positions and corner vertices through the attribute API, once per distinct mesh (a hair
    object's points' positions and radii)."""
    for me, _ in meshes:
        if isinstance(me, bpy.types.Object):
            ob = me.evaluated_get(bpy.context.evaluated_depsgraph_get())
            psys = ob.particle_systems[0]
            for p in range(len(psys.particles), len(psys.particles) + len(psys.child_particles)):
                for k in range(5):
                    psys.co_hair(ob, particle_no=p, step=k)
            continue
        if isinstance(me, bpy.types.Curves):
            co, radius = np.empty(len(me.points) * 3, np.float32), np.empty(len(me.points), np.float32)
            me.attributes["position"].data.foreach_get("vector", co)
            me.attributes["radius"].data.foreach_get("value", radius)
            continue
        co = np.empty(len(me.vertices) * 3, np.float32)
        me.attributes["position"].data.foreach_get("vector", co)
        corner = np.empty(len(me.loops), np.int32)
        me.attributes[".corner_vert"].data.foreach_get("value", corner)


def loop_triangles_read(meshes):
    """Blender's triangulation read through RNA, once per distinct mesh (none for hair)."""
    for me, _ in meshes:
        if isinstance(me, (bpy.types.Curves, bpy.types.Object)):
            continue
        me.calc_loop_triangles()
        tri = np.empty(len(me.loop_triangles) * 3, np.int32)
        me.loop_triangles.foreach_get("loops", tri)


def timed(fn, repeats):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--triangles", type=int, default=1_000_000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", help="also write the figures to this JSON file")
    a = ap.parse_args()
    load_package()
    export_scene = importlib.import_module(f"{PACKAGE}.amcmcppm_addon.export.scene").export_scene
    out = {}
    print(f"bpy {bpy.app.version_string}, {os.cpu_count()} cpus, median of {a.repeats}")
    for kind in ("smooth", "mixed", "instances", "hair", "particles"):
        depsgraph, meshes = build(kind, a.triangles)
        exported = export_scene(depsgraph)                   # warm-up, and the triangle count
        tris = exported.scene.triangle_count
        instances = exported.instances
        t_export = timed(lambda: export_scene(depsgraph), a.repeats)
        t_raw = timed(lambda: raw_read(meshes), a.repeats)
        t_lt = timed(lambda: loop_triangles_read(meshes), a.repeats)
        per_m = 1e3 * 1e6 / tris
        distinct = 0
        for me, _ in meshes:
            if isinstance(me, (bpy.types.Curves, bpy.types.Object)):
                distinct += tris
                continue
            me.calc_loop_triangles()
            distinct += len(me.loop_triangles)
        per_m_read = 1e3 * 1e6 / distinct          # the reads are of the distinct meshes only
        out[kind] = dict(triangles=tris, instances=instances, export_s=t_export, raw_read_s=t_raw,
                         loop_triangles_s=t_lt, export_ms_per_million=t_export * per_m,
                         export_us_per_instance=1e6 * t_export / instances, distinct_triangles=distinct,
                         raw_read_ms_per_million=t_raw * per_m_read,
                         loop_triangles_ms_per_million=t_lt * per_m_read)
        line = (f"{kind:10s} {tris:9,d} triangles, {instances:5d} instances: "
                f"export {t_export * per_m:6.1f} ms "
                f"per million triangles, {1e6 * t_export / instances:6.0f} us per instance; reads of the "
                f"{distinct:,d} distinct triangles: raw {t_raw * per_m_read:5.1f}, loop_triangles "
                f"{t_lt * per_m_read:6.1f} ms per million")
        print(line, flush=True)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
