"""Geometry of every depsgraph object instance -> world-space triangle arrays.

Meshes are read once per evaluated mesh datablock (instances share it by data
pointer) with the attribute API and ``foreach_get`` into NumPy buffers of the
exact dtype (``shared/docs/blender.md`` section 2), and triangulated as Blender
triangulates them: meshes of triangles and quads in NumPy with Blender's own quad
split (``foreach_get`` of ``loop_triangles`` costs about 110 ms per million
triangles, more than the rest of the read), meshes with n-gons by ``loop_triangles``.
Instances of one mesh with one material assignment are transformed together in one
batched ``matmul``: positions by ``world_from_object``, shading normals (per vertex or
per corner, before they are spread to triangle corners) by its inverse transpose.  Where
det(world_from_object) < 0 (mirrored objects) the triangle winding is reversed
so that the geometric normal, and with it the emitting side, stays outward.
Meshes that a normal-mapped material covers are read again with Blender's MikkTSpace
tangents (``Mesh.calc_tangents``), which are transformed as the normals are; their bitangent
sign flips on mirrored instances, so that w (N x T) stays the object's bitangent.

Glossary: ``T`` triangles, ``V`` vertices, ``L`` corners (loops), ``k`` instances.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ...core.cryptomatte import KINDS as CRYPTO_KINDS, name_id
from ...core.procedural import NAMED, OBJECT_INFO, OBJECT_PROPERTY, reads_objects
from ...core.sampling import affine_inverse, inverse
from ...core.scene import (CASTS_NO_SHADOW, HOLDOUT_OBJECT, SHADOW_CATCHER, VISIBLE_CAMERA,
                           VISIBLE_GLOSSY, VISIBLE_TRANSMISSION)
from ...core.texture_hash import hash_uint2, hash_uint2_to_float, hash_uint_to_float
from .lights import instance_group, light_exclude, ray_visibility

# Object types read as geometry.  Curve and text objects are not: the depsgraph presents their
# evaluated mesh as a separate MESH instance (as Cycles' ``object_is_geometry`` notes), so reading
# them too would count their triangles twice.  Surfaces and metaballs are converted with to_mesh;
# a point cloud's points become spheres of triangles (:func:`read_point_cloud`), hair curves tubes
# (:func:`read_curves`).
GEOMETRY_TYPES = {"MESH", "SURFACE", "META", "POINTCLOUD", "CURVES"}
# Object types Cycles renders that the core has no primitive for (named in a warning).
UNSUPPORTED_TYPES = {"VOLUME": "a volume object (OpenVDB grids)"}
# A point cloud's spheres: icospheres subdivided this often, fewer for clouds of more points
# (``SPHERE_BUDGET`` triangles in all at most, down to the icosahedron's 20 a point).
SPHERE_LEVELS = 3
SPHERE_BUDGET = 4_000_000
POINT_RADIUS = 0.01                 # Cycles' radius of points without a radius attribute
# Hair curves' tubes: (sides of the tube, pieces of each Catmull-Rom segment), the first whose
# triangles fit ``SPHERE_BUDGET`` (poly curves: straight segments, one piece).
CURVE_LEVELS = ((8, 4), (6, 4), (6, 2), (4, 2), (4, 1), (3, 1))
CURVE_RADIUS = 0.005                # Cycles' radius of curve points without a radius attribute
CURVE_TYPE_POLY = 1                 # Blender's CURVE_TYPE_POLY (CATMULL_ROM is 0, the default)


@dataclass
class LocalMesh:
    """One evaluated mesh, triangulated, in object space."""

    name: str
    positions: np.ndarray       # (V, 3) float64, object space
    triangles: np.ndarray       # (T, 3) int32 vertex indices, counter-clockwise = front
    slots: np.ndarray           # (T,) int32 material slot index (Blender's material_index)
    normals: np.ndarray | None  # (N, 3) float32 shading normals (per vertex or per corner), or None when flat
    normal_index: np.ndarray | None  # (T, 3) int32 row of ``normals`` at each triangle corner
    uvs: np.ndarray | None      # (T, 3, 2) float32 active render UV map per corner, or None
    mesh_materials: tuple       # the mesh's own materials (used when the object has no slots)
    tangents: np.ndarray | None = None  # (T, 3, 4) float32 tangent and bitangent sign per corner, or None
    uv_map: str = ""            # name of the active render UV map ('' without one)
    tangents_read: bool = False  # read with tangents (which may still be None: Blender had none)
    texspace: tuple = ((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))  # texture space (location, size): Generated
    colors: np.ndarray | None = None  # (T, 3, 3) float32 linear render colour attribute per corner, or None
    colors_read: bool = False   # read with its colour attribute (a material's Color Attribute node)
    # Named attributes (Attribute, Color Attribute and UV Map nodes naming one): {name: (T, 3, 3)
    # float32 per corner} of those the mesh has among ``attributes_read``, the names asked for
    attributes: dict = field(default_factory=dict)
    attributes_read: frozenset = frozenset()
    curves: int = 0             # hair: the strands (:func:`curve_tubes`), for Curves Info's Random
    # (V, 3) float64 the undeformed vertices that Generated coordinates read (Blender's orco: the
    # mesh before its shape keys and deform modifiers), or None: ``positions`` themselves
    orco: np.ndarray | None = None


@dataclass
class Geometry:
    """All instances concatenated in world space (the arrays of ``core.Scene``)."""

    vertices: np.ndarray            # (V, 3) float32, world
    triangles: np.ndarray           # (T, 3) int32
    material_ids: np.ndarray        # (T,) int32
    shading_normals: np.ndarray | None  # (T, 3, 3) float32 or None
    uvs: np.ndarray | None          # (T, 3, 2) float32 or None
    tangents: np.ndarray | None = None  # (T, 3, 4) float32 or None
    colors: np.ndarray | None = None         # (T, 3, 3) float32 or None (Color Attribute nodes)
    attributes: dict | None = None           # {name: (T, 3, 3) float32} named attributes (core.Scene)
    # Objects of procedural textures' Object and Generated coordinates, or None (core.Scene):
    object_ids: np.ndarray | None = None          # (T,) int32 each triangle's instance
    object_from_world: np.ndarray | None = None   # (O, 3, 4) float64
    texture_spaces: np.ndarray | None = None      # (O, 2, 3) float64 location and size
    # (V, 3) float32 world the vertices Generated coordinates read where some mesh is deformed
    # (``LocalMesh.orco``), or None: the vertices (core.Scene.generated_vertices)
    generated_vertices: np.ndarray | None = None
    object_info: np.ndarray | None = None         # (O, 6) float32 Object Info (core.Scene.object_info)
    object_attributes: dict | None = None         # {name: (O, 3) float32} (core.Scene.object_attributes)
    # (T,) uint8 the camera-path rays that see each triangle (its object's ray visibility) and
    # HOLDOUT_OBJECT for a holdout object's, CASTS_NO_SHADOW for one with Shadow off, SHADOW_CATCHER
    # for a shadow catcher's (or an instance's whose instancer is one, :func:`is_shadow_catcher`), or
    # None: all rays, no holdout, every object shadows, no catcher
    triangle_visibility: np.ndarray | None = None
    # (T,) uint8 the rays each triangle's light does not reach (its object's Ray Visibility,
    # core.Scene.emitter_exclude), or None: none excluded
    emitter_exclude: np.ndarray | None = None
    # (T,) int16 the light group of each triangle's object (core.Scene.emitter_group; -1: none), or
    # None: no object is in one
    emitter_group: np.ndarray | None = None
    # Light and shadow linking (export/linking.py), or None without: (T,) uint8 each triangle's
    # receiver (blocker) set and (T,) int16 its object's receiver (blocker) collection as an
    # emitter (-1: none)
    receiver_sets: np.ndarray | None = None
    emitter_collections: np.ndarray | None = None
    blocker_sets: np.ndarray | None = None
    shadow_collections: np.ndarray | None = None
    # (T, 2) float32 Cryptomatte's object and asset ids of each triangle's instance, with
    # {"crypto_object"/"crypto_asset": {name: hash hex}} their manifests, or None (no such pass)
    cryptomatte: np.ndarray | None = None
    crypto_names: dict | None = None
    instances: int = 0              # object instances exported
    meshes: int = 0                 # distinct meshes read

    @staticmethod
    def empty() -> "Geometry":
        return Geometry(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32), np.zeros(0, np.int32),
                        None, None, None)


class GeometryCollector:
    """Gathers the geometry instances of a depsgraph; :meth:`finish` gives the world-space arrays.

    materials : ``MaterialExporter`` assigning core material ids.
    material_override : a Material used for every object (the view layer's override).
    linking : the depsgraph's light and shadow ``LightLinking`` (receivers, blockers), each or
    both None.
    passes : the core data passes the view layer asks for that need geometry beside what the
    materials read: "object_index" the objects and their Object Info (the pass index), "uv" the UVs.
    light_groups : {name: index} of the view layer's light groups (``lights.light_group_index``).
    hair : whether hair curves and hair particles render (the view layer's Filter > Hair box,
    Cycles' ``use_hair``).
    render : whether the depsgraph is a render's (particle systems switched on for renders, their
    render steps and children) or a viewport's (those for the viewport, its display steps and amount).
    """

    def __init__(self, materials, log, material_override=None, linking=(None, None), frame=0.0,
                 passes=frozenset(), light_groups=None, hair=True, render=True):
        """``frame``: the scene's current frame (with subframe), for Particle Info's Age."""
        self.light_groups = light_groups or {}
        self.hair = hair
        self.render = render
        self.materials = materials
        self.frame = frame
        self.passes = frozenset(passes)
        self.log = log
        self.material_override = material_override
        self.linking = linking
        self.meshes = {}      # mesh key -> LocalMesh, or None when it has no faces
        # (mesh key, material ids, ray visibility, per kind of linking (set, emitter collection)
        # or None) -> list of (4, 4) world_from_object, and the same keys -> list of (6,) Object Info
        self.groups = {}
        self.infos = {}
        self.properties = {}  # the same keys -> list of {name: (3,) object property} (object_property)
        # With a Cryptomatte pass: the same keys -> list of (object, asset) per instance, as
        # indices into crypto_names (name -> index)
        self.cryptos = {} if self.passes & set(CRYPTO_KINDS) else None
        self.crypto_names = {}

    def add(self, inst):
        """Add one ``DepsgraphObjectInstance`` (other object types are ignored)."""
        ob = inst.object
        if ob.type == "MESH" and self.hair and inst.show_particles:
            self._add_particle_hair(inst)
        if ob.type not in GEOMETRY_TYPES or not inst.show_self or (ob.type == "CURVES" and not self.hair):
            if ob.type in UNSUPPORTED_TYPES and inst.show_self:
                self.log.warning(f"object '{ob.name}' is {UNSUPPORTED_TYPES[ob.type]}, which is not "
                                 "supported: not rendered")
            return
        key = _mesh_key(ob)
        if key not in self.meshes:
            self.meshes[key] = read_object_mesh(ob, self.log)
        local = self.meshes[key]
        if local is None:
            return
        materials = self.materials
        if self.material_override is not None:
            mat_ids = (materials.material_id(self.material_override),)
        else:
            slots = [slot.material for slot in ob.material_slots]
            mat_ids = tuple(materials.material_id(m) for m in (slots or local.mesh_materials))
            if not mat_ids:
                mat_ids = (materials.default_id(),)
        uv_map = materials.tangent_uv(mat_ids)
        tangents = uv_map is not None and not local.tangents_read and local.uvs is not None
        used = materials.coordinates_used(mat_ids)
        colors = "color" in used and not local.colors_read
        named = frozenset(n[len(NAMED):] for n in used if n.startswith(NAMED))
        if tangents and uv_map and uv_map != local.uv_map:
            self.log.warning(f"object '{ob.name}': its normal map or anisotropic tangent uses UV map "
                             f"'{uv_map}'; the active render UV map '{local.uv_map}' is used instead")
        if tangents or colors or not named <= local.attributes_read:
            # Read again with what the materials need (each only when some material needs it).
            local = read_object_mesh(ob, self.log, tangents=tangents or local.tangents_read,
                                     colors=colors or local.colors_read,
                                     attributes=named | local.attributes_read) or local
            self.meshes[key] = local
        self._place(inst, key, mat_ids, used)

    def _add_particle_hair(self, inst):
        """The hair particle systems of a mesh object's instance (Cycles' ``sync_particle_hair``:
        those of Hair type rendered as Path, on for renders or for the viewport as the depsgraph
        is), each a tube per strand (:func:`read_particle_hair`) of the material its settings name
        (their Material slot)."""
        ob = inst.object
        systems = [m.particle_system for m in ob.modifiers if _renders_hair(m, self.render)]
        slots = [slot.material for slot in ob.material_slots] or list(ob.data.materials)
        first = 0                               # (Cycles numbers the strands across the systems)
        for index, psys in enumerate(systems):
            settings = psys.settings
            if self.material_override is not None:
                material_id = self.materials.material_id(self.material_override)
            elif slots:
                material_id = self.materials.material_id(slots[min(max(settings.material - 1, 0),
                                                                   len(slots) - 1)])
            else:
                material_id = self.materials.default_id()
            mat_ids = (material_id,)
            used = self.materials.coordinates_used(mat_ids)
            named = frozenset(n[len(NAMED):] for n in used if n.startswith(NAMED))
            key = ("hair", ob.original.as_pointer(), index)
            local = self.meshes.get(key)
            if key not in self.meshes or (local is not None and not named <= local.attributes_read):
                named |= local.attributes_read if local is not None else frozenset()
                self.meshes[key] = local = without_undefined(
                    read_particle_hair(ob, psys, self.render, self.log, named, first), self.log)
            if local is None:
                continue
            first += local.curves
            self._place(inst, key, mat_ids, used)

    def _place(self, inst, key, mat_ids, used):
        """One more instance of the geometry under ``key`` with materials ``mat_ids`` (whose
        programs read the coordinates ``used``): its transform and its object's flags, links,
        Object Info, Cryptomatte names and properties."""
        ob = inst.object
        # Copy the matrix inside the loop: the iterator reuses its instance objects.
        flags = (ray_visibility(ob) | (HOLDOUT_OBJECT if ob.is_holdout else 0)
                 | (0 if ob.visible_shadow else CASTS_NO_SHADOW)
                 | (SHADOW_CATCHER if is_shadow_catcher(inst) else 0) | light_exclude(ob) << EXCLUDE_SHIFT
                 | (instance_group(inst, self.light_groups) + 1) << GROUP_SHIFT)
        link = tuple(None if k is None else (k.object_set(ob), k.collection(ob)) for k in self.linking)
        self.groups.setdefault((key, mat_ids, flags, link), []).append(
            np.array(inst.matrix_world, np.float64))
        # (only for materials that read it, or the Object Index pass: a name's hash costs
        # microseconds, and scattered scenes have millions of instances)
        self.infos.setdefault((key, mat_ids, flags, link), []).append(
            object_info(inst) if used & set(OBJECT_INFO) or "object_index" in self.passes else None)
        if self.cryptos is not None:
            index = self.crypto_names
            pair = tuple(index.setdefault(name, len(index)) for name in crypto_names(inst))
            self.cryptos.setdefault((key, mat_ids, flags, link), []).append(pair)
        properties = sorted(n for n in used if n.startswith(OBJECT_PROPERTY))
        if properties:                  # (the same names for every instance of a group)
            self.properties.setdefault((key, mat_ids, flags, link), []).append(
                {n: object_property(inst, n, self.frame) for n in properties})

    def finish(self) -> Geometry:
        geometry = assemble(self.meshes, self.groups, self.materials, self.infos, self.properties,
                            self.passes, self.cryptos, list(self.crypto_names))
        geometry.meshes = sum(1 for m in self.meshes.values() if m is not None)
        return geometry


# Every camera-path ray: a triangle seen by all of them needs no visibility array.
ALL_RAYS = VISIBLE_CAMERA | VISIBLE_GLOSSY | VISIBLE_TRANSMISSION
# An object group's flags: its Scene.triangle_visibility bits, above them its light_exclude bits and
# above those its light group plus one (0: none).
VISIBILITY_MASK = 0xFF
EXCLUDE_SHIFT = 8
GROUP_SHIFT = 16


def is_shadow_catcher(inst) -> bool:
    """Whether depsgraph object instance ``inst`` is a shadow catcher (Object > Visibility > Mask >
    Shadow Catcher), as Cycles' sync finds it: its object is one, or its instancer is (the object
    whose collection, particles or geometry nodes make the instance).  (Setting the box tags the
    depsgraph, so the evaluated objects hold it.)"""
    return inst.object.is_shadow_catcher or (inst.is_instance and inst.parent is not None
                                             and inst.parent.is_shadow_catcher)


def _renders_hair(modifier, render=True) -> bool:
    """Whether ``modifier`` is a particle system that renders as hair strands (Cycles' curves), in
    renders (``render``) or in the viewport."""
    if modifier.type != "PARTICLE_SYSTEM" or not (modifier.show_render if render else modifier.show_viewport):
        return False
    settings = modifier.particle_system.settings
    return settings.type == "HAIR" and settings.render_type == "PATH"


def object_info(inst):
    """(6,) float32 Blender's Object Info of a depsgraph instance as Cycles sets it (``Scene.object_info``):
    Alpha and Color (the object's colour; an instance's come from the object that instances it),
    Object Index (the object's pass index) and Random, the instance's ``random_id`` for an
    instance (a particle, a collection or geometry-nodes instance) and else Cycles' hash of the
    object's name, in [0, 1] as ``random_id / 0xFFFFFFFF`` in float32 (checked against Cycles:
    ``test_object_info_matches_cycles``)."""
    ob = inst.object
    rid = (inst.random_id & 0xFFFFFFFF) if inst.is_instance else cycles_name_hash(ob.name)
    random = np.float32(rid) * np.float32(1.0 / 0xFFFFFFFF)
    colored = inst.parent if inst.is_instance and inst.parent is not None else ob
    r, g, b, alpha = (float(x) for x in colored.color)
    return np.array([alpha, float(ob.pass_index), random, r, g, b], np.float32)


def crypto_names(inst):
    """(object, asset) names of a depsgraph instance for Cryptomatte, as Cycles names them: the
    object's and its topmost parent's (itself without one; an instance's too, not its
    instancer's: a cube instanced by an empty's collection is its own asset in Cycles)."""
    ob = top = inst.object
    while top.parent is not None:
        top = top.parent
    return ob.name, top.name


def object_property(inst, name, frame=0.0):
    """(3,) float32 what Cycles' Attribute node of the Object (``object:`` + an RNA path) or
    Instancer type (``instancer:``) reads for a depsgraph instance (``lookup_instance_property``):
    the property at that path of the instancer (Instancer only), else of the object, else of its
    data (``rna_property``); 0 without one.  ``object:`` + ``PARTICLE`` + a Particle Info output
    is :func:`particle_info`'s (at the scene's ``frame``)."""
    kind, path = name.split(":", 1)
    if path.startswith(PARTICLE):
        return particle_info(inst, path[len(PARTICLE):], frame)
    # (Blender's iterator gives an instance's object its instancer's colour, which Cycles reads:
    # the colour, as Object Info's, comes from the instancer)
    colored = inst.parent if inst.is_instance and inst.parent is not None and path == "color" else inst.object
    owners = [colored, getattr(inst.object, "data", None)]
    if kind == "instancer" and inst.is_instance and inst.parent is not None:
        owners.insert(0, inst.parent)
    return rna_property(owners, path)


# Object property paths (``object:`` + PARTICLE + an output) of Particle Info's outputs: Blender's
# RNA paths never start with a dot.
PARTICLE = ".particle:"


def particle_info(inst, output, frame):
    """(3,) float32 Particle Info's ``output`` for a depsgraph instance, as Cycles' sync sets its
    particle (``sync_dupli_particle``): an instance made by a particle system reads particle
    ``persistent_id[0]`` of it (Index that number, Age the frame less its birth time, Lifetime,
    Location, Size, Velocity, Angular Velocity its own), any other object Cycles' dummy particle 0
    (all 0); Random is ``hash_uint2_to_float(Index, 0)`` for both.  A float is repeated in x, y, z."""
    psys = inst.particle_system if inst.is_instance else None
    index = int(inst.persistent_id[0]) if psys is not None else 0
    particle = psys.particles[index] if psys is not None and 0 <= index < len(psys.particles) else None
    if particle is None:
        index = 0
    if output == "random":
        value = float(hash_uint2_to_float(np.uint32(index), np.uint32(0)))
    elif output == "index":
        value = float(index)
    elif particle is None:
        value = 0.0
    elif output in ("location", "velocity", "angular_velocity"):
        return np.array(getattr(particle, output)[:3], np.float32)
    else:
        value = {"age": frame - particle.birth_time, "lifetime": particle.lifetime,
                 "size": particle.size}[output]
    return np.full(3, value, np.float32)


def rna_property(owners, path):
    """(3,) float32 the first of ``owners`` (RNA structs or None) that has a custom property named
    ``path`` or, failing that, a property at the RNA path ``path`` (Cycles' ``lookup_property``,
    custom properties first): a number repeated, a float array's first three; 0 without one."""
    for owner in owners:
        for where in (f'["{path}"]', path):
            try:
                value = owner.path_resolve(where) if owner is not None else None
            except (ValueError, TypeError, AttributeError):
                continue
            if isinstance(value, (bool, int, float)):
                return np.full(3, float(value), np.float32)
            try:
                items = list(value)
            except TypeError:
                continue
            if 0 < len(items) <= 4 and all(isinstance(x, float) for x in items):
                return np.array((items + [0.0, 0.0])[:3], np.float32)
    return np.zeros(3, np.float32)


def cycles_name_hash(name):
    """Cycles' random_id of an object that is not an instance: ``hash_uint2(hash_string(name), 0)``,
    hash_string multiplying by 37 and adding each byte of the UTF-8 name (as unsigned: a name
    with non-ASCII letters matches Cycles so, not with signed chars)."""
    h = 0
    for byte in name.encode("utf-8"):
        h = (h * 37 + byte) & 0xFFFFFFFF
    return int(hash_uint2(np.uint32(h), np.uint32(0)))


def _mesh_key(ob):
    """Instances with equal keys share one evaluated mesh."""
    if ob.type == "MESH":
        return ("mesh", ob.data.as_pointer())
    # Surfaces and metaballs are converted per evaluated object.
    return ("object", ob.original.as_pointer(), ob.data.as_pointer() if ob.data else 0)


def read_object_mesh(ob, log, tangents=False, colors=False, attributes=frozenset()):
    """:class:`LocalMesh` of an evaluated object (modifiers applied), or None without faces;
    with ``tangents`` also its tangent frames (for normal maps), with ``colors`` its render colour
    attribute (for Color Attribute nodes), and the named ``attributes`` it has; triangles with a
    corner at NaN or infinity left out (:func:`without_undefined`)."""
    if ob.type == "POINTCLOUD":
        return without_undefined(read_point_cloud(ob.data, ob.name, log, attributes), log)
    if ob.type == "CURVES":
        return without_undefined(read_curves(ob.data, ob.name, log, attributes), log)
    try:
        me = ob.to_mesh()
    except RuntimeError as e:
        log.warning(f"object '{ob.name}': cannot convert its {ob.type.lower()} to a mesh ({e}); skipped")
        return None
    try:
        if me is None:
            return None
        local = read_mesh(me, ob.name, log, tangents, colors=colors, attributes=attributes)
        if local is not None and ob.type == "MESH":
            local = replace(local, orco=undeformed_positions(ob, me, local.positions))
    finally:
        ob.to_mesh_clear()
    return without_undefined(local, log)


def undeformed_positions(ob, me, positions):
    """(V, 3) float64 the vertices of evaluated mesh object ``ob``'s original mesh, where shape keys
    or deform modifiers moved the vertices of evaluated mesh ``me`` (``positions``) and left its
    topology (vertices, corners and faces) as it was: Blender's orco, which Cycles' Generated
    coordinates read.  None where nothing moved them, or where modifiers made new geometry (a
    Subdivision Surface: Blender's orco is the stack run on the undeformed mesh, not done here)."""
    if ob.original.type != "MESH":          # (a metaball, a curve or text made a mesh by its nodes)
        return None
    original = ob.original.data
    if original is None or (original.shape_keys is None and not len(ob.original.modifiers)):
        return None
    if (len(original.vertices), len(original.loops), len(original.polygons)) != \
            (len(me.vertices), len(me.loops), len(me.polygons)):
        return None
    corners = [np.empty(len(me.loops), np.int32) for _ in range(2)]
    for mesh, out in zip((original, me), corners):
        mesh.attributes[".corner_vert"].data.foreach_get("value", out)
    if not np.array_equal(*corners):
        return None
    orco = np.empty(len(original.vertices) * 3, np.float32)
    original.attributes["position"].data.foreach_get("vector", orco)
    orco = orco.reshape(-1, 3).astype(np.float64)
    return None if np.array_equal(orco, positions) else orco


def without_undefined(local, log):
    """``local`` (a :class:`LocalMesh` or None) without its triangles that have a corner at NaN or
    infinity (a vertex, a point's position or radius, a curve's key that a driver or script made
    so: Cycles' BVH skips primitives whose bounds are not finite), named in a warning; None when
    none is left."""
    if local is None:
        return None
    unusable = ~np.isfinite(local.positions).all(axis=1)
    if not unusable.any():
        return local
    keep = np.flatnonzero(~unusable.take(local.triangles).any(axis=1))
    log.warning(f"object '{local.name}': {len(local.triangles) - len(keep)} of its {len(local.triangles)} "
                "triangles have a corner at NaN or infinity (a vertex, or a point's position or radius); "
                "they are left out")
    if len(keep) == 0:
        return None
    positions = local.positions.copy()
    positions[unusable] = 0.0                       # (no triangle uses them now)

    def rows(a):
        return None if a is None else a.take(keep, axis=0)
    return replace(local, positions=positions, triangles=rows(local.triangles), slots=rows(local.slots),
                   normal_index=rows(local.normal_index), uvs=rows(local.uvs), tangents=rows(local.tangents),
                   colors=rows(local.colors), attributes={k: rows(v) for k, v in local.attributes.items()})


def read_mesh(me, name, log, tangents=False, triangulated=False, colors=False, attributes=frozenset()):
    """:class:`LocalMesh` of a ``bpy.types.Mesh``, or None (with an info message) without faces.

    With ``tangents``, a mesh with n-gons (for which Blender computes no tangents) is read from a
    triangulated copy (``triangulated``: this is that copy); with ``colors`` its render colour
    attribute is read too, and the named ``attributes`` it has (:func:`_named_attributes`).
    """
    n_vert = len(me.vertices)
    if len(me.polygons) == 0:
        if n_vert:
            log.info(f"object '{name}' has no faces (only vertices or edges); skipped")
        return None
    n_corner = len(me.loops)
    attrs = me.attributes

    positions = np.empty(n_vert * 3, np.float32)
    attrs["position"].data.foreach_get("vector", positions)
    positions = positions.reshape(n_vert, 3)
    corner_vert = np.empty(n_corner, np.int32)
    attrs[".corner_vert"].data.foreach_get("value", corner_vert)

    # (Vertices at NaN or infinity split their quads as if at the origin: ``without_undefined``
    # leaves out the triangles that use them.)
    unusable = ~np.isfinite(positions).all(axis=1)
    split_at = np.where(unusable[:, None], np.float32(0.0), positions) if unusable.any() else positions
    tri_loops, tri_poly = _triangulate(me, split_at, corner_vert)
    tri_vert = corner_vert.take(tri_loops)

    slots = np.zeros(len(tri_poly), np.int32)
    mat_attr = attrs.get("material_index")
    if mat_attr is not None and mat_attr.domain == "FACE" and mat_attr.data_type == "INT":
        poly_mat = np.empty(len(me.polygons), np.int32)
        mat_attr.data.foreach_get("value", poly_mat)
        slots = poly_mat.take(tri_poly)

    normals, normal_index = _shading_normals(me, tri_vert, tri_loops)
    layer = next((uv for uv in me.uv_layers if uv.active_render), None)
    uvs = _corner_uvs(me, layer, tri_loops)
    frames = None
    if tangents and uvs is not None:
        frames = _corner_tangents(me, layer, tri_loops)
        if frames is None and not triangulated:
            copy = _triangulated_copy(me)
            try:
                local = read_mesh(copy, name, log, tangents, triangulated=True, colors=colors,
                                  attributes=attributes)
            finally:
                import bpy
                bpy.data.meshes.remove(copy)
            # (the copy has the same vertices but more edges: the edge-based ones from the mesh itself)
            local.attributes.update(_named_attributes(me, set(attributes) & {RANDOM_PER_ISLAND, POINTINESS},
                                                      local.triangles, None, None, name, log))
            return local
        if frames is None:
            log.warning(f"object '{name}': Blender computed no tangents for its normal map; "
                        "the normal map is ignored")
    return LocalMesh(name=name, positions=positions.astype(np.float64), triangles=tri_vert, slots=slots,
                     normals=normals, normal_index=normal_index, uvs=uvs, mesh_materials=tuple(me.materials),
                     tangents=frames, uv_map=layer.name if layer is not None else "",
                     tangents_read=tangents,
                     texspace=_texture_space(me, positions),
                     colors=_corner_colors(me, tri_vert, tri_loops) if colors else None, colors_read=colors,
                     attributes=_named_attributes(me, attributes, tri_vert, tri_loops, tri_poly, name, log),
                     attributes_read=frozenset(attributes))


def _texture_space(me, positions):
    """(location, size) of mesh ``me``'s texture space (Generated coordinates).  Blender's own, but
    where it is not finite (a vertex at NaN, or vertices so far apart that the size overflows
    float32) the box of the finite vertices ``positions`` (V, 3), as Blender's automatic texture
    space makes it (``BKE_mesh_texspace_calc``: half the box a side, 1 where the box is flat)."""
    location, size = np.array(me.texspace_location, np.float64), np.array(me.texspace_size, np.float64)
    if np.isfinite(location).all() and np.isfinite(size).all():
        return tuple(location), tuple(size)
    p = np.asarray(positions, np.float64)
    p = p[np.isfinite(p).all(axis=1)]
    lo, hi = (p.min(axis=0), p.max(axis=0)) if len(p) else (-np.ones(3), np.ones(3))
    size = np.where(hi > lo, 0.5 * (hi - lo), 1.0)
    location = 0.5 * lo + 0.5 * hi
    ok = np.isfinite(size).all() and np.isfinite(location).all()
    return (tuple(location), tuple(size)) if ok else ((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))


def icosphere(level):
    """(unit vertices (V, 3) float64, triangles (T, 3) int32 counter-clockwise from outside) of the
    icosahedron with its faces cut in four ``level`` times, the new vertices pushed onto the sphere."""
    g = (1.0 + 5.0 ** 0.5) / 2.0
    v = np.array([(-1, g, 0), (1, g, 0), (-1, -g, 0), (1, -g, 0), (0, -1, g), (0, 1, g), (0, -1, -g),
                  (0, 1, -g), (g, 0, -1), (g, 0, 1), (-g, 0, -1), (-g, 0, 1)], np.float64)
    t = np.array([(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
                  (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
                  (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)], np.int64)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    for _ in range(level):
        # Each edge's midpoint once: edges keyed by their sorted corners.
        edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
        keys, inverse = np.unique(edges[:, 0] * len(v) + edges[:, 1], return_inverse=True)
        a, b = keys // len(v), keys % len(v)
        mid = v[a] + v[b]
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        m = len(v) + inverse.reshape(3, -1).T             # (T, 3) midpoints of edges 01, 12, 20
        v = np.concatenate([v, mid])
        t = np.concatenate([np.stack([t[:, 0], m[:, 0], m[:, 2]], 1),
                            np.stack([t[:, 1], m[:, 1], m[:, 0]], 1),
                            np.stack([t[:, 2], m[:, 2], m[:, 1]], 1), m])
    return v, t.astype(np.int32)


def read_point_cloud(pc, name, log, attributes=frozenset()):
    """:class:`LocalMesh` of a ``bpy.types.PointCloud``: each point a sphere of its ``radius``
    (Cycles' point primitive; 0.01 without the attribute) made of an icosphere's triangles with the
    sphere's own normals at its corners, of the first material slot (as Cycles); None without
    points.  Its texture space is the unit cube around the origin (Generated not compared).  The
    named ``attributes`` it has on its points are read, and Point Info's (``POINT_INFO``)."""
    n = len(pc.points)
    if n == 0:
        return None
    attrs = pc.attributes
    centres, radius = _positions_and_radii(attrs, n, POINT_RADIUS)
    radius = np.maximum(radius, 0.0)
    level = SPHERE_LEVELS
    while level > 0 and n * 20 * 4 ** level > SPHERE_BUDGET:
        level -= 1
    unit, tris = icosphere(level)
    log.info(f"object '{name}': {n} points as spheres of {len(tris)} triangles each")
    positions = (centres[:, None, :] + radius[:, None, None] * unit[None]).reshape(-1, 3)
    triangles = (tris[None] + (np.arange(n) * len(unit))[:, None, None]).reshape(-1, 3).astype(np.int32)
    normals = np.tile(unit.astype(np.float32), (n, 1))
    point = np.repeat(np.arange(n), len(tris))                 # each triangle's point
    named = {}
    for key in sorted(attributes):
        if key in POINT_INFO:
            values = {POINT_POSITION: centres, POINT_RADIUS: np.repeat(radius[:, None], 3, axis=1),
                      POINT_RANDOM: np.repeat(hash_uint2_to_float(np.arange(n, dtype=np.uint32),
                                                                  np.uint32(0))[:, None], 3, axis=1)}[key]
        else:
            values = _point_attribute(attrs, key, name, log)
            if values is None:
                continue
        named[key] = np.repeat(values.take(point, axis=0)[:, None, :], 3, axis=1).astype(np.float32)
    return LocalMesh(name=name, positions=positions, triangles=triangles,
                     slots=np.zeros(len(triangles), np.int32), normals=normals, normal_index=triangles.copy(),
                     uvs=None, mesh_materials=tuple(pc.materials), attributes=named,
                     attributes_read=frozenset(attributes), colors_read=True)    # (no colour attribute read)


def catmull_rom(p0, p1, p2, p3, t):
    """(value, derivative in t) of the uniform Catmull-Rom segment from ``p1`` to ``p2`` at ``t``
    (arrays broadcast together; ``t`` with a trailing axis of 1 for vectors)."""
    t2, t3 = t * t, t * t * t
    value = 0.5 * (2.0 * p1 + (p2 - p0) * t + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * t2
                   + (3.0 * (p1 - p2) + p3 - p0) * t3)
    slope = 0.5 * ((p2 - p0) + 2.0 * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * t
                   + 3.0 * (3.0 * (p1 - p2) + p3 - p0) * t2)
    return value, slope


def read_curves(cv, name, log, attributes=frozenset()):
    """:class:`LocalMesh` of a ``bpy.types.Curves`` (hair): each curve a tube of triangles around
    the curve Cycles renders through its points (``blender/curves.cpp``: the control points as keys,
    their ``radius`` or 0.005; a uniform Catmull-Rom spline through them with the end keys repeated,
    or, where the first curve is a poly curve, straight segments), of the first material slot (as
    Cycles, whatever ``material_index`` says).  A tube has ``CURVE_LEVELS``' sides and pieces, its
    corners the circle's normals in a frame carried along the curve without twist
    (:func:`_rotation_minimizing`), its polygon's radius widened by pi / (k sin(pi / k)) so that
    its mean width seen from the side and its area are the circle's.  Cycles' Rounded Ribbons (its
    default shape) face every ray with the round normals of such a tube, its 3D Curves are round
    tubes: both are this tube.  Curves Info's outputs and the named ``attributes`` the curves have
    (on their points or curves) are read per corner (curves have no render colour attribute: an
    unnamed Color Attribute node reads 0, as in Cycles); None without a curve of two or more points.
    (Curves that Geometry Nodes make on a mesh object reach the depsgraph as a Curve object, which
    Cycles does not render either.)"""
    n_points, n_curves = len(cv.points), len(cv.curves)
    if n_points == 0 or n_curves == 0:
        return None
    attrs = cv.attributes
    keys, radius = _positions_and_radii(attrs, n_points, CURVE_RADIUS)
    offsets = np.empty(n_curves + 1, np.int32)
    cv.curve_offset_data.foreach_get("value", offsets)
    poly = False
    t_attr = attrs.get("curve_type")
    if t_attr is not None and t_attr.domain == "CURVE":
        types = np.empty(n_curves, np.int32)
        t_attr.data.foreach_get("value", types)
        poly = int(types[0]) == CURVE_TYPE_POLY        # (Cycles looks at the first curve only)
    return curve_tubes(keys, radius, offsets, poly, name, log, attributes, attrs, tuple(cv.materials))


def read_particle_hair(ob, psys, render, log, attributes=frozenset(), first_random=0):
    """:class:`LocalMesh` of a hair particle system ``psys`` of evaluated mesh object ``ob``, in its
    object space, as Cycles exports it (``ObtainCacheParticleData``): each strand (the parents, or
    only the children where there are any) the keys of its path cache (``ParticleSystem.co_hair``,
    2^steps + 1 of them, steps the settings' render or display steps as ``render`` says, plus a
    spiral kink's extra steps), radius half the Radius Scale times the root-to-tip blend by Shape
    along the strand's length (0 at the tip with Close Tip), Catmull-Rom tubes of them
    (:func:`curve_tubes`); Curves Info's Random numbers its strands from ``first_random`` (Cycles
    counts across the object's systems).  None without strands.  (co_hair is a call per key: about
    0.5 us.)"""
    settings = psys.settings
    steps = (1 << (settings.render_step if render else settings.display_step)) + 1
    if settings.kink == "SPIRAL":
        steps += settings.kink_extra_steps
    parents, children = len(psys.particles), len(psys.child_particles)
    if not render:
        children = int(children * settings.display_percentage / 100.0)
    start = parents if settings.child_type != "NONE" and children else 0
    strands = range(start, parents + children)
    if len(strands) == 0:
        return None
    co_hair = psys.co_hair
    world = np.array([tuple(co_hair(ob, particle_no=p, step=k)) for p in strands for k in range(steps)],
                     np.float64)
    back = affine_inverse(np.array(ob.matrix_world, np.float64))       # (an object of scale 0: pinv)
    keys = world @ back[:3, :3].T + back[:3, 3]
    step = np.linalg.norm(np.diff(keys.reshape(len(strands), steps, 3), axis=1), axis=2)
    along = np.concatenate([np.zeros((len(strands), 1)), np.cumsum(step, axis=1)], axis=1)
    length = along[:, -1:]
    time = np.where(length > 0.0, along / np.where(length > 0.0, length, 1.0), 0.0)
    shape, root, tip = settings.shape, settings.root_radius, settings.tip_radius
    blend = 1.0 - time
    if shape < 0.0:
        blend = blend ** (1.0 + shape)
    elif shape > 0.0:
        blend = blend ** (1.0 / (1.0 - shape))
    radius = 0.5 * settings.radius_scale * (blend * (root - tip) + tip)
    if settings.use_close_tip:
        radius[:, -1] = 0.0
    offsets = steps * np.arange(len(strands) + 1)
    name = f"{ob.name}' particles '{psys.name}"
    return curve_tubes(keys, radius.ravel(), offsets, False, name, log, attributes, None, (), first_random)


def curve_tubes(keys, radius, offsets, poly, name, log, attributes=frozenset(), attrs=None, materials=(),
                first_random=0):
    """:class:`LocalMesh` of tubes around curves (:func:`read_curves`): ``keys`` (P, 3) and
    ``radius`` (P,) of the points, curve c the points ``offsets[c]`` to ``offsets[c + 1]``, poly
    or Catmull-Rom; ``attrs`` the curves' own attributes (or None), ``materials`` their data's,
    ``first_random`` the number of the first curve for Curves Info's Random.  None without a
    curve of two or more points."""
    n_curves = len(offsets) - 1
    first, count = offsets[:-1].astype(np.int64), np.diff(offsets).astype(np.int64)
    curves = np.flatnonzero(count >= 2)
    if len(curves) == 0:
        log.info(f"object '{name}' has no curve of two or more points; skipped")
        return None
    n_seg = int((count[curves] - 1).sum())
    sides, pieces = CURVE_LEVELS[-1]
    for k, p in CURVE_LEVELS:
        if 2 * k * (1 if poly else p) * n_seg <= SPHERE_BUDGET:
            sides, pieces = k, p
            break
    pieces = 1 if poly else pieces
    # Each segment: its curve and its keys k1 -> k2, with k0 and k3 beside them (the ends repeated).
    seg_curve = np.repeat(curves, count[curves] - 1)
    j = np.arange(n_seg) - np.repeat(np.cumsum(count[curves] - 1) - (count[curves] - 1), count[curves] - 1)
    k1 = first[seg_curve] + j
    k2 = k1 + 1
    k0 = np.maximum(k1 - 1, first[seg_curve])
    k3 = np.minimum(k2 + 1, first[seg_curve] + count[seg_curve] - 1)
    # Points along the curves: each segment's pieces from its start, then each curve's last key
    # (t = 1 of its last segment).
    seg = np.repeat(np.arange(n_seg), pieces)
    t = np.tile(np.arange(pieces) / pieces, n_seg)
    last = np.cumsum(count[curves] - 1) - 1
    seg = np.concatenate([seg, last])
    t = np.concatenate([t, np.ones(len(curves))])
    order = np.argsort(seg * 2.0 + t, kind="stable")            # (a curve's points in a row)
    seg, t = seg[order], t[order]
    a, b, c, d = k0[seg], k1[seg], k2[seg], k3[seg]
    tv = t[:, None]
    miter = None
    if poly:
        centre = keys[b] * (1.0 - tv) + keys[c] * tv
        r = radius[b] * (1.0 - t) + radius[c] * t
        # At a key between two segments (the start, t = 0, of the second: a before it, b at it) the
        # ring lies in the plane halfway between them, stretched across the bend by
        # 1 / cos(half the angle): a mitre joint, no gap, no pinch.  (A ring square to the second
        # segment sheared the first one's tube: 9 % darker than Cycles.)
        slope = _unit_or(keys[c] - keys[b], keys[d] - keys[a])
        inner = np.flatnonzero((t == 0.0) & (a < b))
        before = _unit_or(keys[b[inner]] - keys[a[inner]], slope[inner])
        half = np.clip(np.einsum("ij,ij->i", before, _unit_or(before + slope[inner], before)), 0.25, 1.0)
        miter = (inner, _unit_or(slope[inner] - before, _perpendicular(before)), 1.0 / half)
        slope[inner] += before
    else:
        centre, slope = catmull_rom(keys[a], keys[b], keys[c], keys[d], tv)
        r = catmull_rom(radius[a], radius[b], radius[c], radius[d], t)[0]
    r = np.maximum(r, 0.0)
    tangent = _unit_or(slope, keys[c] - keys[b])
    per_curve = (count[curves] - 1) * pieces + 1
    starts = np.cumsum(per_curve) - per_curve
    normal = _rotation_minimizing(centre, tangent, starts, per_curve)
    binormal = np.cross(tangent, normal)
    # The ring of each point, its sides counter-clockwise about the tangent.
    theta = 2.0 * np.pi * np.arange(sides) / sides
    radial = (np.cos(theta)[None, :, None] * normal[:, None, :]
              + np.sin(theta)[None, :, None] * binormal[:, None, :])           # (E, k, 3)
    widen = np.pi / (sides * np.sin(np.pi / sides))
    offset = (widen * r)[:, None, None] * radial                                  # (E, k, 3)
    if miter is not None:
        rows, across, stretch = miter
        along = np.einsum("ekj,ej->ek", offset[rows], across)
        offset[rows] += ((stretch - 1.0)[:, None] * along)[:, :, None] * across[:, None, :]
    positions = (centre[:, None, :] + offset).reshape(-1, 3)

    # Quads between consecutive points of a curve, each two triangles facing out.
    n_eval = len(seg)
    is_last = np.zeros(n_eval, bool)
    is_last[starts + per_curve - 1] = True
    e = np.flatnonzero(~is_last)
    side = np.arange(sides)
    v00 = e[:, None] * sides + side[None, :]
    v01 = e[:, None] * sides + (side[None, :] + 1) % sides
    v10, v11 = v00 + sides, v01 + sides
    triangles = np.stack([np.stack([v00, v01, v11], -1), np.stack([v00, v11, v10], -1)], 2)
    triangles = triangles.reshape(-1, 3).astype(np.int32)
    log.info(f"object '{name}': {len(curves)} curves as tubes of {sides} sides, {len(triangles)} triangles")
    named = {}
    ring = triangles // sides                                 # (T, 3) each corner's point
    if attributes:
        point_values = _curve_info(keys, radius, first, count, seg, t, b, c, seg_curve, attrs, attributes,
                                   name, log, first_random)
        for key, values in point_values.items():
            named[key] = values.astype(np.float32)[ring]
    return LocalMesh(name=name, positions=positions, triangles=triangles,
                     slots=np.zeros(len(triangles), np.int32),
                     normals=radial.reshape(-1, 3).astype(np.float32), normal_index=triangles.copy(),
                     uvs=None, mesh_materials=materials, attributes=named,
                     attributes_read=frozenset(attributes), colors_read=True,    # (none to read)
                     curves=n_curves)


def _unit_or(v, fallback):
    """Rows of ``v`` normalised; where one is (nearly) 0, ``fallback``'s normalised (or x)."""
    n = np.linalg.norm(v, axis=1, keepdims=True)
    f = np.linalg.norm(fallback, axis=1, keepdims=True)
    out = np.where(n > 1e-12, v / np.maximum(n, 1e-300), fallback / np.maximum(f, 1e-300))
    bad = (n[:, 0] <= 1e-12) & (f[:, 0] <= 1e-12)
    out[bad] = (1.0, 0.0, 0.0)
    return out


def _rotation_minimizing(centre, tangent, starts, lengths):
    """(E, 3) unit normals along curves of points ``centre`` and unit ``tangent`` (E, 3), curve c the
    ``lengths[c]`` rows from ``starts[c]``: a normal perpendicular to the first tangent, carried
    along each curve by Wang et al.'s double reflection (a rotation-minimizing frame: the tube does
    not twist), the curves side by side, point after point.  (Blender's own curve normals were not
    usable: ``Curves.normals`` gave 2.8e24 at a curve's first point.)"""
    normal = np.empty_like(tangent)
    normal[starts] = _perpendicular(tangent[starts])
    for i in range(1, int(lengths.max())):
        at = starts[lengths > i] + i
        prev = at - 1
        v1 = centre[at] - centre[prev]
        c1 = np.einsum("ij,ij->i", v1, v1)
        k1 = np.where(c1 > 1e-30, 2.0 / np.maximum(c1, 1e-30), 0.0)[:, None]
        r = normal[prev] - k1 * np.einsum("ij,ij->i", v1, normal[prev])[:, None] * v1
        t = tangent[prev] - k1 * np.einsum("ij,ij->i", v1, tangent[prev])[:, None] * v1
        v2 = tangent[at] - t
        c2 = np.einsum("ij,ij->i", v2, v2)
        k2 = np.where(c2 > 1e-30, 2.0 / np.maximum(c2, 1e-30), 0.0)[:, None]
        r = r - k2 * np.einsum("ij,ij->i", v2, r)[:, None] * v2
        r -= np.einsum("ij,ij->i", r, tangent[at])[:, None] * tangent[at]
        normal[at] = _unit_or(r, _perpendicular(tangent[at]))
    return normal


def _perpendicular(v):
    """A unit vector perpendicular to each unit row of ``v``."""
    axis = np.zeros_like(v)
    axis[np.arange(len(v)), np.argmin(np.abs(v), axis=1)] = 1.0
    p = np.cross(v, axis)
    return p / np.maximum(np.linalg.norm(p, axis=1, keepdims=True), 1e-300)


def _curve_info(keys, radius, first, count, seg, t, b, c, seg_curve, attrs, attributes, name, log,
                first_random=0):
    """{name: (E, 3) values at the tubes' points} of the named ``attributes`` asked for: Curves
    Info's (``HAIR_INFO``, as Cycles sets them: Intercept the length along the keys' polygon over the
    curve's, Length the curve's, Thickness twice the radius, Random ``hash_uint2_to_float(curve,
    0)``, Is Strand 1) and the curves' own attributes on their points (between two keys as t goes)
    or curves."""
    curve_of_point = seg_curve[seg]
    out = {}
    step = np.zeros(len(keys))
    step[1:] = np.linalg.norm(np.diff(keys, axis=0), axis=1)
    step[first] = 0.0
    along = np.cumsum(step)
    along -= np.repeat(along[first], count)                 # (length from each curve's first key)
    length = along[first + count - 1]
    for key in sorted(attributes):
        if key == HAIR_IS_STRAND:
            v = np.ones(len(seg))
        elif key == HAIR_INTERCEPT:
            total = np.repeat(length, count)
            fraction = np.where(total > 0, along / np.where(total > 0, total, 1.0), 0.0)
            v = fraction[b] * (1.0 - t) + fraction[c] * t
        elif key == HAIR_LENGTH:
            v = length[curve_of_point]
        elif key == HAIR_THICKNESS:
            v = 2.0 * (radius[b] * (1.0 - t) + radius[c] * t)
        elif key == HAIR_RANDOM:
            v = hash_uint2_to_float((curve_of_point + first_random).astype(np.uint32),
                                    np.uint32(0)).astype(np.float64)
        else:
            v = None if attrs is None else _curve_attribute(attrs, key, name, log, b, c, t, curve_of_point)
            if v is not None:
                out[key] = v
            continue
        out[key] = np.repeat(np.asarray(v, np.float64)[:, None], 3, axis=1)
    return out


def _curve_attribute(attrs, key, name, log, b, c, t, curve_of_point):
    """(E, 3) a curves attribute ``key`` at the tubes' points (on the points: between keys ``b``
    and ``c`` as ``t`` goes; on the curves: each point's curve's), or None without it."""
    alpha = key.startswith(ALPHA)
    attr = attrs.get(key[len(ALPHA):] if alpha else key)
    if attr is None:
        return None
    kind = ATTRIBUTE_TYPES.get(attr.data_type)
    values = None if kind is None else _curve_values(attr, kind, alpha, b, c, t, curve_of_point)
    if values is None:
        log.warning(f"object '{name}': attribute '{key}' ({attr.data_type.lower()} on the "
                    f"{attr.domain.lower()} domain) cannot be read; it reads 0")
    return values


def _curve_values(attr, kind, alpha, b, c, t, curve_of_point):
    """(E, 3) float64 values of a curves attribute (``ATTRIBUTE_TYPES`` entry ``kind``) at the tubes'
    points: on the curves' points between keys ``b`` and ``c`` as ``t`` goes (as Cycles
    interpolates a key's attribute along its segment), on the curves each point's curve's; None on
    another domain."""
    if attr.domain not in ("POINT", "CURVE"):
        return None
    values = _attribute_values(attr, kind, alpha).astype(np.float64)
    if attr.domain == "CURVE":
        return values[curve_of_point]
    return values[b] * (1.0 - t)[:, None] + values[c] * t[:, None]


def _positions_and_radii(attrs, n, default):
    """((n, 3) float64 positions, (n,) float64 radii) of a point cloud's or a hair object's points
    (attribute collection ``attrs``): their ``radius`` attribute, or ``default`` without one."""
    positions = np.empty(n * 3, np.float32)
    attrs["position"].data.foreach_get("vector", positions)
    radius = np.full(n, default)
    r_attr = attrs.get("radius")
    if r_attr is not None and r_attr.domain == "POINT" and r_attr.data_type == "FLOAT":
        values = np.empty(n, np.float32)
        r_attr.data.foreach_get("value", values)
        radius = values.astype(np.float64)
    return positions.reshape(n, 3).astype(np.float64), radius


def _point_attribute(attrs, key, name, log):
    """(n, 3) float values of a point cloud's attribute ``key`` on its points (as
    :func:`_named_attributes` reads a mesh's, an ``ALPHA`` name its alpha), or None without it (0,
    as in Cycles)."""
    alpha = key.startswith(ALPHA)
    attr = attrs.get(key[len(ALPHA):] if alpha else key)
    if attr is None:
        return None
    kind = ATTRIBUTE_TYPES.get(attr.data_type)
    if kind is None or attr.domain != "POINT":
        log.warning(f"object '{name}': attribute '{key}' ({attr.data_type.lower()} on the "
                    f"{attr.domain.lower()} domain) cannot be read; it reads 0")
        return None
    return _attribute_values(attr, kind, alpha)


def _triangulate(me, positions, corner_vert):
    """(T, 3) corner indices of the triangles and (T,) their polygons, in Blender's order.

    Triangles and quads are split here exactly as Blender's tessellation splits them
    (``mesh_tessellate``: a quad is cut along its 0-2 diagonal unless the triangles
    (0, 1, 2) and (0, 3, 2) face the same way, in float32); a mesh with any n-gon
    takes Blender's ``loop_triangles``.
    """
    n_poly, n_corner = len(me.polygons), len(corner_vert)
    # Blender's triangle-to-polygon map is a fast array read (``polygons.loop_start`` goes
    # through RNA per item: 20 ms per million); a k-gon has k - 2 triangles, and the corners
    # of a polygon are contiguous and in order, so it also gives every polygon's corners.
    tri_poly = np.empty(len(me.loop_triangle_polygons), np.int32)
    me.loop_triangle_polygons.foreach_get("value", tri_poly)
    size = (np.bincount(tri_poly, minlength=n_poly) + 2).astype(np.int32)
    if size.max() > 4 or int(size.sum()) != n_corner:
        me.calc_loop_triangles()
        tri_loops = np.empty(len(tri_poly) * 3, np.int32)
        me.loop_triangles.foreach_get("loops", tri_loops)
        return tri_loops.reshape(-1, 3), tri_poly
    start = (np.cumsum(size) - size).astype(np.int32)
    quads = np.flatnonzero(size == 4)
    if len(quads) == 0:
        return start[:, None] + np.arange(3, dtype=np.int32), tri_poly
    q = start.take(quads)
    # (np.take: fancy indexing of rows is several times slower.)
    p0, p1, p2, p3 = (np.take(positions, corner_vert.take(q + k), axis=0) for k in range(4))
    # (float32 as Blender's: coordinates near its limit overflow to infinity there too, and a NaN
    # product does not flip the quad)
    with np.errstate(over="ignore", invalid="ignore"):
        d13 = p2 - p0
        flip = np.einsum("qi,qi->q", _cross(p1 - p0, d13), _cross(p3 - p0, d13)) > 0
    split = np.array([[[0, 1, 2], [0, 2, 3]], [[0, 1, 3], [1, 2, 3]]], np.int32)
    quad_loops = q[:, None, None] + np.take(split, flip.astype(np.intp), axis=0)    # (Q, 2, 3)
    if len(quads) == n_poly:
        return quad_loops.reshape(-1, 3), tri_poly
    first = start - 2 * np.arange(n_poly, dtype=np.int32)   # each polygon's first triangle
    tri_loops = np.empty((len(tri_poly), 3), np.int32)
    tris = np.flatnonzero(size == 3)
    tri_loops[first[tris]] = start[tris, None] + np.arange(3, dtype=np.int32)
    tri_loops[first[quads]] = quad_loops[:, 0]
    tri_loops[first[quads] + 1] = quad_loops[:, 1]
    return tri_loops, tri_poly


def _cross(a, b):
    """Row-wise cross product of (n, 3) arrays (np.cross is slower for many short rows)."""
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


def _shading_normals(me, tri_vert, tri_loops):
    """(N, 3) float32 shading normals and their (T, 3) rows at the triangle corners, or None, None
    for flat shading.  They stay per vertex or per corner until transformed (fewer rows)."""
    domain = me.normals_domain
    if domain == "FACE":
        return None, None
    if domain == "POINT":
        n = np.empty(len(me.vertices) * 3, np.float32)
        me.vertex_normals.foreach_get("vector", n)
        return n.reshape(-1, 3), tri_vert
    n = np.empty(len(me.loops) * 3, np.float32)
    me.corner_normals.foreach_get("vector", n)
    return n.reshape(-1, 3), tri_loops


def _corner_uvs(me, layer, tri_loops):
    """(T, 3, 2) float32 coordinates of UV map ``layer`` (the active render one), or None without one."""
    if layer is None:
        return None
    attr = me.attributes.get(layer.name)
    if attr is None or attr.domain != "CORNER":
        return None
    uv = np.empty(len(me.loops) * 2, np.float32)
    attr.data.foreach_get("vector", uv)
    return np.take(uv.reshape(-1, 2), tri_loops, axis=0)


def _corner_colors(me, tri_vert, tri_loops):
    """(T, 3, 3) float32 scene-linear RGB of the render colour attribute (Cycles' default for a
    Color Attribute node) at the triangle corners, or None without one."""
    attrs = me.color_attributes
    index = attrs.render_color_index
    if not len(attrs) or not 0 <= index < len(attrs):
        return None
    attr = attrs[index]
    if attr.domain not in ("POINT", "CORNER"):
        return None
    rgba = np.empty(len(attr.data) * 4, np.float32)
    attr.data.foreach_get("color", rgba)         # linear for byte colours too
    rows = tri_vert if attr.domain == "POINT" else tri_loops
    return np.take(rgba.reshape(-1, 4)[:, :3], rows, axis=0)


# Blender attribute data types the core reads: (property, components, buffer dtype).
ATTRIBUTE_TYPES = {"FLOAT": ("value", 1, np.float32), "INT": ("value", 1, np.int32),
                   "INT8": ("value", 1, np.int32), "BOOLEAN": ("value", 1, bool),
                   "FLOAT_VECTOR": ("vector", 3, np.float32), "FLOAT2": ("vector", 2, np.float32),
                   "INT32_2D": ("value", 2, np.int32), "FLOAT_COLOR": ("color", 4, np.float32),
                   "BYTE_COLOR": ("color", 4, np.float32)}


# The name under which Geometry's Random Per Island is kept in ``Scene.attributes`` (Blender's
# internal names start with a dot: no attribute of the mesh has it).
RANDOM_PER_ISLAND = ".random_per_island"
POINTINESS = ".pointiness"                      # (and Geometry's Pointiness)
# ALPHA + a name: the Alpha of that attribute (an Attribute or Color Attribute node's): a colour's
# alpha, 1 for the other types and where the mesh has none; ALPHA alone: the render colour attribute's.
ALPHA = ".alpha:"
# Point Info's outputs (a point cloud's spheres: their point's centre, radius and Cycles' random
# number hash_uint2_to_float(index, 0)), read as named attributes; 0 on meshes, as in Cycles.
POINT_POSITION, POINT_RADIUS, POINT_RANDOM = ".point_position", ".point_radius", ".point_random"
POINT_INFO = (POINT_POSITION, POINT_RADIUS, POINT_RANDOM)
# Curves Info's outputs (Cycles' curve attributes: Is Strand, Intercept, Length, Thickness, Random),
# read as named attributes of the tubes (:func:`read_curves`); 0 on meshes, as in Cycles.
HAIR_IS_STRAND, HAIR_INTERCEPT, HAIR_LENGTH, HAIR_THICKNESS, HAIR_RANDOM = (
    ".hair_is_strand", ".hair_intercept", ".hair_length", ".hair_thickness", ".hair_random")
HAIR_INFO = (HAIR_IS_STRAND, HAIR_INTERCEPT, HAIR_LENGTH, HAIR_THICKNESS, HAIR_RANDOM)


def _edges(me):
    """(E, 2) int32 the vertices of the mesh's edges, in Blender's order."""
    pairs = np.empty(len(me.edges) * 2, np.int32)
    me.edges.foreach_get("vertices", pairs)
    return pairs.reshape(-1, 2)


def pointiness(me):
    """(V,) float64 Cycles' Pointiness (``attr_create_pointiness``) of each vertex: vertices at the
    same place welded, the angle between the welded vertex normal and the mean of the unit edges
    leaving it, over pi, then blurred once with its edge neighbours (the mean of itself and
    them)."""
    n = len(me.vertices)
    if n == 0:
        return np.zeros(0)
    co = np.empty(n * 3, np.float32)
    me.vertices.foreach_get("co", co)
    co = co.reshape(n, 3).astype(np.float64)
    normals = np.empty(n * 3, np.float32)
    me.vertices.foreach_get("normal", normals)
    normals = normals.reshape(n, 3).astype(np.float64)
    # Duplicates: vertices at the same place (to 1e-4; Cycles: within sqrt(FLT_EPSILON)) share one.
    _, first, orig = np.unique(np.round(co / 1e-4), axis=0, return_index=True, return_inverse=True)
    orig = first.take(orig.ravel())
    welded = np.zeros((n, 3))
    np.add.at(welded, orig, normals)
    length = np.linalg.norm(welded, axis=1, keepdims=True)
    welded = np.divide(welded, length, out=np.zeros_like(welded), where=length > 0).take(orig, axis=0)
    e = orig.take(_edges(me))
    e = np.unique(np.sort(e[e[:, 0] != e[:, 1]], axis=1), axis=0)          # each welded edge once
    d = co.take(e[:, 1], axis=0) - co.take(e[:, 0], axis=0)
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-30)
    accum, count = np.zeros((n, 3)), np.zeros(n)
    np.add.at(accum, e[:, 0], d)
    np.add.at(accum, e[:, 1], -d)
    np.add.at(count, e.ravel(), 1.0)
    mean = np.divide(accum, count[:, None], out=np.zeros_like(accum), where=count[:, None] > 0)
    raw = np.where(count > 0, np.arccos(np.clip((welded * mean).sum(axis=1), -1.0, 1.0)) / np.pi, 0.0)
    blurred = raw.copy()
    np.add.at(blurred, e[:, 0], raw.take(e[:, 1]))
    np.add.at(blurred, e[:, 1], raw.take(e[:, 0]))
    blurred /= count + 1.0
    return blurred.take(orig)


def random_per_island(me, tri_vert):
    """(T,) float32 Cycles' Random Per Island of each triangle: ``hash_uint_to_float`` of the root
    of its first vertex's island, the islands joined edge by edge in Blender's order by Cycles'
    union by rank (``DisjointSet``), whose roots the hash sees; a Python loop over the edges (at
    export, only for materials that read it)."""
    parent = list(range(len(me.vertices)))
    rank = [0] * len(parent)

    def find(x):
        root = x
        while parent[root] != root:
            root = parent[root]
        while parent[x] != root:
            parent[x], x = root, parent[x]
        return root

    for a, b in _edges(me).tolist():
        ra, rb = find(a), find(b)
        if ra == rb:
            continue
        if rank[ra] < rank[rb]:
            ra, rb = rb, ra
        parent[rb] = ra
        if rank[ra] == rank[rb]:
            rank[ra] += 1
    roots = np.array([find(v) for v in range(len(parent))], np.int64)
    return hash_uint_to_float(roots.take(tri_vert[:, 0])).astype(np.float32)


def _named_attributes(me, names, tri_vert, tri_loops, tri_poly, mesh_name, log):
    """{name: (T, 3, 3) float32} of the ``names`` the mesh has as attributes Cycles reads by name (a
    float repeated in x, y, z; a 2D value (x, y, 0); a colour's linear RGB), per triangle corner
    from its point, corner or face domain (``tri_loops``, ``tri_poly``: None where only the two
    computed ones, ``RANDOM_PER_ISLAND`` and ``POINTINESS``, are asked for); an ``ALPHA`` name its
    attribute's alpha; the others are left out (0, as in Cycles), an unusable one with a warning."""
    out = {}
    for name in sorted(names):
        if name in (RANDOM_PER_ISLAND, POINTINESS):
            if name == RANDOM_PER_ISLAND:
                values = np.repeat(random_per_island(me, tri_vert)[:, None], 3, axis=1)     # (T, 3)
            else:
                values = pointiness(me).take(tri_vert)
            out[name] = np.repeat(values[:, :, None], 3, axis=2).astype(np.float32)
            continue
        alpha = name.startswith(ALPHA)
        attr = _attribute(me, name[len(ALPHA):] if alpha else name)
        if attr is None:
            continue
        kind = ATTRIBUTE_TYPES.get(attr.data_type)
        rows = {"POINT": tri_vert, "CORNER": tri_loops,
                "FACE": np.repeat(np.asarray(tri_poly)[:, None], 3, axis=1)}.get(attr.domain)
        if kind is None or rows is None:
            log.warning(f"object '{mesh_name}': attribute '{name}' ({attr.data_type.lower()} on the "
                        f"{attr.domain.lower()} domain) cannot be read; it reads 0")
            continue
        out[name] = np.take(_attribute_values(attr, kind, alpha), rows, axis=0)
    return out


def _attribute(me, name):
    """Mesh ``me``'s attribute ``name`` ('': the render colour attribute), or None."""
    if name:
        return me.attributes.get(name)
    attrs = me.color_attributes
    index = attrs.render_color_index
    return me.attributes.get(attrs[index].name) if len(attrs) and 0 <= index < len(attrs) else None


def _attribute_values(attr, kind, alpha=False):
    """(n, 3) float32 values of a Blender attribute of ``ATTRIBUTE_TYPES`` entry ``kind``, as Cycles
    reads them by name: a float repeated in x, y, z; a 2D value (x, y, 0); a colour's RGB.  With
    ``alpha``: its Alpha (Cycles' attribute node), repeated in x, y, z: a colour's, 1 for the others."""
    prop, k, dtype = kind
    if alpha and k != 4:
        return np.ones((len(attr.data), 3), np.float32)
    flat = np.empty(len(attr.data) * k, dtype)
    attr.data.foreach_get(prop, flat)
    values = flat.reshape(-1, k).astype(np.float32)
    if alpha:
        return np.repeat(values[:, 3:], 3, axis=1)
    return {1: np.repeat(values, 3, axis=1), 2: np.pad(values, ((0, 0), (0, 1))), 3: values,
            4: values[:, :3]}[k]


def _corner_tangents(me, layer, tri_loops):
    """(T, 3, 4) float32 MikkTSpace tangents (object space) and bitangent signs of UV map ``layer``
    at the triangle corners, as Cycles computes them; None where Blender cannot (it refuses
    meshes with n-gons)."""
    try:
        me.calc_tangents(uvmap=layer.name)
    except RuntimeError:
        return None
    n = len(me.loops)
    t = np.empty(n * 3, np.float32)
    me.loops.foreach_get("tangent", t)
    sign = np.empty(n, np.float32)
    me.loops.foreach_get("bitangent_sign", sign)
    frames = np.concatenate([t.reshape(-1, 3), sign[:, None]], axis=1)
    return np.take(frames, tri_loops, axis=0)


def _triangulated_copy(me):
    """A new mesh datablock: ``me`` with every face triangulated (same materials and UVs)."""
    import bmesh
    import bpy
    bm = bmesh.new()
    try:
        bm.from_mesh(me)
        bmesh.ops.triangulate(bm, faces=bm.faces[:])
        copy = bpy.data.meshes.new(f"{me.name} (triangulated)")
        bm.to_mesh(copy)
    finally:
        bm.free()
    for m in me.materials:
        copy.materials.append(m)
    return copy


def assemble(meshes, groups, materials, infos=None, properties=None, passes=frozenset(),
             cryptos=None, crypto_names=()) -> Geometry:
    """Transform every instance group to world space and concatenate; ``infos``: the groups'
    Object Info rows (:func:`object_info`), kept when some material reads them or ``passes`` has
    "object_index" (the Object Index pass), ``properties`` their objects' properties
    (:func:`object_property`); the UVs are kept when some material reads them or ``passes`` has "uv"."""
    parts = []
    offset = 0
    instances = 0
    # Data of procedural textures, when some material reads it (for every triangle).
    coordinates = materials.coordinates_used({i for _, ids, _, _ in groups for i in ids})
    if "object_index" in passes:
        coordinates.add("object_info")              # (the pass index is the Object Info's)
    objects = reads_objects(coordinates)
    names = sorted(n for n in coordinates if n.startswith(OBJECT_PROPERTY))
    for (key, mat_ids, visibility, link), matrices in groups.items():
        part = transform_instances(meshes[key], np.stack(matrices), np.asarray(mat_ids, np.int32), offset,
                                   coordinates)
        part["visibility"] = np.full(len(part["triangles"]), visibility & VISIBILITY_MASK, np.uint8)
        part["exclude"] = np.full(len(part["triangles"]), (visibility >> EXCLUDE_SHIFT) & 0xFF,
                                  np.uint8)
        part["group"] = np.full(len(part["triangles"]), (visibility >> GROUP_SHIFT) - 1, np.int16)
        part["link"] = link
        if objects:
            part["object_ids"] += instances
            if coordinates & set(OBJECT_INFO) and infos is not None:
                rows = infos[key, mat_ids, visibility, link]
                part["object_info"] = np.stack([np.zeros(6, np.float32) if r is None else r for r in rows])
            for n in names:
                values = [p.get(n) for p in (properties or {}).get((key, mat_ids, visibility, link), [])]
                part[n] = np.stack([np.zeros(3, np.float32) if v is None else v for v in values]) \
                    if len(values) == len(matrices) else np.zeros((len(matrices), 3), np.float32)
        if cryptos is not None:
            # (the instances' triangles follow each other: transform_instances)
            per = len(part["triangles"]) // max(len(matrices), 1)
            pairs = np.array(cryptos[key, mat_ids, visibility, link], np.int32)
            part["crypto"] = np.repeat(pairs, per, axis=0)
        parts.append(part)
        offset += len(part["vertices"])
        instances += len(matrices)
    if not parts:
        return Geometry.empty()
    vertices = np.concatenate([p["vertices"] for p in parts])
    generated = None
    if any("generated_vertices" in p for p in parts):
        generated = np.concatenate([p.get("generated_vertices", p["vertices"]) for p in parts])
    triangles = np.concatenate([p["triangles"] for p in parts])
    material_ids = np.concatenate([p["material_ids"] for p in parts])
    normals = None
    if any(p["normals"] is not None for p in parts):
        normals = np.concatenate([p["normals"] if p["normals"] is not None
                                  else _flat_normals(vertices, p["triangles"]) for p in parts])
    uvs = tangents = None
    used = np.flatnonzero(np.bincount(material_ids))
    if "uv" in passes or materials.uses_textures(used):
        uvs = np.concatenate([p["uvs"] if p["uvs"] is not None
                              else np.zeros((len(p["triangles"]), 3, 2), np.float32) for p in parts])
    objects = {name: np.concatenate([p[name] for p in parts])
               for name in ("object_ids", "object_from_world", "texture_spaces", "object_info")
               if name in parts[0]}
    if objects and names:
        objects["object_attributes"] = {n: np.concatenate([p[n] for p in parts]) for n in names}
    if materials.tangent_uv(used) is not None:
        # Zero tangents (meshes without UVs or a tangent frame) keep the unbent normal, as in Cycles.
        tangents = np.concatenate([p["tangents"] if p["tangents"] is not None
                                   else np.zeros((len(p["triangles"]), 3, 4), np.float32) for p in parts])
    visibility = np.concatenate([p["visibility"] for p in parts])
    exclude = np.concatenate([p["exclude"] for p in parts])
    group = np.concatenate([p["group"] for p in parts])
    links = {}
    sizes = [len(p["triangles"]) for p in parts]
    for k, (sets, collections) in enumerate((("receiver_sets", "emitter_collections"),
                                              ("blocker_sets", "shadow_collections"))):
        if parts[0]["link"][k] is not None:
            links[sets] = np.repeat(np.uint8([p["link"][k][0] for p in parts]), sizes)
            links[collections] = np.repeat(np.int16([p["link"][k][1] for p in parts]), sizes)
    hidden = materials.hidden_rays()
    if hidden.any():
        visibility &= ~hidden.take(material_ids)          # Light Path mixes (materials.py)
    crypto = crypto_manifests = None
    if cryptos is not None:
        crypto, crypto_manifests = crypto_ids(np.concatenate([p["crypto"] for p in parts]), crypto_names)
    return Geometry(vertices=vertices, triangles=np.ascontiguousarray(triangles, np.int32),
                    material_ids=np.ascontiguousarray(material_ids, np.int32),
                    shading_normals=None if normals is None else np.ascontiguousarray(normals, np.float32),
                    uvs=None if uvs is None else np.ascontiguousarray(uvs, np.float32),
                    tangents=None if tangents is None else np.ascontiguousarray(tangents, np.float32),
                    colors=np.concatenate([p["color"] for p in parts]) if "color" in coordinates else None,
                    attributes={key[len(NAMED):]: np.concatenate([p[key] for p in parts])
                                for key in sorted(coordinates) if key.startswith(NAMED)} or None,
                    **objects, generated_vertices=generated,
                    triangle_visibility=visibility if (visibility != ALL_RAYS).any() else None,
                    emitter_exclude=exclude if exclude.any() else None,
                    emitter_group=group if (group >= 0).any() else None,
                    cryptomatte=crypto, crypto_names=crypto_manifests,
                    instances=instances, **links)


def crypto_ids(index, names):
    """((T, 2) float32 Cryptomatte ids, {"crypto_object", "crypto_asset": {name: hex}}) of the
    triangles' (object, asset) ``index`` (T, 2) int32 into ``names`` (:func:`crypto_names`; each
    name hashed once)."""
    hashed = [name_id(n) for n in names]
    table = np.array([h[0] for h in hashed], np.float32)
    manifests = {kind: {names[i]: hashed[i][1] for i in np.unique(index[:, column])}
                 for column, kind in enumerate(("crypto_object", "crypto_asset"))}
    return table.take(index), manifests


def transform_instances(local, world_from_object, mat_ids, vertex_offset, coordinates=frozenset()):
    """World-space arrays of ``k`` instances of ``local``.

    world_from_object : (k, 4, 4) float64.  mat_ids : (n_slots,) int32 core material
    ids of the slots.  Returns a dict of vertices (k V, 3) float32, triangles (k T, 3)
    int32 offset by ``vertex_offset``, material_ids (k T,), normals (k T, 3, 3) float32
    or None, uvs (k T, 3, 2) float32 or None and tangents (k T, 3, 4) float32 or None; with
    "object", "generated", "normal" or Object Info in ``coordinates`` also object_ids (k T,) int32
    (0 .. k - 1, the instance), object_from_world (k, 3, 4) float64 and texture_spaces (k, 2, 3)
    float64, and with
    "color" the render colour attribute per corner, color (k T, 3, 3) float32 (black without one).
    """
    k = len(world_from_object)
    rot = world_from_object[:, :3, :3]
    n_v, n_t = len(local.positions), len(local.triangles)
    # One batched matrix product per mesh: (1, V, 3) @ (k, 3, 3) -> (k, V, 3).
    vertices = np.matmul(local.positions[None], rot.transpose(0, 2, 1)) + world_from_object[:, None, :3, 3]
    # Mirroring instances (det < 0) keep their front side by reversing the winding.
    mirrored = np.flatnonzero(np.linalg.det(rot) < 0)
    tri = local.triangles[None, :, :] + (vertex_offset + n_v * np.arange(k, dtype=np.int64))[:, None, None]
    _swap_corners(tri, mirrored)
    slot = np.clip(local.slots, 0, len(mat_ids) - 1)
    material_ids = np.tile(mat_ids[slot], k)
    normals = tangents = None
    normal_from_object = None
    if local.normals is not None or local.tangents is not None:
        normal_from_object = _inverse_transpose(rot).astype(np.float32)
    if local.normals is not None:
        n = np.matmul(local.normals[None], normal_from_object.transpose(0, 2, 1))      # (k, N, 3)
        # Rotations keep unit length; scaled or sheared instances are renormalised.
        gram = np.matmul(normal_from_object, normal_from_object.transpose(0, 2, 1))
        rescale = np.flatnonzero(np.abs(gram - np.eye(3, dtype=np.float32)).max(axis=(1, 2)) > 1e-5)
        if len(rescale):
            # In place when every instance needs it (no copies of the whole normal array).
            m = n if len(rescale) == k else n[rescale]
            length = np.sqrt(np.einsum("kci,kci->kc", m, m))
            m /= np.maximum(length, 1e-30)[..., None]
            if m is not n:
                n[rescale] = m
        normals = np.take(n, local.normal_index, axis=1)                               # (k, T, 3, 3)
        _swap_corners(normals, mirrored)
        normals = normals.reshape(k * n_t, 3, 3)
    uvs = None
    if local.uvs is not None:
        uvs = np.repeat(local.uvs[None], k, axis=0) if (k > 1 or len(mirrored)) else local.uvs[None]
        _swap_corners(uvs, mirrored)
        uvs = uvs.reshape(k * n_t, 3, 2)
    if local.tangents is not None:
        # Tangents as the normals (Cycles transforms the bent normal with the normal matrix), unit
        # length; the bitangent sign flips where the instance mirrors: N x T flips there.
        t = np.matmul(local.tangents[None, :, :, :3], normal_from_object[:, None].transpose(0, 1, 3, 2))
        t /= np.maximum(np.sqrt(np.einsum("ktci,ktci->ktc", t, t)), 1e-30)[..., None]
        sign = np.repeat(local.tangents[None, :, :, 3], k, axis=0)
        sign[mirrored] *= -1.0
        tangents = np.concatenate([t, sign[..., None]], axis=3)                       # (k, T, 3, 4)
        _swap_corners(tangents, mirrored)
        tangents = tangents.reshape(k * n_t, 3, 4)
    with np.errstate(over="ignore"):                # (past float32: infinity, left out by within_reach)
        world = vertices.reshape(k * n_v, 3).astype(np.float32)
    out = {"vertices": world,
           "triangles": tri.reshape(k * n_t, 3).astype(np.int32), "material_ids": material_ids,
           "normals": normals, "uvs": uvs, "tangents": tangents}
    # Texture coordinates of procedural textures: each instance's own object space.
    if "generated" in coordinates and local.orco is not None:
        undeformed = np.matmul(local.orco[None], rot.transpose(0, 2, 1)) + world_from_object[:, None, :3, 3]
        with np.errstate(over="ignore", invalid="ignore"):
            out["generated_vertices"] = np.nan_to_num(undeformed.reshape(k * n_v, 3).astype(np.float32),
                                                      nan=0.0, posinf=0.0, neginf=0.0)
    if reads_objects(coordinates):
        out["object_ids"] = np.repeat(np.arange(k, dtype=np.int32), n_t)
        out["object_from_world"] = affine_inverse(world_from_object)[:, :3, :4]
        out["texture_spaces"] = np.repeat(np.asarray(local.texspace, np.float64)[None], k, axis=0)
    for key in coordinates:
        if key == "color" or key.startswith(NAMED):
            # Meshes without such a colour attribute (or named one) read 0, as in Cycles, and its
            # Alpha 1.
            c = local.colors if key == "color" else local.attributes.get(key[len(NAMED):])
            if c is None:
                c = np.full((n_t, 3, 3), 1.0 if key.startswith(NAMED + ALPHA) else 0.0, np.float32)
            c = np.repeat(c[None], k, axis=0)
            if key == NAMED + POINT_POSITION and local.attributes.get(POINT_POSITION) is not None:
                # Point Info's Position is in world space: each instance's point centres moved with it.
                c = (np.matmul(c.astype(np.float64), rot[:, None].transpose(0, 1, 3, 2))
                     + world_from_object[:, None, None, :3, 3]).astype(np.float32)
            _swap_corners(c, mirrored)
            out[key] = c.reshape(k * n_t, 3, 3)
    return out


def _swap_corners(a, instances):
    """Exchange corners 1 and 2 of every triangle of the given instances of a (k, T, 3, ...)."""
    if len(instances):
        a[instances, :, 1], a[instances, :, 2] = a[instances, :, 2].copy(), a[instances, :, 1].copy()


def _inverse_transpose(rot):
    """(k, 3, 3) inverse transposes; pseudo-inverse for flattened (singular) instances."""
    return inverse(rot).transpose(0, 2, 1)


def _flat_normals(vertices, triangles):
    """(T, 3, 3) float32 geometric normals repeated at each corner."""
    p = vertices[triangles].astype(np.float64)
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    return np.repeat(n[:, None, :], 3, axis=1).astype(np.float32)
