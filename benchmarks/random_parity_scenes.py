"""The random rooms of ``random_parity.py``: specs drawn from a seed, and their builder in ``bpy``.

Two families: "rooms" (:func:`random_spec`) and "glass" (:func:`random_glass_spec`, transmissive
objects, caustics and volumes; ``FAMILIES``).
A spec is a JSON-able dict (:func:`random_spec`): ``room`` (open or closed, size, height, the
floor's, walls' and ceiling's materials; optionally ``keep_walls``, the open room's walls to keep,
of "Back" and "Left"), ``objects`` (shape, place, size, turn, lift and material each), ``lights``
(kind and parameters each; point, spot, area, emissive panel, sun, world colour, sky texture) and
``cam_lens``; a glass spec also has ``family``, ``camera`` (location, target, lens) and
``light_paths`` (Cycles' bounce limits, which ours takes too).  A material is a dict of ``kind``
(diffuse, principled, glossy, translucent, emission, glass, refraction, mix / add of two, or none:
no surface) and its parameters, with an optional checker or noise ``texture`` and ``volume``
(absorption, scatter or principled_volume on the Volume output).
:func:`build` makes a spec's scene with ``tests/addon/blender_scenes.py`` (on ``sys.path``, with
the add-on registered, as ``random_parity.py``'s render process does); it imports ``bpy`` only
when called, so that the specs are drawn without it.
"""
from __future__ import annotations

import math
import random


# ------------------------------------------------------------------------------ random specs
def rcol(rng, lo=0.1, hi=0.9):
    return [round(rng.uniform(lo, hi), 3) for _ in range(3)]


def rand_bsdf(rng, allow_emission=True):
    kinds = ["diffuse", "principled", "principled", "glossy", "translucent"]
    if allow_emission:
        kinds.append("emission")
    k = rng.choice(kinds)
    if k == "diffuse":
        return {"kind": "diffuse", "color": rcol(rng)}
    if k == "glossy":
        return {"kind": "glossy", "color": rcol(rng, 0.3, 0.95), "roughness": round(rng.uniform(0.2, 0.7), 3)}
    if k == "translucent":
        return {"kind": "translucent", "color": rcol(rng, 0.3, 0.9)}
    if k == "emission":
        return {"kind": "emission", "color": rcol(rng, 0.5, 1.0), "strength": round(rng.uniform(1.0, 6.0), 2)}
    p = {"kind": "principled", "base": rcol(rng), "roughness": round(rng.uniform(0.2, 0.9), 3),
         "metallic": rng.choice([0.0, 0.0, 0.0, 1.0, round(rng.uniform(0, 1), 2)])}
    if rng.random() < 0.3:
        p["coat"] = round(rng.uniform(0.3, 1.0), 2)
        p["coat_roughness"] = round(rng.uniform(0.2, 0.5), 2)
    if rng.random() < 0.3:
        p["sheen"] = round(rng.uniform(0.3, 1.0), 2)
        p["sheen_roughness"] = round(rng.uniform(0.3, 0.8), 2)
    if rng.random() < 0.3:
        p["specular_level"] = round(rng.uniform(0.0, 1.0), 2)
    if rng.random() < 0.15:
        p["subsurface"] = round(rng.uniform(0.05, 0.2), 2)
    return p


def rand_material(rng, allow_emission=True, allow_mix=True):
    mix = rng.random() < 0.2           # (drawn also when not allowed: the seeds' rooms stay as they were)
    if allow_mix and mix:
        return {"kind": rng.choice(["mix", "add"]), "fac": round(rng.uniform(0.2, 0.8), 2),
                "a": rand_bsdf(rng, False), "b": rand_bsdf(rng, False)}
    m = rand_bsdf(rng, allow_emission)
    if m["kind"] in ("diffuse", "principled", "glossy") and rng.random() < 0.25:
        m["texture"] = {"type": rng.choice(["checker", "noise"]), "scale": round(rng.uniform(2, 8), 2),
                        "c1": rcol(rng), "c2": rcol(rng)}
    return m


def rand_light(rng, room, kinds):
    k = rng.choice(kinds)
    h = room["height"]
    w = room["size"] / 2
    if k == "point":
        return {"kind": "point", "loc": [rng.uniform(-w + 0.5, w - 0.5), rng.uniform(-w + 0.5, w - 0.5),
                                         rng.uniform(1.2, h - 0.3)],
                "energy": rng.uniform(100, 600), "radius": rng.uniform(0.05, 0.5),
                "soft": rng.random() < 0.7, "color": rcol(rng, 0.6, 1.0)}
    if k == "spot":
        return {"kind": "spot", "loc": [rng.uniform(-w + 0.5, w - 0.5), rng.uniform(-w + 0.5, 0.0),
                                        rng.uniform(1.5, h - 0.2)],
                "target": [rng.uniform(-1, 1), rng.uniform(-1, 1), 0.0],
                "energy": rng.uniform(300, 1200), "radius": rng.uniform(0.05, 0.3),
                "spot_size": math.radians(rng.uniform(40, 110)), "blend": rng.uniform(0.1, 0.8),
                "color": rcol(rng, 0.6, 1.0)}
    if k == "area":
        shape = rng.choice(["SQUARE", "RECTANGLE", "DISK", "ELLIPSE"])
        return {"kind": "area", "shape": shape,
                "loc": [rng.uniform(-w + 0.6, w - 0.6), rng.uniform(-w + 0.6, w - 0.6),
                        h - rng.uniform(0.05, 0.6)],
                "target": [rng.uniform(-1, 1), rng.uniform(-1, 1), 0.0],
                "energy": rng.uniform(200, 800), "size": rng.uniform(0.4, 1.5),
                "size_y": rng.uniform(0.3, 1.2),
                "spread": math.radians(rng.choice([180, 180, rng.uniform(40, 150)])),
                "color": rcol(rng, 0.6, 1.0)}
    if k == "panel":      # an emissive quad under the ceiling, facing down
        return {"kind": "panel", "loc": [rng.uniform(-w + 0.6, w - 0.6), rng.uniform(-w + 0.6, w - 0.6),
                                         h - rng.uniform(0.05, 0.5)],
                "size": rng.uniform(0.5, 1.5), "strength": rng.uniform(5, 25), "color": rcol(rng, 0.6, 1.0)}
    if k == "sun":
        return {"kind": "sun", "elev": rng.uniform(25, 70), "azim": rng.uniform(180, 330),
                "energy": rng.uniform(1.5, 5.0), "angle": math.radians(rng.uniform(0.5, 15)),
                "color": rcol(rng, 0.7, 1.0)}
    if k == "world":
        return {"kind": "world", "color": rcol(rng, 0.2, 0.8), "strength": rng.uniform(0.5, 1.5)}
    return {"kind": "sky", "elev": rng.uniform(20, 60), "rot": rng.uniform(150, 300),
            "strength": rng.uniform(0.1, 0.3), "sun_disc": rng.random() < 0.5}


def random_spec(seed):
    """The random room of ``seed`` as a JSON-able dict (built by :func:`build`)."""
    rng = random.Random(seed)
    closed = rng.random() < 0.5
    room = {"closed": closed, "size": rng.uniform(4.0, 6.0), "height": rng.uniform(2.6, 3.4),
            "floor": rand_material(rng, False, False), "walls": rand_material(rng, False, False),
            "ceiling": {"kind": "diffuse", "color": rcol(rng, 0.5, 0.9)}}
    # Walls and floor: mostly diffuse-like.
    for key in ("floor", "walls"):
        kind = room[key]["kind"]
        if kind in ("translucent", "emission") or (kind == "glossy" and rng.random() < 0.7):
            room[key] = {"kind": "diffuse", "color": rcol(rng)}
    objects = []
    used = []
    for _ in range(rng.randint(1, 4)):
        t = rng.choice(["cube", "sphere", "cylinder", "plane"])
        for _ in range(20):          # a place at least 1 away from the others (else the 20th tried)
            x, y = rng.uniform(-1.3, 1.3), rng.uniform(-1.0, 1.4)
            if all((x - u) ** 2 + (y - v) ** 2 > 1.0 for u, v in used):
                break
        used.append((x, y))
        o = {"type": t, "loc": [x, y], "size": rng.uniform(0.4, 1.0), "rot": rng.uniform(0, math.pi),
             "lift": rng.choice([0.0, 0.0, rng.uniform(0.2, 0.8)]), "mat": rand_material(rng, True, True)}
        if t == "plane":
            o["tilt"] = rng.uniform(0.6, 1.5)      # standing up-ish
        objects.append(o)
    if closed:
        kinds = ["point", "spot", "area", "area", "panel"]
    else:
        kinds = ["point", "spot", "area", "panel", "sun", "sun", "world", "world", "sky"]
    lights = []
    for _ in range(rng.randint(1, 3)):
        light = rand_light(rng, room, kinds)
        if light["kind"] in ("world", "sky") and any(x["kind"] in ("world", "sky") for x in lights):
            continue                 # one world at most
        lights.append(light)
    return {"seed": seed, "room": room, "objects": objects, "lights": lights, "cam_lens": rng.uniform(22, 32)}


# ------------------------------------------------------------------------------ the glass family
GLASS_LIGHT_PATHS = {"max_bounces": 16, "diffuse_bounces": 8, "glossy_bounces": 16,
                     "transmission_bounces": 16, "volume_bounces": 0, "transparent_max_bounces": 16}


def rand_tint(rng):
    """A glass's colour: clear (white) half the time, else a light tint."""
    return [1.0, 1.0, 1.0] if rng.random() < 0.5 else rcol(rng, 0.6, 1.0)


def rand_glass_material(rng):
    """A transmissive material: Glass (smooth or rough, GGX or Multiscatter GGX), Principled of
    Transmission Weight 1 (sometimes with a coat), Refraction, or a Mix of a Glass and a Diffuse."""
    k = rng.choice(["glass", "glass", "glass", "principled_glass", "principled_glass", "refraction",
                    "glass_mix"])
    rough = 0.0 if rng.random() < 0.5 else round(rng.uniform(0.05, 0.4), 3)
    ior = round(rng.uniform(1.2, 1.8), 3)
    if k == "glass":
        return {"kind": "glass", "color": rand_tint(rng), "roughness": rough, "ior": ior,
                "distribution": rng.choice(["GGX", "MULTI_GGX"])}
    if k == "refraction":
        return {"kind": "refraction", "color": rand_tint(rng), "roughness": rough, "ior": ior,
                "distribution": rng.choice(["GGX", "BECKMANN"])}
    if k == "principled_glass":
        p = {"kind": "principled", "base": rand_tint(rng),
             "roughness": round(rng.choice([0.0, rng.uniform(0, 0.4)]), 3),
             "metallic": 0.0, "transmission": 1.0, "ior": ior}
        if rng.random() < 0.3:
            p["coat"] = round(rng.uniform(0.3, 1.0), 2)
            p["coat_roughness"] = round(rng.uniform(0.0, 0.3), 2)
        return p
    return {"kind": "mix", "fac": round(rng.uniform(0.1, 0.5), 2),
            "a": {"kind": "glass", "color": rand_tint(rng), "roughness": rough, "ior": ior,
                  "distribution": rng.choice(["GGX", "MULTI_GGX"])},
            "b": {"kind": "diffuse", "color": rcol(rng, 0.3, 0.9)}}


def rand_glass_light(rng, room, kinds):
    """A light that Cycles reaches through smooth glass by BSDF sampling: an area light of size at
    least 0.4, an emissive panel, a sun of angle at least 5 degrees or a world colour."""
    k = rng.choice(kinds)
    h, w = room["height"], room["size"] / 2
    if k == "area":
        return {"kind": "area", "shape": rng.choice(["SQUARE", "RECTANGLE", "DISK", "ELLIPSE"]),
                "loc": [rng.uniform(-1.5, 1.5), rng.uniform(-1.0, 1.5), h - rng.uniform(0.05, 0.6)],
                "target": [rng.uniform(-0.8, 0.8), rng.uniform(-0.5, 1.0), 0.0],
                "energy": rng.uniform(200, 800), "size": rng.uniform(0.4, 1.5),
                "size_y": rng.uniform(0.4, 1.2),
                "spread": math.radians(rng.choice([180, 180, rng.uniform(60, 150)])),
                "color": rcol(rng, 0.6, 1.0)}
    if k == "panel":
        return {"kind": "panel",
                "loc": [rng.uniform(-1.5, 1.5), rng.uniform(-1.0, 1.5), h - rng.uniform(0.05, 0.5)],
                "size": rng.uniform(0.5, 1.5), "strength": rng.uniform(5, 25), "color": rcol(rng, 0.6, 1.0)}
    if k == "sun":
        return {"kind": "sun", "elev": rng.uniform(30, 75), "azim": rng.uniform(180, 330),
                "energy": rng.uniform(1.5, 5.0), "angle": math.radians(rng.uniform(5, 15)),
                "color": rcol(rng, 0.7, 1.0)}
    return {"kind": "world", "color": rcol(rng, 0.2, 0.8), "strength": rng.uniform(0.5, 1.5)}


def random_glass_spec(seed):
    """The glass room of ``seed`` (family "glass"): a room (open or closed) with one to three
    transmissive objects (Glass, Principled transmission, Refraction, a Mix of glass and diffuse;
    spheres, cubes, cylinders, thin panes; sometimes an absorbing liquid inside), sometimes a cube
    of a homogeneous scattering volume, zero to two diffuse objects for caustics to land on, and
    one to three lights that Cycles reaches through smooth glass (``rand_glass_light``)."""
    rng = random.Random(f"glass-{seed}")
    closed = rng.random() < 0.5
    room = {"closed": closed, "size": rng.uniform(4.0, 6.0), "height": rng.uniform(2.6, 3.4),
            "floor": {"kind": "diffuse", "color": rcol(rng, 0.4, 0.9)},
            "walls": {"kind": "diffuse", "color": rcol(rng, 0.3, 0.9)},
            "ceiling": {"kind": "diffuse", "color": rcol(rng, 0.5, 0.9)}}
    if rng.random() < 0.3:
        room["floor"]["texture"] = {"type": "checker", "scale": round(rng.uniform(2, 6), 2),
                                    "c1": rcol(rng, 0.3, 0.9), "c2": rcol(rng, 0.3, 0.9)}
    objects, used = [], []

    def place():
        for _ in range(20):
            x, y = rng.uniform(-1.1, 1.1), rng.uniform(-0.6, 1.2)
            if all((x - u) ** 2 + (y - v) ** 2 > 0.8 for u, v in used):
                break
        used.append((x, y))
        return [x, y]
    for _ in range(rng.randint(1, 3)):
        t = rng.choice(["sphere", "sphere", "cube", "cylinder", "pane"])
        o = {"type": t, "loc": place(), "size": rng.uniform(0.4, 1.0), "rot": rng.uniform(0, math.pi),
             "lift": rng.choice([0.0, 0.0, rng.uniform(0.2, 0.8)]), "mat": rand_glass_material(rng)}
        if t == "pane":
            o["thickness"] = rng.uniform(0.02, 0.08)
            o["tilt"] = rng.choice([0.0, math.pi / 2, rng.uniform(0.3, 1.3)])   # standing, lying, leaning
        if t != "pane" and rng.random() < 0.3:
            o["mat"]["volume"] = {"kind": "absorption", "color": rcol(rng, 0.2, 0.9),
                                  "density": round(rng.uniform(0.5, 4.0), 2)}
        objects.append(o)
    if rng.random() < 0.25:
        objects.append({"type": "cube", "loc": place(), "size": rng.uniform(0.5, 1.1),
                        "rot": rng.uniform(0, math.pi),
                        "lift": 0.0, "mat": {"kind": "none", "volume": {
                            "kind": rng.choice(["principled_volume", "scatter"]),
                            "color": rcol(rng, 0.5, 1.0),
                            "density": round(rng.uniform(0.2, 1.5), 2),
                            "anisotropy": round(rng.uniform(-0.3, 0.6), 2)}}})
    for _ in range(rng.randint(0, 2)):
        t = rng.choice(["cube", "plane", "sphere"])
        o = {"type": t, "loc": place(), "size": rng.uniform(0.3, 0.8), "rot": rng.uniform(0, math.pi),
             "lift": 0.0, "mat": {"kind": "diffuse", "color": rcol(rng, 0.3, 0.9)}}
        if t == "plane":
            o["tilt"] = rng.uniform(1.2, 1.57)
        objects.append(o)
    kinds = ["area", "area", "panel"] if closed else ["area", "panel", "sun", "sun", "world"]
    lights = []
    for _ in range(rng.randint(1, 3)):
        light = rand_glass_light(rng, room, kinds)
        if light["kind"] == "world" and any(x["kind"] == "world" for x in lights):
            continue
        lights.append(light)
    has_volume = any("volume" in o["mat"] for o in objects)
    w, h = room["size"] / 2, room["height"]
    lens = rng.uniform(22, 32)
    camera = ({"loc": [0.3, -w + 0.3, h * 0.55], "target": [0.0, 0.3, 0.4], "lens": lens} if closed else
              {"loc": [0.9, -3.4, 1.9], "target": [-0.1, 0.3, 0.4], "lens": lens + 4})
    return {"family": "glass", "seed": seed, "room": room, "objects": objects, "lights": lights,
            "cam_lens": lens, "camera": camera,
            "light_paths": {**GLASS_LIGHT_PATHS, "volume_bounces": 8 if has_volume else 0}}


FAMILIES = {"rooms": random_spec, "glass": random_glass_spec}


def describe(spec):
    """One line: the room, each object's shape and material, the lights."""
    def name(m):
        k = m["kind"]
        if k in ("mix", "add"):
            return f"{k}({name(m['a'])},{name(m['b'])})"
        extra = [f for f in ("coat", "sheen", "specular_level", "subsurface") if f in m]
        if k == "principled" and m.get("metallic"):
            extra.append(f"met{m['metallic']}")
        if k == "principled" and m.get("transmission"):
            extra.append(f"trans,r{m['roughness']:g},ior{m['ior']:g}")
        if k in ("glass", "refraction"):
            extra.append(f"{m['distribution']},r{m['roughness']:g},ior{m['ior']:g}")
        if "texture" in m:
            extra.append(m["texture"]["type"])
        if "volume" in m:
            extra.append(f"vol:{m['volume']['kind']}")
        return k + ("[" + ",".join(extra) + "]" if extra else "")
    r = spec["room"]
    return (f"{'closed' if r['closed'] else 'open'} floor={name(r['floor'])} walls={name(r['walls'])}; "
            + " ".join(f"{o['type']}:{name(o['mat'])}" for o in spec["objects"]) + "; "
            + " ".join(x["kind"] + (f"/{x['shape']}" if x["kind"] == "area" else "") for x in spec["lights"]))


# ------------------------------------------------------------------------------ building (bpy)
def make_bsdf(nt, m):
    """The shader node of material dict ``m`` in node tree ``nt`` (its texture linked in)."""
    k = m["kind"]
    if k in ("mix", "add"):
        a, b = make_bsdf(nt, m["a"]), make_bsdf(nt, m["b"])
        if k == "mix":
            n = nt.nodes.new("ShaderNodeMixShader")
            n.inputs["Fac"].default_value = m["fac"]
            nt.links.new(a.outputs[0], n.inputs[1])
            nt.links.new(b.outputs[0], n.inputs[2])
        else:
            n = nt.nodes.new("ShaderNodeAddShader")
            nt.links.new(a.outputs[0], n.inputs[0])
            nt.links.new(b.outputs[0], n.inputs[1])
        return n
    if k in ("glass", "refraction"):
        n = nt.nodes.new("ShaderNodeBsdfGlass" if k == "glass" else "ShaderNodeBsdfRefraction")
        n.distribution = m["distribution"]
        n.inputs["Color"].default_value = (*m["color"], 1)
        n.inputs["Roughness"].default_value = m["roughness"]
        n.inputs["IOR"].default_value = m["ior"]
        return n
    if k == "principled":
        n = nt.nodes.new("ShaderNodeBsdfPrincipled")
        col = n.inputs["Base Color"]
        col.default_value = (*m["base"], 1)
        n.inputs["Roughness"].default_value = m["roughness"]
        n.inputs["Metallic"].default_value = m["metallic"]
        for key, inputs in PRINCIPLED_OPTIONS.items():
            if key in m:
                for name, field in inputs:
                    n.inputs[name].default_value = m[field] if isinstance(field, str) else field
    else:
        node_type = {"diffuse": "ShaderNodeBsdfDiffuse", "glossy": "ShaderNodeBsdfGlossy",
                     "translucent": "ShaderNodeBsdfTranslucent", "emission": "ShaderNodeEmission"}[k]
        n = nt.nodes.new(node_type)
        col = n.inputs["Color"]
        col.default_value = (*m["color"], 1)
        if k == "glossy":
            n.inputs["Roughness"].default_value = m["roughness"]
        if k == "emission":
            n.inputs["Strength"].default_value = m["strength"]
    tex = m.get("texture")
    if tex and tex["type"] == "checker":
        t = nt.nodes.new("ShaderNodeTexChecker")
        t.inputs["Color1"].default_value = (*tex["c1"], 1)
        t.inputs["Color2"].default_value = (*tex["c2"], 1)
        t.inputs["Scale"].default_value = tex["scale"]
        nt.links.new(nt.nodes.new("ShaderNodeTexCoord").outputs["Object"], t.inputs["Vector"])
        nt.links.new(t.outputs["Color"], col)
    elif tex:
        t = nt.nodes.new("ShaderNodeTexNoise")
        t.inputs["Scale"].default_value = tex["scale"]
        ramp = nt.nodes.new("ShaderNodeMix")
        ramp.data_type = "RGBA"
        ramp.inputs["A"].default_value = (*tex["c1"], 1)
        ramp.inputs["B"].default_value = (*tex["c2"], 1)
        nt.links.new(t.outputs["Fac"], ramp.inputs["Factor"])
        nt.links.new(ramp.outputs["Result"], col)
    return n


# A Principled spec's optional keys: the inputs each sets, from the spec's field of that name (or
# a constant).
PRINCIPLED_OPTIONS = {
    "transmission": (("Transmission Weight", "transmission"), ("IOR", "ior")),
    "coat": (("Coat Weight", "coat"), ("Coat Roughness", "coat_roughness")),
    "sheen": (("Sheen Weight", "sheen"), ("Sheen Roughness", "sheen_roughness")),
    "specular_level": (("Specular IOR Level", "specular_level"),),
    "subsurface": (("Subsurface Weight", "subsurface"), ("Subsurface Scale", 0.05)),
}


def material(name, m):
    """A new material of dict ``m`` (its output node kept, the default shader replaced)."""
    import bpy
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree
    for node in list(nt.nodes):
        if node.bl_idname != "ShaderNodeOutputMaterial":
            nt.nodes.remove(node)
    out = nt.nodes["Material Output"]
    if m["kind"] != "none":               # ("none": a volume-only material, no surface)
        nt.links.new(make_bsdf(nt, m).outputs[0], out.inputs["Surface"])
    v = m.get("volume")
    if v:
        node_type = {"absorption": "ShaderNodeVolumeAbsorption", "scatter": "ShaderNodeVolumeScatter",
                     "principled_volume": "ShaderNodeVolumePrincipled"}[v["kind"]]
        n = nt.nodes.new(node_type)
        n.inputs["Color"].default_value = (*v["color"], 1)
        n.inputs["Density"].default_value = v["density"]
        if "anisotropy" in v:
            n.inputs["Anisotropy"].default_value = v["anisotropy"]
        nt.links.new(n.outputs[0], out.inputs["Volume"])
    return mat


def build_room(room):
    """Floor, walls (back and left; closed rooms also right, front and a ceiling)."""
    import blender_scenes as bs
    s, h = room["size"], room["height"]
    w = s / 2
    bs.plane("Floor", size=s if room["closed"] else 30.0, material=material("Floor", room["floor"]))
    walls = material("Walls", room["walls"])
    keep = room.get("keep_walls", ["Back", "Left"])
    if "Back" in keep:
        bs.plane("Back", size=1.0, material=walls, location=(0, w, h / 2), rotation=(math.pi / 2, 0, 0),
                 scale=(s, h, 1))
    if "Left" in keep:
        bs.plane("Left", size=1.0, material=walls, location=(-w, 0, h / 2), rotation=(0, math.pi / 2, 0),
                 scale=(h, s, 1))
    if room["closed"]:
        bs.plane("Right", size=1.0, material=walls, location=(w, 0, h / 2), rotation=(0, math.pi / 2, 0),
                 scale=(h, s, 1))
        bs.plane("Front", size=1.0, material=walls, location=(0, -w, h / 2), rotation=(math.pi / 2, 0, 0),
                 scale=(s, h, 1))
        bs.plane("Ceiling", size=s, material=material("Ceiling", room["ceiling"]), location=(0, 0, h))


def build_object(i, o):
    """Object ``i`` (cube, sphere, cylinder or plane) standing on the floor or lifted above it."""
    import bmesh
    import blender_scenes as bs
    mat = material(f"M{i}", o["mat"])
    s, (x, y), lift = o["size"], o["loc"], o["lift"]
    bm = bmesh.new()
    if o["type"] == "cube":
        bmesh.ops.create_cube(bm, size=s)
        bs.mesh_object(f"O{i}", bm, mat, location=(x, y, s / 2 + 0.001 + lift), rotation=(0, 0, o["rot"]))
    elif o["type"] == "sphere":
        segments = o.get("segments", 32)        # (a spec may ask for a finer sphere)
        bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=segments // 2, radius=s / 2)
        bs.mesh_object(f"O{i}", bm, mat, location=(x, y, s / 2 + 0.001 + lift)).data.shade_smooth()
    elif o["type"] == "cylinder":
        bmesh.ops.create_cone(bm, cap_ends=True, segments=24, radius1=s / 2.5, radius2=s / 2.5, depth=s * 1.3)
        bs.mesh_object(f"O{i}", bm, mat, location=(x, y, s * 0.65 + 0.001 + lift), rotation=(0, 0, o["rot"]))
    elif o["type"] == "pane":           # a thin slab (a flattened cube): standing, lying or leaning
        bmesh.ops.create_cube(bm, size=1.0)
        t, tilt = o["thickness"], o["tilt"]
        # (its lowest edge on the floor)
        z = 0.4 * s * math.cos(tilt) + 0.5 * t * math.sin(tilt) + 0.001 + lift
        bs.mesh_object(f"O{i}", bm, mat, location=(x, y, z), rotation=(tilt, 0, o["rot"]),
                       scale=(s, t, 0.8 * s))
    else:
        bmesh.ops.create_grid(bm, x_segments=1, y_segments=1, size=s / 2)
        bs.mesh_object(f"O{i}", bm, mat, location=(x, y, s / 2 + 0.05 + lift),
                       rotation=(o["tilt"], 0, o["rot"]))


def build_light(j, light):
    """Light ``j``; returns whether it made the world."""
    import blender_scenes as bs
    from mathutils import Vector
    k = light["kind"]
    if k == "point":
        bs.light("POINT", location=light["loc"], energy=light["energy"], name=f"L{j}",
                 shadow_soft_size=light["radius"], use_soft_falloff=light["soft"], color=light["color"])
    elif k == "spot":
        bs.light("SPOT", location=light["loc"], target=light["target"], energy=light["energy"], name=f"L{j}",
                 shadow_soft_size=light["radius"], spot_size=light["spot_size"], spot_blend=light["blend"],
                 color=light["color"])
    elif k == "area":
        bs.light("AREA", location=light["loc"], target=light["target"], energy=light["energy"], name=f"L{j}",
                 shape=light["shape"], size=light["size"], size_y=light["size_y"], spread=light["spread"],
                 color=light["color"])
    elif k == "panel":
        emission = {"kind": "emission", "color": light["color"], "strength": light["strength"]}
        bs.plane(f"Panel{j}", size=light["size"], material=material(f"Panel{j}", emission),
                 location=light["loc"], rotation=(math.pi, 0, 0))
    elif k == "sun":
        el, az = math.radians(light["elev"]), math.radians(light["azim"])
        d = Vector((math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)))
        bs.light("SUN", location=tuple(5 * d), target=(0, 0, 0), energy=light["energy"], name=f"L{j}",
                 angle=light["angle"], color=light["color"])
    elif k == "world":
        bs.world(tuple(light["color"]), strength=light["strength"])
    else:
        nt = bs.world((0.0, 0.0, 0.0), strength=light["strength"]).node_tree
        sky = nt.nodes.new("ShaderNodeTexSky")
        sky.sun_elevation, sky.sun_rotation = math.radians(light["elev"]), math.radians(light["rot"])
        sky.sun_disc = light["sun_disc"]
        nt.links.new(sky.outputs["Color"], nt.nodes["Background"].inputs["Color"])
    return k in ("world", "sky")


def build(spec, resolution):
    """The scene of ``spec`` in a new empty file (blender_scenes.empty_scene); returns it."""
    import blender_scenes as bs
    scene = bs.empty_scene(resolution)
    room = spec["room"]
    build_room(room)
    for i, o in enumerate(spec["objects"]):
        build_object(i, o)
    made_world = [build_light(j, light) for j, light in enumerate(spec["lights"])]
    if not any(made_world):
        bs.world((0.0, 0.0, 0.0))
    w, h = room["size"] / 2, room["height"]
    if "camera" in spec:
        cam = spec["camera"]
        bs.camera(location=cam["loc"], target=cam["target"], lens=cam["lens"])
    elif room["closed"]:
        bs.camera(location=(0.3, -w + 0.3, h * 0.55), target=(0.0, 0.3, 0.5), lens=spec["cam_lens"])
    else:
        bs.camera(location=(1.5, -w - 4.0, 2.6), target=(-0.2, 0.3, 0.6), lens=spec["cam_lens"] + 8)
    return scene
