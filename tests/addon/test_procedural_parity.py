"""Procedural textures against Cycles, value by value.

Each case builds a node graph feeding a plane's diffuse colour.  Cycles evaluates it at every
pixel centre (``blender_scenes.cycles_texture_values``: the graph drives an emission seen
directly, one sample, a 0.01-pixel filter) and our exporter and core at the same points
(``our_texture_values``: the colour of the surface where a ray hits it).  The values must agree
to float32 precision except at the rare pixels that sit on a discontinuity (a checker edge, a
ramp stop), where float32 and float64 may fall on different sides.
"""
from __future__ import annotations

import math

import bpy
import numpy as np
import pytest

import blender_scenes as bs


def socket(sockets, identifier):
    return next(s for s in sockets if s.identifier == identifier)


def node(nt, kind, **settings):
    n = nt.nodes.new(kind)
    for key, value in settings.items():
        sock = next((s for s in n.inputs if s.name == key), None)
        if sock is not None:
            sock.default_value = value
        elif key[0].isupper():
            continue                    # an input this node type hides (Mapping's Location for vectors)
        else:
            setattr(n, key, value)
    return n


def coords(nt, output="Object", mapping=None, **mapping_inputs):
    tc = nt.nodes.new("ShaderNodeTexCoord")
    if mapping is None:
        return tc.outputs[output]
    m = node(nt, "ShaderNodeMapping", vector_type=mapping, **mapping_inputs)
    nt.links.new(tc.outputs[output], m.inputs["Vector"])
    return m.outputs["Vector"]


def checker_default(nt):
    """Generated coordinates (the unlinked Vector) of the plane: its texture space."""
    return node(nt, "ShaderNodeTexChecker", Scale=3.0, Color1=(0.9, 0.5, 0.1, 1.0),
                Color2=(0.1, 0.2, 0.7, 1.0)).outputs["Color"]


def ramp_over_gradient(interpolation):
    def build(nt):
        g = node(nt, "ShaderNodeTexGradient", gradient_type="RADIAL")
        nt.links.new(coords(nt, "Object", "TEXTURE", Location=(0.2, -0.1, 0.3), Rotation=(0.3, 0.2, 0.5),
                            Scale=(1.5, 0.7, 2.0)), g.inputs["Vector"])
        r = nt.nodes.new("ShaderNodeValToRGB")
        band = r.color_ramp
        band.interpolation = interpolation
        band.elements[0].color = (1.0, 0.0, 0.0, 1.0)
        band.elements.new(0.4).color = (0.0, 1.0, 0.2, 1.0)
        band.elements[-1].color = (0.1, 0.3, 1.0, 1.0)
        nt.links.new(g.outputs["Fac"], r.inputs["Fac"])
        return r.outputs["Color"]
    return build


def gradient(kind, mapping="POINT"):
    def build(nt):
        g = node(nt, "ShaderNodeTexGradient", gradient_type=kind)
        nt.links.new(coords(nt, "Object", mapping, Location=(0.1, 0.2, 0.0), Rotation=(0.0, 0.0, 0.7),
                            Scale=(0.8, 1.3, 1.0)), g.inputs["Vector"])
        return g.outputs["Color"]
    return build


def blend(mode, legacy=False):
    """A mix of a checker and a noise's colour (both coloured) with ``mode``."""
    def build(nt):
        c = node(nt, "ShaderNodeTexChecker", Scale=2.0, Color1=(0.9, 0.6, 0.2, 1.0),
                 Color2=(0.2, 0.1, 0.8, 1.0))
        g = node(nt, "ShaderNodeTexNoise", Scale=2.0)
        nt.links.new(coords(nt, "Generated"), g.inputs["Vector"])
        if legacy:
            m = node(nt, "ShaderNodeMixRGB", blend_type=mode, Fac=0.7)
            a, b, out = m.inputs["Color1"], m.inputs["Color2"], m.outputs["Color"]
        else:
            m = node(nt, "ShaderNodeMix", data_type="RGBA", blend_type=mode)
            socket(m.inputs, "Factor_Float").default_value = 0.7
            a, b = socket(m.inputs, "A_Color"), socket(m.inputs, "B_Color")
            out = socket(m.outputs, "Result_Color")
        nt.links.new(c.outputs["Color"], a)
        nt.links.new(g.outputs["Color"], b)
        return out
    return build


def arithmetic(nt):
    """Math, Map Range, Invert, Gamma, Bright/Contrast, Separate and Combine, float factors."""
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(coords(nt, "Object"), sep.inputs["Vector"])
    power = node(nt, "ShaderNodeMath", operation="POWER")
    nt.links.new(sep.outputs["X"], power.inputs[0])
    power.inputs[1].default_value = 2.0
    fract = node(nt, "ShaderNodeMath", operation="FRACT")
    scale = node(nt, "ShaderNodeMath", operation="MULTIPLY")
    nt.links.new(sep.outputs["Y"], scale.inputs[0])
    scale.inputs[1].default_value = 3.0
    nt.links.new(scale.outputs[0], fract.inputs[0])
    ranged = node(nt, "ShaderNodeMapRange", interpolation_type="SMOOTHSTEP")
    ranged.inputs["From Min"].default_value = -0.5
    ranged.inputs["From Max"].default_value = 0.8
    nt.links.new(sep.outputs["X"], ranged.inputs["Value"])
    comb = nt.nodes.new("ShaderNodeCombineColor")
    nt.links.new(power.outputs[0], comb.inputs["Red"])
    nt.links.new(fract.outputs[0], comb.inputs["Green"])
    nt.links.new(ranged.outputs["Result"], comb.inputs["Blue"])
    gamma = node(nt, "ShaderNodeGamma", Gamma=1.7)
    nt.links.new(comb.outputs["Color"], gamma.inputs["Color"])
    bc = node(nt, "ShaderNodeBrightContrast", Bright=0.1, Contrast=0.3)
    nt.links.new(gamma.outputs["Color"], bc.inputs["Color"])
    inv = nt.nodes.new("ShaderNodeInvert")
    nt.links.new(ranged.outputs["Result"], inv.inputs["Fac"])          # a float factor
    nt.links.new(bc.outputs["Color"], inv.inputs["Color"])
    return inv.outputs["Color"]


def image_on_mapped_uv_with(extension, interpolation):
    """:func:`image_on_mapped_uv` with the node's extension and interpolation (the UVs leave the
    image on every side)."""
    def build(nt):
        out = image_on_mapped_uv(nt)
        out.node.extension, out.node.interpolation = extension, interpolation
        return out
    return build


def image_on_mapped_uv(nt):
    """An image looked up at turned and scaled UVs (not the plain UV map)."""
    import bpy
    img = bpy.data.images.new("Gradient", 16, 8, float_buffer=True)
    img.colorspace_settings.name = "Non-Color"      # first: changing it regenerates the pixels
    h, w = 8, 16
    y, x = np.mgrid[0:h, 0:w]
    img.pixels.foreach_set(np.stack([x / w, y / h, (x * y) % 3 / 3.0, np.ones_like(x, float)], axis=-1)
                           .astype(np.float32).ravel())
    t = nt.nodes.new("ShaderNodeTexImage")
    t.image = img
    uv = coords(nt, "UV", "POINT", Rotation=(0.0, 0.0, 0.4), Scale=(1.7, 1.2, 1.0))
    nt.links.new(uv, t.inputs["Vector"])
    return t.outputs["Color"]


def value_to_colour(nt):
    """A checker's Fac (float) into a colour socket, and a colour (luminance) into a float."""
    c = node(nt, "ShaderNodeTexChecker", Scale=4.0, Color1=(0.2, 0.9, 0.4, 1.0))
    nt.links.new(coords(nt, "Object"), c.inputs["Vector"])
    lum = node(nt, "ShaderNodeMath", operation="MULTIPLY")
    nt.links.new(c.outputs["Color"], lum.inputs[0])                    # colour -> float
    lum.inputs[1].default_value = 0.5
    mix = node(nt, "ShaderNodeMix", data_type="RGBA", blend_type="ADD")
    nt.links.new(lum.outputs[0], socket(mix.inputs, "Factor_Float"))
    nt.links.new(c.outputs["Fac"], socket(mix.inputs, "A_Color"))      # float -> colour
    socket(mix.inputs, "B_Color").default_value = (0.1, 0.2, 0.3, 1.0)
    return socket(mix.outputs, "Result_Color")


def noise(output, **settings):
    """A Noise Texture (default Generated coordinates) through a Color Ramp, or its Color."""
    def build(nt):
        n = node(nt, "ShaderNodeTexNoise", **settings)
        if output == "Color":
            return n.outputs["Color"]
        r = nt.nodes.new("ShaderNodeValToRGB")
        r.color_ramp.elements[0].position = 0.3
        r.color_ramp.elements[1].position = 0.7
        r.color_ramp.elements[1].color = (1.0, 0.6, 0.1, 1.0)
        nt.links.new(n.outputs["Fac"], r.inputs["Fac"])
        return r.outputs["Color"]
    return build


def hue_saturation_value(nt):
    """Hue/Saturation/Value of a Noise Texture's Color, shifted, saturated and partly mixed back."""
    n = node(nt, "ShaderNodeTexNoise", Scale=3.0)
    h = node(nt, "ShaderNodeHueSaturation", Hue=0.3, Saturation=1.8, Value=1.2, Fac=0.8)
    nt.links.new(n.outputs["Color"], h.inputs["Color"])
    return h.outputs["Color"]


def brick_over_checker(nt):
    """Bricks (smooth mortar, offset and squashed rows) whose second colour is a checker."""
    b = node(nt, "ShaderNodeTexBrick", Scale=2.0, offset=0.3, squash=1.4, squash_frequency=3,
             Bias=0.2, **{"Mortar Smooth": 0.3, "Mortar Size": 0.05})
    c = node(nt, "ShaderNodeTexChecker", Scale=6.0, Color1=(0.9, 0.1, 0.1, 1.0))
    nt.links.new(c.outputs["Color"], b.inputs["Color2"])
    return b.outputs["Color"]


def white_noise_snapped(nt):
    """White noise hashes the float bits of its input: snapped to cells of 1/8 (floor of 8 x the
    object coordinates), away from where a pixel centre's rounding could pick another cell."""
    scale = node(nt, "ShaderNodeMapping", vector_type="POINT", Scale=(8.0, 8.0, 8.0))
    nt.links.new(coords(nt, "Object"), scale.inputs["Vector"])
    floor = [node(nt, "ShaderNodeMath", operation="FLOOR") for _ in range(3)]
    sep, comb = nt.nodes.new("ShaderNodeSeparateXYZ"), nt.nodes.new("ShaderNodeCombineXYZ")
    nt.links.new(scale.outputs["Vector"], sep.inputs["Vector"])
    for f, axis in zip(floor, "XYZ"):
        nt.links.new(sep.outputs[axis], f.inputs[0])
        nt.links.new(f.outputs[0], comb.inputs[axis])
    w = node(nt, "ShaderNodeTexWhiteNoise")
    nt.links.new(comb.outputs["Vector"], w.inputs["Vector"])
    return w.outputs["Color"]


def voronoi(output, **settings):
    """A Voronoi Texture on Object coordinates through a Mapping, one of its outputs."""
    def build(nt):
        v = node(nt, "ShaderNodeTexVoronoi", **settings)
        nt.links.new(coords(nt, "Object", "POINT", Location=(0.3, 0.1, 0.2)), v.inputs["Vector"])
        return v.outputs[output]
    return build


def blackbody_checker(temperature):
    """A checker of a Blackbody colour (a lamp's usual colour) and its half."""
    def build(nt):
        bb = node(nt, "ShaderNodeBlackbody", Temperature=temperature)
        c = node(nt, "ShaderNodeTexChecker", Scale=3.0)
        nt.links.new(bb.outputs["Color"], c.inputs["Color1"])
        half = node(nt, "ShaderNodeMix", data_type="RGBA", blend_type="MULTIPLY")
        socket(half.inputs, "Factor_Float").default_value = 1.0
        nt.links.new(bb.outputs["Color"], socket(half.inputs, "A_Color"))
        socket(half.inputs, "B_Color").default_value = (0.5, 0.5, 0.5, 1.0)
        nt.links.new(socket(half.outputs, "Result_Color"), c.inputs["Color2"])
        return c.outputs["Color"]
    return build


def blackbody_over_gradient(nt):
    """Temperatures from 500 to 13,000 K across the plane: every range of Cycles' fit."""
    g = node(nt, "ShaderNodeTexGradient")
    r = node(nt, "ShaderNodeMapRange", **{"To Min": 500.0, "To Max": 13000.0})
    nt.links.new(g.outputs["Fac"], r.inputs["Value"])
    bb = node(nt, "ShaderNodeBlackbody")
    nt.links.new(r.outputs["Result"], bb.inputs["Temperature"])
    half = node(nt, "ShaderNodeMix", data_type="RGBA", blend_type="MULTIPLY")     # within the clamp
    socket(half.inputs, "Factor_Float").default_value = 1.0
    nt.links.new(bb.outputs["Color"], socket(half.inputs, "A_Color"))
    socket(half.inputs, "B_Color").default_value = (0.2, 0.2, 0.2, 1.0)
    return socket(half.outputs, "Result_Color")


def math_chain(*ops):
    """A Combine Color of three Math nodes of the Object coordinates' x and y: (operation,
    first input, second input, third) per channel, where inputs are 'x', 'y' or numbers."""
    def build(nt):
        sep = nt.nodes.new("ShaderNodeSeparateXYZ")
        nt.links.new(coords(nt, "Object"), sep.inputs["Vector"])
        comb = nt.nodes.new("ShaderNodeCombineColor")
        for channel, (operation, *args) in zip(("Red", "Green", "Blue"), ops):
            m = node(nt, "ShaderNodeMath", operation=operation)
            for sock, arg in zip(m.inputs, args):
                if isinstance(arg, str):
                    nt.links.new(sep.outputs[arg.upper()], sock)
                else:
                    sock.default_value = arg
            nt.links.new(m.outputs[0], comb.inputs[channel])
        return comb.outputs["Color"]
    return build


def vector_math(*ops):
    """Vector Math nodes in a chain from the Object coordinates, each (operation, b, c, scale)
    with constant other inputs; a value operation's output goes on as grey."""
    def build(nt):
        out = coords(nt, "Object")
        for operation, b, c, scale in ops:
            m = node(nt, "ShaderNodeVectorMath", operation=operation)
            nt.links.new(out, m.inputs[0])
            m.inputs[1].default_value, m.inputs[2].default_value = b, c
            socket(m.inputs, "Scale").default_value = scale       # hidden unless the operation uses it
            out = m.outputs["Value"] if operation in ("DOT_PRODUCT", "LENGTH", "DISTANCE") else m.outputs[0]
        return out
    return build


def vector_rotate(rotation_type, invert=False, textured_center=False, **inputs):
    """Vector Rotate of the Object coordinates (then a checker of them, so that the turn shows)."""
    def build(nt):
        r = node(nt, "ShaderNodeVectorRotate", rotation_type=rotation_type, invert=invert, **inputs)
        nt.links.new(coords(nt, "Object"), r.inputs["Vector"])
        if textured_center:
            nt.links.new(node(nt, "ShaderNodeTexNoise").outputs["Color"], r.inputs["Center"])
        checker = node(nt, "ShaderNodeTexChecker", Scale=2.0)
        nt.links.new(r.outputs["Vector"], checker.inputs["Vector"])
        mix = node(nt, "ShaderNodeMix", data_type="RGBA", blend_type="MIX")
        socket(mix.inputs, "Factor_Float").default_value = 0.5
        nt.links.new(checker.outputs["Color"], socket(mix.inputs, "A_Color"))
        nt.links.new(r.outputs["Vector"], socket(mix.inputs, "B_Color"))
        return socket(mix.outputs, "Result_Color")
    return build


def map_range_vector(interpolation):
    """Map Range of the Object coordinates as vectors (per component), clamped."""
    def build(nt):
        m = node(nt, "ShaderNodeMapRange", data_type="FLOAT_VECTOR", interpolation_type=interpolation,
                 clamp=True)
        nt.links.new(coords(nt, "Object"), m.inputs["Vector"])
        for identifier, value in (("From_Min_FLOAT3", (-0.8, -0.5, 0.0)),
                                  ("From_Max_FLOAT3", (0.6, 0.9, 1.0)), ("To_Min_FLOAT3", (0.1, 0.9, 0.2)),
                                  ("To_Max_FLOAT3", (0.9, 0.0, 0.7)), ("Steps_FLOAT3", (3.0, 5.0, 2.0))):
            socket(m.inputs, identifier).default_value = value
        return socket(m.outputs, "Vector")
    return build


def color_modes(mode):
    """Separate Color in ``mode`` of the arithmetic graph's colour, its outputs shifted (Hue + 0.3 +
    Object x, Saturation times 1.2, the third minus 0.1) and joined by Combine Color in that mode:
    both conversions, with hues outside [0, 1)."""
    def build(nt):
        sep = node(nt, "ShaderNodeSeparateColor", mode=mode)
        nt.links.new(arithmetic(nt), sep.inputs["Color"])
        x = nt.nodes.new("ShaderNodeSeparateXYZ")
        nt.links.new(coords(nt, "Object"), x.inputs["Vector"])
        hue = node(nt, "ShaderNodeMath", operation="ADD")
        nt.links.new(sep.outputs[0], hue.inputs[0])
        nt.links.new(x.outputs["X"], hue.inputs[1])
        shift = node(nt, "ShaderNodeMath", operation="ADD")
        nt.links.new(hue.outputs[0], shift.inputs[0])
        shift.inputs[1].default_value = 0.3
        sat = node(nt, "ShaderNodeMath", operation="MULTIPLY")
        nt.links.new(sep.outputs[1], sat.inputs[0])
        sat.inputs[1].default_value = 1.2
        third = node(nt, "ShaderNodeMath", operation="SUBTRACT")
        nt.links.new(sep.outputs[2], third.inputs[0])
        third.inputs[1].default_value = 0.1
        comb = node(nt, "ShaderNodeCombineColor", mode=mode)
        for k, out in enumerate((shift, sat, third)):
            nt.links.new(out.outputs[0], comb.inputs[k])
        return comb.outputs["Color"]
    return build


def normal_dot(nt):
    """The Normal node's Dot of its direction with the Object coordinates (normalised), and its
    Normal output, mixed."""
    n = nt.nodes.new("ShaderNodeNormal")
    n.outputs["Normal"].default_value = (0.3, 0.5, 0.81)
    nt.links.new(coords(nt, "Object"), n.inputs["Normal"])
    mix = node(nt, "ShaderNodeMix", data_type="RGBA", blend_type="MIX")
    nt.links.new(n.outputs["Dot"], socket(mix.inputs, "Factor_Float"))
    nt.links.new(n.outputs["Normal"], socket(mix.inputs, "A_Color"))
    socket(mix.inputs, "B_Color").default_value = (0.9, 0.2, 0.1, 1.0)
    return socket(mix.outputs, "Result_Color")


def wavelength(nt):
    """The Wavelength node over 360 to 800 nm along the Object x (past both ends of its table)."""
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(coords(nt, "Object"), sep.inputs["Vector"])
    nm = node(nt, "ShaderNodeMapRange")
    nm.inputs["From Min"].default_value, nm.inputs["From Max"].default_value = -1.0, 1.0
    nm.inputs["To Min"].default_value, nm.inputs["To Max"].default_value = 360.0, 800.0
    nt.links.new(sep.outputs["X"], nm.inputs["Value"])
    w = nt.nodes.new("ShaderNodeWavelength")
    nt.links.new(nm.outputs["Result"], w.inputs["Wavelength"])
    return w.outputs["Color"]


def rgb_to_bw(nt):
    """RGB to BW of the arithmetic graph's colour (Rec. 709 luminance, as Cycles' colour-to-float)."""
    bw = nt.nodes.new("ShaderNodeRGBToBW")
    nt.links.new(arithmetic(nt), bw.inputs["Color"])
    return bw.outputs["Val"]


def clamped(kind, low, high):
    """A Clamp of the Object x (RANGE swaps a minimum above the maximum, MINMAX does not)."""
    def build(nt):
        sep = nt.nodes.new("ShaderNodeSeparateXYZ")
        nt.links.new(coords(nt, "Object"), sep.inputs["Vector"])
        c = node(nt, "ShaderNodeClamp", clamp_type=kind, Min=low, Max=high)
        nt.links.new(sep.outputs["X"], c.inputs["Value"])
        ramp = node(nt, "ShaderNodeMath", operation="MULTIPLY")
        nt.links.new(c.outputs[0], ramp.inputs[0])
        ramp.inputs[1].default_value = 1.3
        return ramp.outputs[0]
    return build


def curves(kind, extend):
    """An RGB Curves (its C and R curves bent), Vector Curves (X and Z bent) or Float Curve on
    coordinates that leave the curves' range (extrapolated or extended flat: HORIZONTAL)."""
    def build(nt):
        tc = coords(nt, "Object", "POINT", Scale=(1.5, 1.2, 1.0), Location=(0.2, 0.0, 0.4))
        n = nt.nodes.new({"rgb": "ShaderNodeRGBCurve", "vector": "ShaderNodeVectorCurve",
                          "float": "ShaderNodeFloatCurve"}[kind])
        mapping = n.mapping
        mapping.extend = extend
        bent = {"rgb": (3, 0), "vector": (0, 2), "float": (0,)}[kind]
        for i, k in enumerate(bent):
            curve = mapping.curves[k]
            curve.points.new(0.3 if i == 0 else 0.6, 0.6 if i == 0 else 0.2)
            curve.points[-1].location = (curve.points[-1].location[0], 0.8)
        mapping.update()
        if kind == "float":
            sep = nt.nodes.new("ShaderNodeSeparateXYZ")
            nt.links.new(tc, sep.inputs["Vector"])
            nt.links.new(sep.outputs["X"], n.inputs["Value"])
            n.inputs["Factor"].default_value = 0.9
            return n.outputs["Value"]
        nt.links.new(tc, n.inputs[1])
        n.inputs["Fac"].default_value = 0.8
        return n.outputs[0]
    return build


def gabor(gabor_type, textured=False, **inputs):
    """A Gabor Texture on its default (Generated) coordinates, its Value, Phase and Intensity as
    the colour's channels; with ``textured`` its Frequency a linear gradient from 1 to 4."""
    def build(nt):
        g = node(nt, "ShaderNodeTexGabor", gabor_type=gabor_type, **inputs)
        if textured:
            ramp = node(nt, "ShaderNodeMapRange", **{"To Min": 1.0, "To Max": 4.0})
            nt.links.new(node(nt, "ShaderNodeTexGradient").outputs["Fac"], ramp.inputs["Value"])
            nt.links.new(ramp.outputs["Result"], g.inputs["Frequency"])
        comb = nt.nodes.new("ShaderNodeCombineXYZ")
        for output, axis in (("Value", "X"), ("Phase", "Y"), ("Intensity", "Z")):
            nt.links.new(g.outputs[output], comb.inputs[axis])
        return comb.outputs[0]
    return build


def facing_of_a_bump(nt):
    """Layer Weight's Facing (Blend 0.5: 1 - cos) whose Normal is a Bump (distance 0.6, strength
    0.8) of sin(5 x) plus a noise, on Object coordinates: the view (straight down) meets the bent
    normal (stop 42; before, the Bump's normal was noted and the surface's own taken)."""
    x = node(nt, "ShaderNodeSeparateXYZ")
    nt.links.new(coords(nt, "Object"), x.inputs[0])
    times = node(nt, "ShaderNodeMath", operation="MULTIPLY")
    times.inputs[1].default_value = 5.0
    nt.links.new(x.outputs["X"], times.inputs[0])
    wave = node(nt, "ShaderNodeMath", operation="SINE")
    nt.links.new(times.outputs[0], wave.inputs[0])
    height = node(nt, "ShaderNodeMath", operation="MULTIPLY_ADD")
    height.inputs[1].default_value = 0.5
    nt.links.new(node(nt, "ShaderNodeTexNoise", Scale=2.0).outputs["Fac"], height.inputs[0])
    nt.links.new(wave.outputs[0], height.inputs[2])
    bump = node(nt, "ShaderNodeBump", Distance=0.6, Strength=0.8)
    nt.links.new(height.outputs[0], bump.inputs["Height"])
    weight = node(nt, "ShaderNodeLayerWeight", Blend=0.5)
    nt.links.new(bump.outputs["Normal"], weight.inputs["Normal"])
    return weight.outputs["Facing"]


CASES = {
    "checker_generated": checker_default,
    "blackbody_gradient": blackbody_over_gradient,
    "blackbody_2700": blackbody_checker(2700.0),
    "blackbody_9000": blackbody_checker(9000.0),
    "ramp_linear": ramp_over_gradient("LINEAR"),
    "ramp_constant": ramp_over_gradient("CONSTANT"),
    "ramp_ease": ramp_over_gradient("EASE"),
    **{f"gradient_{k.lower()}": gradient(k) for k in ("LINEAR", "QUADRATIC", "EASING", "DIAGONAL",
                                                       "SPHERICAL", "QUADRATIC_SPHERE", "RADIAL")},
    "mapping_vector": gradient("SPHERICAL", "VECTOR"),
    "mapping_normal": gradient("DIAGONAL", "NORMAL"),
    **{f"mix_{m.lower()}": blend(m) for m in ("MIX", "MULTIPLY", "SCREEN", "OVERLAY", "SUBTRACT", "DIVIDE",
                                              "DIFFERENCE", "EXCLUSION", "DARKEN", "LIGHTEN", "LINEAR_LIGHT",
                                              "SOFT_LIGHT", "ADD", "DODGE", "BURN", "HUE", "SATURATION",
                                              "VALUE", "COLOR")},
    "hue_saturation_value": hue_saturation_value,
    "mixrgb_multiply": blend("MULTIPLY", legacy=True),
    "arithmetic": arithmetic,
    "image_mapped_uv": image_on_mapped_uv,
    **{f"image_{e.lower()}_{i.lower()}": image_on_mapped_uv_with(e, i)
       for e, i in (("EXTEND", "Linear"), ("CLIP", "Linear"), ("MIRROR", "Linear"), ("REPEAT", "Closest"),
                    ("CLIP", "Closest"), ("MIRROR", "Closest"), ("REPEAT", "Cubic"), ("EXTEND", "Cubic"),
                    ("CLIP", "Cubic"), ("MIRROR", "Smart"))},
    "conversions": value_to_colour,
    "voronoi_f1_color": voronoi("Color", Scale=4.0),
    "voronoi_f2_distance": voronoi("Distance", Scale=3.0, feature="F2", distance="MANHATTAN"),
    "voronoi_edges_fractal": voronoi("Distance", Scale=3.0, feature="DISTANCE_TO_EDGE", Detail=2.0),
    "voronoi_smooth_position": voronoi("Position", Scale=2.0, feature="SMOOTH_F1", Smoothness=0.4),
    "wave_rings_distorted": lambda nt: node(nt, "ShaderNodeTexWave", wave_type="RINGS",
                                            rings_direction="SPHERICAL", wave_profile="SAW", Scale=3.0,
                                            Distortion=2.0).outputs["Color"],
    "brick_over_checker": brick_over_checker,
    "magic": lambda nt: node(nt, "ShaderNodeTexMagic", turbulence_depth=3, Scale=2.0).outputs["Color"],
    "white_noise_snapped": white_noise_snapped,
    "gabor_2d_generated": gabor("2D", Scale=6.0, Anisotropy=0.4),
    "gabor_3d_textured_frequency": gabor("3D", textured=True, Scale=4.0),
    "noise_fac_ramp": noise("Fac", Scale=4.0, Detail=3.5, Roughness=0.6),
    "noise_color_distorted": noise("Color", Scale=2.5, Distortion=0.8, noise_type="RIDGED_MULTIFRACTAL"),
    "math_inverse_trig": math_chain(("ARCTAN2", "x", "y"), ("ARCCOSINE", "y"), ("ARCSINE", "x")),
    "math_exp_log": math_chain(("LOGARITHM", "x", 3.0), ("EXPONENT", "y"), ("INVERSE_SQRT", "x")),
    "math_hyperbolic": math_chain(("TANH", "x"), ("SINH", "y"), ("COSH", "x")),
    "math_wrap_pingpong": math_chain(("WRAP", "x", 0.7, 0.1), ("PINGPONG", "y", 0.35), ("TANGENT", "x")),
    "math_smooth_compare": math_chain(("SMOOTH_MIN", "x", "y", 0.4), ("SMOOTH_MAX", "x", "y", 0.3),
                                      ("COMPARE", "x", "y", 0.23)),
    "math_degrees": math_chain(("DEGREES", "x"), ("RADIANS", "y"), ("TRUNC", "x")),
    "vector_math_geometry": vector_math(("CROSS_PRODUCT", (0.3, 0.8, 0.5), (0, 0, 0), 1.0),
                                        ("REFLECT", (0.2, 0.5, 1.0), (0, 0, 0), 1.0),
                                        ("PROJECT", (1.0, 0.4, 0.2), (0, 0, 0), 1.0),
                                        ("ABSOLUTE", (0, 0, 0), (0, 0, 0), 1.0)),
    "vector_math_refract": vector_math(("NORMALIZE", (0, 0, 0), (0, 0, 0), 1.0),
                                       ("REFRACT", (0.3, 0.2, 1.0), (0, 0, 0), 0.7),
                                       ("FACEFORWARD", (0.1, 0.9, 0.3), (0.5, -0.2, 0.4), 1.0),
                                       ("MULTIPLY_ADD", (0.8, 0.6, 0.4), (0.5, 0.5, 0.5), 1.0)),
    "vector_math_wrap_snap": vector_math(("SCALE", (0, 0, 0), (0, 0, 0), 2.5),
                                         ("WRAP", (1.0, 0.8, 0.6), (0.1, 0.2, 0.0), 1.0),
                                         ("SNAP", (0.3, 0.25, 0.2), (0, 0, 0), 1.0),
                                         ("POWER", (1.5, 2.0, 0.5), (0, 0, 0), 1.0)),
    "vector_math_values": vector_math(("DISTANCE", (0.4, 0.3, 0.0), (0, 0, 0), 1.0)),
    "vector_math_dot": vector_math(("DOT_PRODUCT", (0.6, -0.3, 0.2), (0, 0, 0), 1.0)),
    "rgb_to_bw": rgb_to_bw,
    "normal_dot": normal_dot,
    "wavelength": wavelength,
    "color_hsv": color_modes("HSV"),
    "color_hsl": color_modes("HSL"),
    "vector_rotate_axis": vector_rotate("AXIS_ANGLE", Axis=(0.3, 0.5, 0.8), Angle=0.7,
                                        Center=(0.2, -0.1, 0.0)),
    "vector_rotate_z_inverted": vector_rotate("Z_AXIS", invert=True, Angle=0.5),
    "vector_rotate_euler": vector_rotate("EULER_XYZ", Rotation=(0.3, -0.4, 0.9), Center=(0.1, 0.2, 0.3)),
    "vector_rotate_euler_inverted_noise_center": vector_rotate("EULER_XYZ", invert=True, textured_center=True,
                                                               Rotation=(0.3, -0.4, 0.9)),
    "map_range_vector_linear": map_range_vector("LINEAR"),
    "map_range_vector_stepped": map_range_vector("STEPPED"),
    "map_range_vector_smoothstep": map_range_vector("SMOOTHSTEP"),
    "clamp_minmax": clamped("MINMAX", 0.2, 0.7),
    "clamp_range": clamped("RANGE", 0.7, 0.2),
    "rgb_curves_extrapolated": curves("rgb", "EXTRAPOLATED"),
    "rgb_curves_horizontal": curves("rgb", "HORIZONTAL"),
    "vector_curves": curves("vector", "EXTRAPOLATED"),
    "float_curve": curves("float", "HORIZONTAL"),
}


def compare(ours, cycles, name):
    # Cycles lets a negative colour (a Subtract, a Linear Light) subtract light; the core clamps
    # colours to 0.
    err = np.abs(ours - np.maximum(cycles, 0.0)).max(axis=2)
    print(f"procedural {name}: max {err.max():.2e}, 99.5th percentile {np.percentile(err, 99.5):.2e}, "
          f"mean value {cycles.mean():.3f}")
    # Discontinuities (checker edges, constant ramp stops) may flip a pixel between float32 and
    # float64; everything else agrees to float32 precision.
    assert (err < 2e-3).mean() > 0.99
    assert np.percentile(err, 99.5) < 5e-3


@pytest.mark.parametrize("case", list(CASES))
def test_procedural_colour_matches_cycles(addon, tmp_path, case):
    mat, positions = bs.texture_plane(CASES[case])
    ours = bs.our_texture_values(positions)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    assert np.isfinite(ours).all()
    assert np.ptp(cycles, axis=(0, 1)).max() > 0.05      # the graph does vary over the plane
    compare(ours, cycles, case)


def test_a_bump_feeds_a_layer_weight_as_cycles(addon, tmp_path):
    """:func:`facing_of_a_bump` on the plane seen from above: every pixel within 0.01 of Cycles,
    whose Bump takes its differences over the pixel's footprint where ours takes them over
    1e-5 of the scene (the mean difference below 0.003; the surface's own normal gives 0, 0.32
    from Cycles' mean)."""
    mat, positions = bs.texture_plane(facing_of_a_bump)
    ours = bs.our_texture_values(positions)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    assert not [w for w in bs.export().warnings if "Bump" in w]
    err = np.abs(ours - cycles).max(axis=2)
    print(f"facing of a bump: max {err.max():.2e}, mean {err.mean():.2e}, Cycles' mean {cycles.mean():.3f}")
    assert cycles.mean() > 0.2 and err.max() < 0.01 and err.mean() < 0.003


@pytest.mark.parametrize("space", ["TANGENT", "OBJECT"])
def test_a_normal_map_of_a_texture_feeds_a_layer_weight_as_cycles(addon, tmp_path, space):
    """Layer Weight's Facing (Blend 0.5) whose Normal is a Normal Map (strength 0.7) of a magic
    texture's colour, in the UV map's tangent space or the object's (stop 42, ``procedural``'s
    ``normal_map`` op; before, the Normal Map's normal was noted and the surface's own taken, and
    a procedural colour on a BSDF's Normal Map was noted): value for value as Cycles."""
    def build(nt):
        magic = node(nt, "ShaderNodeTexMagic", turbulence_depth=2, Scale=3.0)
        normal_map = node(nt, "ShaderNodeNormalMap", space=space, Strength=0.7)
        nt.links.new(magic.outputs["Color"], normal_map.inputs["Color"])
        weight = node(nt, "ShaderNodeLayerWeight", Blend=0.5)
        nt.links.new(normal_map.outputs["Normal"], weight.inputs["Normal"])
        return weight.outputs["Facing"]

    mat, positions = bs.texture_plane(build)
    ours = bs.our_texture_values(positions)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    assert not [w for w in bs.export().warnings if "Normal Map" in w]
    assert np.ptp(cycles, axis=(0, 1)).max() > 0.05
    compare(ours, cycles, f"facing of a normal map, {space.lower()}")


def test_generated_and_object_coordinates_follow_the_object(addon, tmp_path):
    """A moved, turned, unevenly scaled and mirrored plane: Object coordinates are its own
    (Cycles' inverse object transform) and Generated its texture space, for each instance."""
    def build(nt):
        add = node(nt, "ShaderNodeMix", data_type="RGBA", blend_type="ADD")
        socket(add.inputs, "Factor_Float").default_value = 1.0
        a = node(nt, "ShaderNodeTexChecker", Scale=2.5)
        nt.links.new(coords(nt, "Object"), a.inputs["Vector"])
        g = node(nt, "ShaderNodeTexGradient", gradient_type="DIAGONAL")
        nt.links.new(coords(nt, "Generated"), g.inputs["Vector"])
        nt.links.new(a.outputs["Color"], socket(add.inputs, "A_Color"))
        nt.links.new(g.outputs["Color"], socket(add.inputs, "B_Color"))
        return socket(add.outputs, "Result_Color")

    mat, positions = bs.texture_plane(build, size=2.0, location=(0.1, -0.05, 0.0),
                                      rotation=(0.0, 0.0, math.radians(25)), scale=(-1.3, 0.9, 1.0))
    ours = bs.our_texture_values(positions)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    # The turned plane does not cover the image's corners.
    on = np.isfinite(ours).all(axis=2)
    assert 0.5 < on.mean() < 1.0 and (cycles[~on] == 0).all()
    compare(ours[on][None], cycles[on][None], "moved object")


@pytest.mark.parametrize("deform", ["shape_key", "displace_modifier"])
def test_generated_coordinates_are_the_undeformed_meshs(addon, tmp_path, deform):
    """Generated coordinates of a mesh that a shape key or a deform modifier moves are those of
    its undeformed mesh (Blender's orco, which Cycles reads), in the undeformed texture space;
    before stop 76 they followed the deformation (a shape-keyed box's emission 0.653 where
    Cycles' was 0.374)."""
    def build(nt):
        g = node(nt, "ShaderNodeTexGradient", gradient_type="DIAGONAL")
        nt.links.new(coords(nt, "Generated"), g.inputs["Vector"])
        return g.outputs["Color"]

    mat, positions = bs.texture_plane(build, size=2.0)
    ob = bpy.data.objects["Plane"]
    if deform == "shape_key":
        ob.shape_key_add(name="Basis")
        key = ob.shape_key_add(name="Shear")
        for v in key.data:
            v.co.x += 0.3 * v.co.y - 0.2
        key.value = 1.0
    else:
        modifier = ob.modifiers.new("Displace", "DISPLACE")
        modifier.direction, modifier.strength = "X", 0.4
    ours = bs.our_texture_values(positions)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    on = np.isfinite(ours).all(axis=2)
    assert 0.5 < on.mean() < 1.0 and (cycles[~on] == 0).all()
    compare(ours[on][None], cycles[on][None], f"Generated under a {deform}")


@pytest.mark.parametrize("factor", ["noise_mask", "constant"])
def test_a_mix_shader_of_two_diffuse_shaders_mixes_their_colours_point_by_point(addon, tmp_path, factor):
    """A Mix Shader whose Fac is a noise mask (or a constant) between a Diffuse BSDF coloured by a
    checker and a plain blue one: the core's diffuse colour at each point is (1 - F) A + F B.
    Cycles shows the same mix when both shaders are Emission shaders of the same colours."""

    def build(nt):
        checker = node(nt, "ShaderNodeTexChecker", Scale=3.0, Color1=(0.9, 0.6, 0.2, 1.0))
        return checker.outputs["Color"]

    mat, positions = bs.texture_plane(build)
    nt = mat.node_tree
    first = nt.nodes["Diffuse BSDF"]
    second = node(nt, "ShaderNodeBsdfDiffuse", Color=(0.1, 0.2, 0.9, 1.0))
    mix = nt.nodes.new("ShaderNodeMixShader")
    if factor == "noise_mask":
        mask = node(nt, "ShaderNodeTexNoise", Scale=2.0)
        ramp = nt.nodes.new("ShaderNodeValToRGB")
        ramp.color_ramp.elements[0].position, ramp.color_ramp.elements[1].position = 0.35, 0.65
        nt.links.new(mask.outputs["Fac"], ramp.inputs["Fac"])
        nt.links.new(ramp.outputs["Color"], mix.inputs["Fac"])
    else:
        mix.inputs["Fac"].default_value = 0.3
    nt.links.new(first.outputs[0], mix.inputs[1])
    nt.links.new(second.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    ours = bs.our_texture_values(positions)
    warnings = bs.export().warnings
    assert not any("Textured" in w for w in warnings), warnings       # exact: no note
    # Cycles: the two BSDFs become emissions of their colours.
    for bsdf in (first, second):
        emit = nt.nodes.new("ShaderNodeEmission")
        links = bsdf.inputs["Color"].links
        if links:
            nt.links.new(links[0].from_socket, emit.inputs["Color"])
        else:
            emit.inputs["Color"].default_value = bsdf.inputs["Color"].default_value
        nt.links.new(emit.outputs[0], bsdf.outputs[0].links[0].to_socket)
    cycles = bs.cycles_pixel_centres(tmp_path / "cycles.exr")
    assert np.ptp(cycles, axis=(0, 1)).max() > 0.05
    compare(ours, cycles, f"mix shader, {factor}")


def with_gradient(nt, source, blend="MULTIPLY"):
    """Colour output of ``source`` times (``blend``) a spherical gradient of the Object coordinates."""
    mix = node(nt, "ShaderNodeMix", data_type="RGBA", blend_type=blend)
    socket(mix.inputs, "Factor_Float").default_value = 1.0
    nt.links.new(source, socket(mix.inputs, "A_Color"))
    g = node(nt, "ShaderNodeTexGradient", gradient_type="SPHERICAL")
    nt.links.new(coords(nt, "Object"), g.inputs["Vector"])
    nt.links.new(g.outputs["Color"], socket(mix.inputs, "B_Color"))
    return socket(mix.outputs, "Result_Color")


@pytest.mark.parametrize("domain, kind", [("CORNER", "BYTE_COLOR"), ("POINT", "FLOAT_COLOR")])
def test_color_attribute_matches_cycles(addon, tmp_path, domain, kind):
    """The render colour attribute (byte colours are stored in sRGB, read linear), interpolated
    across the plane's triangles, times a gradient."""
    def build(nt):
        return with_gradient(nt, nt.nodes.new("ShaderNodeVertexColor").outputs["Color"])

    import bpy
    mat, positions = bs.texture_plane(build)
    me = bpy.data.objects["Plane"].data
    me.color_attributes.new("Other", "FLOAT_COLOR", "POINT")          # not the render one
    attr = me.color_attributes.new("Paint", kind, domain)
    me.color_attributes.render_color_index = list(me.color_attributes).index(attr)
    rgba = np.array([[0.9, 0.1, 0.1, 1], [0.1, 0.8, 0.2, 1], [0.2, 0.3, 0.9, 1], [0.7, 0.7, 0.1, 1]],
                    np.float32)
    attr.data.foreach_set("color", rgba[np.arange(len(attr.data)) % 4].ravel())
    ours = bs.our_texture_values(positions)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    assert np.ptp(cycles, axis=(0, 1)).max() > 0.05
    compare(ours, cycles, f"colour attribute {domain} {kind}")


@pytest.mark.parametrize("graph", ["attribute_float", "attribute_vector_fac", "named_color", "named_uv",
                                   "standard_heat", "standard_uv"])
def test_named_attributes_match_cycles(addon, tmp_path, graph):
    """Attributes read by name (stop 39; before, the Attribute node was unsupported and the Color
    Attribute and UV Map nodes used the render layers): an Attribute node's Color of a float point
    attribute written as in geometry nodes, its Fac of a vector corner attribute (the average), a
    Color Attribute node naming a colour layer that is not the render one, and a UV Map node naming
    the second UV map (each times a gradient, on the plane's two triangles).  Cycles' standard
    names come first: 'heat' reads its volume grid, 0 on a surface, though the mesh has a 'heat'
    attribute, and 'uv' the render UV map (each plus the gradient)."""
    import bpy

    def build(nt):
        if graph == "named_color":
            source = node(nt, "ShaderNodeVertexColor", layer_name="Dirt").outputs["Color"]
        elif graph == "named_uv":
            source = node(nt, "ShaderNodeUVMap", uv_map="Detail").outputs["UV"]
        elif graph.startswith("standard_"):
            source = node(nt, "ShaderNodeAttribute", attribute_name=graph[len("standard_"):]).outputs["Color"]
        else:
            scalar = graph == "attribute_float"
            attr = node(nt, "ShaderNodeAttribute", attribute_name="warmth" if scalar else "flow")
            source = attr.outputs["Color" if scalar else "Fac"]
        return with_gradient(nt, source, "ADD" if graph.startswith("standard_") else "MULTIPLY")

    mat, positions = bs.texture_plane(build)
    me = bpy.data.objects["Plane"].data
    for name in ("warmth", "heat"):
        me.attributes.new(name, "FLOAT", "POINT").data.foreach_set("value", [0.1, 0.9, 0.4, 0.7])
    flow = me.attributes.new("flow", "FLOAT_VECTOR", "CORNER")
    flow.data.foreach_set("vector", [0.9, 0.1, 0.2, 0.1, 0.8, 0.3, 0.2, 0.3, 0.9, 0.7, 0.7, 0.1])
    me.color_attributes.new("Render", "FLOAT_COLOR", "POINT")         # the render one: black
    dirt = me.color_attributes.new("Dirt", "BYTE_COLOR", "CORNER")
    dirt.data.foreach_set("color", [0.9, 0.1, 0.1, 1, 0.1, 0.8, 0.2, 1, 0.2, 0.3, 0.9, 1, 0.7, 0.7, 0.1, 1])
    detail = me.uv_layers.new(name="Detail")
    detail.data.foreach_set("uv", [0.2, 0.1, 0.9, 0.3, 0.6, 0.8, 0.1, 0.7])
    ours = bs.our_texture_values(positions)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    assert np.ptp(cycles, axis=(0, 1)).max() > 0.05
    compare(ours, cycles, f"named attribute, {graph}")


@pytest.mark.parametrize("graph", ["attribute_color", "attribute_float", "attribute_missing",
                                   "attribute_heat", "color_attribute_named", "color_attribute_render"])
def test_attribute_alpha_matches_cycles(addon, tmp_path, graph):
    """The Alpha of an Attribute or Color Attribute node (stop 42; before, not an output of ours:
    the node's Alpha was noted and read as a constant): a colour attribute's alpha interpolated
    across the plane's two triangles (a corner byte colour 'Paint', the render one a point float
    colour 'Render'), 1 for a float attribute; an attribute the mesh lacks and a volume grid's
    name (each plus the gradient)."""
    import bpy

    def build(nt):
        if graph.startswith("attribute_"):
            name = {"attribute_color": "Paint", "attribute_float": "warmth", "attribute_missing": "nothing",
                    "attribute_heat": "heat"}[graph]
            source = node(nt, "ShaderNodeAttribute", attribute_name=name).outputs["Alpha"]
        else:
            layer = "Paint" if graph == "color_attribute_named" else ""
            source = node(nt, "ShaderNodeVertexColor", layer_name=layer).outputs["Alpha"]
        added = graph in ("attribute_missing", "attribute_heat")
        return with_gradient(nt, source, "ADD" if added else "MULTIPLY")

    mat, positions = bs.texture_plane(build)
    me = bpy.data.objects["Plane"].data
    me.attributes.new("warmth", "FLOAT", "POINT").data.foreach_set("value", [0.1, 0.9, 0.4, 0.7])
    render = me.color_attributes.new("Render", "FLOAT_COLOR", "POINT")
    render.data.foreach_set("color", [0.5, 0.5, 0.5, 0.9, 0.5, 0.5, 0.5, 0.2,
                                      0.5, 0.5, 0.5, 0.6, 0.5, 0.5, 0.5, 0.0])
    me.color_attributes.render_color_index = 0
    paint = me.color_attributes.new("Paint", "BYTE_COLOR", "CORNER")
    paint.data.foreach_set("color", [0.9, 0.1, 0.1, 0.1, 0.1, 0.8, 0.2, 0.8,
                                     0.2, 0.3, 0.9, 0.5, 0.7, 0.7, 0.1, 1.0])
    ours = bs.our_texture_values(positions)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    assert np.ptp(cycles, axis=(0, 1)).max() > 0.05
    compare(ours, cycles, f"attribute alpha, {graph}")


def test_textures_inside_node_groups_match_cycles(addon, tmp_path):
    """A node group (a checker of the group's Scale and Tint inputs, behind a reroute) used twice
    with other inputs, mixed by a noise: groups, group inputs and reroutes are followed."""
    import bpy

    def tiles_group():
        group = bpy.data.node_groups.new("Tiles", "ShaderNodeTree")
        group.interface.new_socket("Scale", in_out="INPUT", socket_type="NodeSocketFloat")
        group.interface.new_socket("Tint", in_out="INPUT", socket_type="NodeSocketColor")
        group.interface.new_socket("Color", in_out="OUTPUT", socket_type="NodeSocketColor")
        g_in, g_out = group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")
        checker = group.nodes.new("ShaderNodeTexChecker")
        group.links.new(g_in.outputs["Scale"], checker.inputs["Scale"])
        group.links.new(g_in.outputs["Tint"], checker.inputs["Color1"])
        reroute = group.nodes.new("NodeReroute")
        group.links.new(checker.outputs["Color"], reroute.inputs[0])
        group.links.new(reroute.outputs[0], g_out.inputs["Color"])
        return group

    def build(nt):
        group = tiles_group()          # after texture_plane's factory reset
        a, b = nt.nodes.new("ShaderNodeGroup"), nt.nodes.new("ShaderNodeGroup")
        for g, scale, tint in ((a, 3.0, (0.9, 0.2, 0.1, 1.0)), (b, 7.0, (0.1, 0.6, 0.9, 1.0))):
            g.node_tree = group
            g.inputs["Scale"].default_value = scale
            g.inputs["Tint"].default_value = tint
        mix = node(nt, "ShaderNodeMix", data_type="RGBA")
        noise = node(nt, "ShaderNodeTexNoise", Scale=2.0)
        nt.links.new(noise.outputs["Fac"], socket(mix.inputs, "Factor_Float"))
        nt.links.new(a.outputs["Color"], socket(mix.inputs, "A_Color"))
        nt.links.new(b.outputs["Color"], socket(mix.inputs, "B_Color"))
        return socket(mix.outputs, "Result_Color")

    mat, positions = bs.texture_plane(build)
    ours = bs.our_texture_values(positions)
    assert not [w for w in bs.export().warnings if "Textured" in w]
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    assert np.ptp(cycles, axis=(0, 1)).max() > 0.05
    compare(ours, cycles, "node groups")


@pytest.mark.parametrize("shader", ["emission_mix", "principled", "diffuse_emission_mask"])
def test_textured_emission_matches_cycles(addon, tmp_path, shader):
    """The radiance a textured emitter emits at each point (``Materials.emission_program``), against
    Cycles seeing the plane directly under a black world (the pixel is the emission):

    * ``emission_mix``: a Mix Shader by a noise mask of an Emission coloured by a checker
      (strength 3) and a plain blue one (strength 0.5);
    * ``principled``: a black Principled BSDF whose Emission Color is a checker and whose
      Emission Strength is a gradient times 5;
    * ``diffuse_emission_mask``: a Diffuse BSDF and a checker Emission mixed by a noise mask."""

    def build(nt):
        return node(nt, "ShaderNodeTexChecker", Scale=3.0, Color1=(0.9, 0.6, 0.2, 1.0)).outputs["Color"]

    mat, positions = bs.texture_plane(build)
    nt = mat.node_tree
    out = nt.nodes["Material Output"].inputs["Surface"]
    checker = nt.nodes["Diffuse BSDF"].inputs["Color"].links[0].from_socket

    def mask():
        noise = node(nt, "ShaderNodeTexNoise", Scale=2.0)
        return noise.outputs["Fac"]

    def emission(color, strength):
        e = node(nt, "ShaderNodeEmission", Strength=strength)
        if isinstance(color, tuple):
            e.inputs["Color"].default_value = color
        else:
            nt.links.new(color, e.inputs["Color"])
        return e.outputs[0]

    if shader == "principled":
        bsdf = node(nt, "ShaderNodeBsdfPrincipled", **{"Base Color": (0.0, 0.0, 0.0, 1.0)})
        nt.links.new(checker, bsdf.inputs["Emission Color"])
        times = node(nt, "ShaderNodeMath", operation="MULTIPLY")
        times.inputs[1].default_value = 5.0
        nt.links.new(node(nt, "ShaderNodeTexGradient").outputs["Fac"], times.inputs[0])
        nt.links.new(times.outputs[0], bsdf.inputs["Emission Strength"])
        nt.links.new(bsdf.outputs[0], out)
    else:
        mix = nt.nodes.new("ShaderNodeMixShader")
        nt.links.new(mask(), mix.inputs["Fac"])
        first = (emission((0.1, 0.2, 0.9, 1.0), 0.5) if shader == "emission_mix"
                 else nt.nodes["Diffuse BSDF"].outputs[0])
        nt.links.new(first, mix.inputs[1])
        nt.links.new(emission(checker, 3.0), mix.inputs[2])
        nt.links.new(mix.outputs[0], out)
    ours = bs.our_texture_values(positions, emitted=True)
    warnings = bs.export().warnings
    assert not any("Textured" in w for w in warnings), warnings       # exact: no note
    cycles = bs.cycles_pixel_centres(tmp_path / "cycles.exr")
    assert np.ptp(cycles, axis=(0, 1)).max() > 0.5
    compare(ours, cycles, f"emission, {shader}")


@pytest.mark.parametrize("height", ["noise", "wave_moved"])
def test_procedural_bump_matches_cycles(addon, tmp_path, height):
    """A Bump node whose Height is a texture (``Materials.bump_program``): the bent normal at each
    point against Cycles' (the Bump's Normal output seen as an emission colour; Filter Width
    0.01 so that Cycles' finite differences over the pixel footprint approach the gradient ours
    takes along the triangle's edges).  A Noise on Generated coordinates (strength 0.8, distance
    0.3), or a Wave on Object coordinates of a turned plane (distance 0.05, inverted)."""

    def build(nt):
        return node(nt, "ShaderNodeRGB").outputs[0]              # the diffuse colour: unused here

    moved = height == "wave_moved"
    mat, positions = bs.texture_plane(build, rotation=(0.0, 0.0, math.radians(20)) if moved else (0, 0, 0))
    nt = mat.node_tree
    bump = node(nt, "ShaderNodeBump", Strength=0.8, Distance=0.05 if moved else 0.3, invert=moved)
    if "Filter Width" in bump.inputs:
        bump.inputs["Filter Width"].default_value = 0.01
    if moved:
        tex = node(nt, "ShaderNodeTexWave", Scale=2.0, Distortion=1.0)
        nt.links.new(coords(nt, "Object"), tex.inputs["Vector"])
        nt.links.new(tex.outputs["Fac"], bump.inputs["Height"])
    else:
        tex = node(nt, "ShaderNodeTexNoise", Scale=3.0, Detail=2.0)
        nt.links.new(tex.outputs["Fac"], bump.inputs["Height"])
    nt.links.new(bump.outputs["Normal"], nt.nodes["Diffuse BSDF"].inputs["Normal"])
    from amcmcppm.core.context import RenderContext
    ctx = RenderContext(bs.export().scene)
    p = positions.reshape(-1, 3)
    hits = ctx.accel.intersect(p + [0.0, 0.0, 1.0], np.tile([0.0, 0.0, -1.0], (len(p), 1)))
    on = hits.prim_ids >= 0
    ours = np.full((len(p), 3), np.nan)
    ours[on] = ctx.surface(hits.prim_ids[on], hits.b1[on], hits.b2[on]).ns
    ours = ours.reshape(positions.shape)
    emit = nt.nodes.new("ShaderNodeEmission")
    nt.links.new(bump.outputs["Normal"], emit.inputs["Color"])
    nt.links.new(emit.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    cycles = bs.cycles_pixel_centres(tmp_path / "cycles.exr")
    inside = np.isfinite(ours).all(axis=2)
    if moved:
        inside &= (np.abs(cycles).sum(axis=2) > 0)
    tilt = np.degrees(np.arccos(np.clip(cycles[inside][:, 2] / np.linalg.norm(cycles[inside], axis=1), -1, 1)))
    err = np.linalg.norm(ours[inside] - cycles[inside], axis=1)
    print(f"procedural bump {height}: tilt up to {tilt.max():.1f} deg (mean {tilt.mean():.1f}); "
          f"normal difference max {err.max():.2e}, 99th percentile {np.percentile(err, 99):.2e}")
    assert tilt.mean() > 3.0                                 # the bump does bend the normals
    assert np.percentile(err, 99) < 0.01 and err.max() < 0.02


def alpha_image(nt, is_float, output):
    """An Image Texture on the UV map of an image with alpha (discs of 0 in a wave of 0.1 to 0.9;
    a colour that varies smoothly, with no jump across the wrap) and the socket under test:
    ``Alpha``, ``Color`` (Alpha unused), or ``Both`` (Color times Alpha, so the Alpha is used)."""
    import bpy
    img = bpy.data.images.new("Leaf", 32, 16, alpha=True, float_buffer=is_float)
    h, w = 16, 32
    y, x = np.mgrid[0:h, 0:w]
    alpha = np.where((x % 8 - 3.5) ** 2 + (y % 8 - 3.5) ** 2 < 6.0, 0.0, 0.5 + 0.4 * np.sin(2 * np.pi * x / w))
    green = 0.5 + 0.3 * np.sin(2 * np.pi * y / h)
    if is_float:                        # Blender's float images hold premultiplied colour
        rgba = [0.8 * alpha, green * alpha, 0.3 * alpha, alpha]
    else:
        rgba = [np.full_like(alpha, 0.8), green, np.full_like(alpha, 0.3), alpha]
    img.pixels.foreach_set(np.stack(rgba, axis=-1).astype(np.float32).ravel())
    t = nt.nodes.new("ShaderNodeTexImage")
    t.image = img
    if output != "Both":
        return t.outputs[output]
    times = node(nt, "ShaderNodeMix", data_type="RGBA", blend_type="MULTIPLY")
    socket(times.inputs, "Factor_Float").default_value = 1.0
    nt.links.new(t.outputs["Color"], socket(times.inputs, "A_Color"))
    nt.links.new(t.outputs["Alpha"], socket(times.inputs, "B_Color"))
    return socket(times.outputs, "Result_Color")


@pytest.mark.parametrize("is_float", [False, True], ids=["byte", "float"])
@pytest.mark.parametrize("output", ["Alpha", "Color", "Both"])
def test_image_alpha_matches_cycles(addon, tmp_path, is_float, output):
    """An image's Alpha output (a foliage cut-out's usual source) is exact.  Its Color is what
    Cycles gives: straight when the Alpha is used, else times the alpha (byte images are stored
    straight, float ones premultiplied); exact for float images.  Cycles filters 8-bit sRGB
    images before making them linear, we after, so byte images differ where the colour jumps
    between texels: here at the discs' rims, 2 % of the pixels with the straight colour, 15 %
    (up to 0.12) premultiplied, whose colour jumps to 0 there."""
    mat, positions = bs.texture_plane(lambda nt: alpha_image(nt, is_float, output))
    ours = bs.our_texture_values(positions)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    err = np.abs(ours - cycles).max(axis=2)
    print(f"image alpha, {'float' if is_float else 'byte'} {output}: max {err.max():.2e}, "
          f"share within 0.01: {(err < 0.01).mean():.3f}")
    assert np.ptp(cycles, axis=(0, 1)).max() > 0.3
    if output == "Alpha" or is_float:
        assert err.max() < 1e-4
    elif output == "Both":
        assert (err < 0.01).mean() > 0.95 and err.max() < 0.05
    else:
        assert (err < 0.01).mean() > 0.8 and err.max() < 0.15


TRANSFORMS = {"transform_object_point_to_world": ("Object", "POINT", "OBJECT", "WORLD"),
              "transform_world_vector_to_object": ("Normal", "VECTOR", "WORLD", "OBJECT"),
              "transform_object_normal_to_camera": ("Object", "NORMAL", "OBJECT", "CAMERA"),
              "transform_world_point_to_camera": ("Position", "POINT", "WORLD", "CAMERA"),
              "transform_camera_point_to_object": ("Position", "POINT", "CAMERA", "OBJECT")}


@pytest.mark.parametrize("graph", ["normal", "box_sharp", "box_blended", "sphere_projection",
                                   "tube_projection", "geometry_normal", "geometry_true_normal",
                                   "geometry_position", *TRANSFORMS])
def test_normal_coordinates_and_box_projection_match_cycles(addon, tmp_path, graph):
    """A smooth, turned and unevenly scaled sphere seen from above: the Texture Coordinate's
    Normal (the object-space shading normal), an image box-projected on Object coordinates
    (blend 0 and 0.3), whose three projections the normal weighs (``procedural.box_weights``), an
    image sphere- and tube-projected on Generated coordinates (stop 41, ``procedural.map_to_sphere``,
    ``map_to_tube``; before, noted and flat), and the Geometry node's Normal, True Normal (the
    facet's) and Position, in world space, and Vector Transform between world, object and camera
    space (stop 39; before, unsupported nodes)."""
    import bmesh
    import bpy

    def build(nt):
        if graph == "normal":
            return nt.nodes.new("ShaderNodeTexCoord").outputs["Normal"]
        if graph in TRANSFORMS:
            source, kind, src, dst = TRANSFORMS[graph]
            t = node(nt, "ShaderNodeVectorTransform", vector_type=kind, convert_from=src, convert_to=dst)
            origin = (nt.nodes.new("ShaderNodeTexCoord").outputs[source] if source == "Object"
                      else nt.nodes.new("ShaderNodeNewGeometry").outputs[source])
            nt.links.new(origin, t.inputs["Vector"])
            scaled = node(nt, "ShaderNodeVectorMath", operation="MULTIPLY_ADD")
            nt.links.new(t.outputs["Vector"], scaled.inputs[0])
            scaled.inputs[1].default_value = (0.25, 0.25, 0.25)
            scaled.inputs[2].default_value = (0.5, 0.5, 0.5)
            return scaled.outputs["Vector"]
        if graph.startswith("geometry_"):
            output = {"geometry_normal": "Normal", "geometry_true_normal": "True Normal",
                      "geometry_position": "Position"}[graph]
            return nt.nodes.new("ShaderNodeNewGeometry").outputs[output]
        out = image_on_mapped_uv(nt)
        t = out.node
        if graph.endswith("_projection"):
            t.projection = graph.removesuffix("_projection").upper()
            nt.links.new(coords(nt, "Generated"), t.inputs["Vector"])
            return out
        t.projection = "BOX"
        t.projection_blend = 0.0 if graph == "box_sharp" else 0.3
        nt.links.new(coords(nt, "Object"), t.inputs["Vector"])
        return out

    mat, positions = bs.texture_plane(build, size=2.0)
    bpy.data.objects.remove(bpy.data.objects["Plane"])
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=64, v_segments=32, radius=0.9)
    sphere = bs.mesh_object("Ball", bm, mat, rotation=(0.4, 0.2, 0.3), scale=(1.0, 0.8, 0.9))
    sphere.data.shade_smooth()
    ours = bs.our_texture_values(positions)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    on = np.isfinite(ours).all(axis=2)
    assert 0.4 < on.mean() < 0.8
    # Our colours stop at 0 (the Normal's negative components), Cycles' emission does not.
    err = np.abs(ours[on] - np.maximum(cycles[on], 0.0)).max(axis=1)
    print(f"{graph}: max {err.max():.2e}, 99th percentile {np.percentile(err, 99):.2e}, "
          f"share within 2e-3 {(err < 2e-3).mean():.3f}")
    if graph in ("normal", "geometry_normal", "geometry_position", *TRANSFORMS):
        assert np.percentile(err, 99) < 2e-3
    else:
        # Discontinuities: where the dominant axis changes (blend 0) a pixel may fall either side.
        assert (err < 2e-3).mean() > 0.97


@pytest.mark.parametrize("output, camera_kind", [("Camera", "perspective"), ("Window", "perspective"),
                                                 ("Window", "orthographic")])
def test_camera_and_window_coordinates_match_cycles(addon, tmp_path, output, camera_kind):
    """Texture Coordinate's Camera (the hit in camera space, depth positive in front) and Window
    (where it lands in the frame) on a plane seen at a slant by a shifted camera whose sensor fits
    the height: ours at each pixel centre's camera ray against Cycles' (stop 39; before, each was
    an unsupported output, replaced by the socket's value)."""
    import bpy

    def build(nt):
        out = nt.nodes.new("ShaderNodeTexCoord").outputs[output]
        if output == "Window":
            return out
        scaled = node(nt, "ShaderNodeVectorMath", operation="SCALE", Scale=0.25)
        nt.links.new(out, scaled.inputs[0])
        return scaled.outputs["Vector"]

    mat, _ = bs.texture_plane(build, resolution=(40, 30), size=6.0, rotation=(0.3, 0.0, 0.2))
    bpy.data.objects.remove(bpy.data.objects["Camera"])
    cam = bs.camera(location=(1.0, -5.0, 4.0), target=(0.3, 0.2, 0.0), lens=35.0,
                    ortho_scale=4.5 if camera_kind == "orthographic" else None)
    cam.data.sensor_fit, cam.data.shift_x = "VERTICAL", 0.1
    ours = our_values_through_the_camera()
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    on = np.isfinite(ours).all(axis=2)
    assert 0.3 < on.mean() and np.ptp(cycles[on], axis=0).max() > 0.1
    err = np.abs(ours[on] - np.maximum(cycles[on], 0.0)).max(axis=1)
    print(f"texture coordinate {output}, {camera_kind}: max {err.max():.2e}, "
          f"99th percentile {np.percentile(err, 99):.2e}")
    assert np.percentile(err, 99) < 1e-4


def our_values_through_the_camera(offsets=((0.0, 0.0),), normals=False, sharp=True):
    """Our diffuse colour (with ``normals``: the shading normal n as the colour n / 2 + 1/2) of the
    current scene's surfaces where each pixel centre's camera ray meets them, seen along that ray
    (what Cycles' one-sample render of the colour shows), the mean over the rays moved by
    ``offsets`` (pixels; ``sharp`` as ``RenderContext.surface``'s): (H, W, 3), NaN where the ray
    misses."""
    from amcmcppm.core.bsdf import DIFFUSE
    from amcmcppm.core.camera import generate_camera_rays
    from amcmcppm.core.context import RenderContext
    from amcmcppm.core.procedural import CAMERA_PATH, LIGHT_PATH, Rays
    scene = bs.export().scene
    ctx = RenderContext(scene)
    w, h = scene.camera.resolution
    ids = np.arange(w * h)
    runs = []
    for dx, dy in offsets:
        centres = np.tile([0.5 + dx, 0.5 + dy, 0.0, 0.0], (len(ids), 1))
        origins, dirs, _, _ = generate_camera_rays(scene.camera, ids, centres)
        hits = ctx.accel.intersect(origins, dirs)
        hit = np.flatnonzero(hits.prim_ids >= 0)
        ours = np.full((w * h, 3), np.nan)
        path = np.tile(CAMERA_PATH, (len(hit), 1))                      # (camera rays: their length)
        path[:, LIGHT_PATH.index("Ray Length")] = hits.t[hit]
        surf = ctx.surface(hits.prim_ids[hit], hits.b1[hit], hits.b2[hit], rays=Rays(-dirs[hit], sharp, path))
        ours[hit] = 0.5 * surf.ns + 0.5 if normals else surf.colors[:, DIFFUSE]
        runs.append(ours.reshape(h, w, 3))
    return np.mean(runs, axis=0)


def half_unit(nt, vector):
    """A vector output as a colour: v / 2 + 1/2."""
    m = node(nt, "ShaderNodeVectorMath", operation="MULTIPLY_ADD")
    nt.links.new(vector, m.inputs[0])
    m.inputs[1].default_value, m.inputs[2].default_value = (0.5, 0.5, 0.5), (0.5, 0.5, 0.5)
    return m.outputs["Vector"]


def fresnel(ior_map=False, normal=None):
    def build(nt):
        f = node(nt, "ShaderNodeFresnel", IOR=1.45)
        if ior_map:
            ior = node(nt, "ShaderNodeMapRange")
            ior.inputs["To Min"].default_value, ior.inputs["To Max"].default_value = 1.1, 2.5
            nt.links.new(node(nt, "ShaderNodeTexNoise", Scale=3.0).outputs["Fac"], ior.inputs["Value"])
            nt.links.new(ior.outputs["Result"], f.inputs["IOR"])
        if normal is not None:
            nt.links.new(nt.nodes.new("ShaderNodeNewGeometry").outputs[normal], f.inputs["Normal"])
        return f.outputs["Fac"]
    return build


def layer_weight(blend):
    """Layer Weight's Fresnel, Facing and Geometry's Backfacing as red, green and blue."""
    def build(nt):
        lw = node(nt, "ShaderNodeLayerWeight", Blend=blend)
        comb = nt.nodes.new("ShaderNodeCombineColor")
        nt.links.new(lw.outputs["Fresnel"], comb.inputs["Red"])
        nt.links.new(lw.outputs["Facing"], comb.inputs["Green"])
        nt.links.new(nt.nodes.new("ShaderNodeNewGeometry").outputs["Backfacing"], comb.inputs["Blue"])
        return comb.outputs["Color"]
    return build


def view_vector(kind, output):
    return lambda nt: half_unit(nt, nt.nodes.new(kind).outputs[output])


def light_path(nt):
    """Light Path's Is Camera Ray, a tenth of its Ray Length and Is Glossy Ray (camera rays)."""
    lp = nt.nodes.new("ShaderNodeLightPath")
    comb = nt.nodes.new("ShaderNodeCombineXYZ")
    tenth = node(nt, "ShaderNodeMath", operation="MULTIPLY")
    tenth.inputs[1].default_value = 0.1
    nt.links.new(lp.outputs["Ray Length"], tenth.inputs[0])
    for output, axis in ((lp.outputs["Is Camera Ray"], "X"), (tenth.outputs[0], "Y"),
                         (lp.outputs["Is Glossy Ray"], "Z")):
        nt.links.new(output, comb.inputs[axis])
    return comb.outputs[0]


def camera_data(nt):
    """Camera Data's View Z Depth and View Distance (a tenth of each) and the View Vector's x."""
    cam = nt.nodes.new("ShaderNodeCameraData")
    comb = nt.nodes.new("ShaderNodeCombineXYZ")
    for output, axis in (("View Z Depth", "X"), ("View Distance", "Y")):
        tenth = node(nt, "ShaderNodeMath", operation="MULTIPLY")
        tenth.inputs[1].default_value = 0.1
        nt.links.new(cam.outputs[output], tenth.inputs[0])
        nt.links.new(tenth.outputs[0], comb.inputs[axis])
    x = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(cam.outputs["View Vector"], x.inputs[0])
    nt.links.new(x.outputs["X"], comb.inputs["Z"])
    return half_unit(nt, comb.outputs[0])


def wireframe(size, pixels=False):
    return lambda nt: node(nt, "ShaderNodeWireframe", Size=size, use_pixel_size=pixels).outputs["Fac"]


def object_of_an_empty(nt):
    """Texture Coordinate's Object in the space of an Empty (moved, turned and scaled), a quarter
    of it plus 1/2."""
    import bpy
    empty = bpy.data.objects.new("Projector", None)
    empty.location, empty.rotation_euler, empty.scale = (0.5, -0.3, 1.2), (0.3, 0.5, 0.8), (1.5, 0.7, 1.0)
    bpy.context.scene.collection.objects.link(empty)
    coords = nt.nodes.new("ShaderNodeTexCoord")
    coords.object = empty
    scaled = node(nt, "ShaderNodeVectorMath", operation="MULTIPLY_ADD")
    nt.links.new(coords.outputs["Object"], scaled.inputs[0])
    scaled.inputs[1].default_value, scaled.inputs[2].default_value = (0.25,) * 3, (0.5,) * 3
    return scaled.outputs["Vector"]


def tangent(direction, axis="Z"):
    """The Tangent node, radial about an object axis or along the UV map's tangents."""
    return lambda nt: half_unit(nt, node(nt, "ShaderNodeTangent", direction_type=direction,
                                         axis=axis).outputs["Tangent"])


VIEW_CASES = {
    "fresnel": fresnel(), "fresnel_ior_map": fresnel(ior_map=True),
    "fresnel_true_normal": fresnel(normal="True Normal"),
    "layer_weight": layer_weight(0.3), "layer_weight_steep": layer_weight(0.8),
    "incoming": view_vector("ShaderNodeNewGeometry", "Incoming"),
    "normal": view_vector("ShaderNodeNewGeometry", "Normal"),
    "true_normal": view_vector("ShaderNodeNewGeometry", "True Normal"),
    "object_normal": view_vector("ShaderNodeTexCoord", "Normal"),
    "camera_data": camera_data,
    "light_path": light_path,
    "view_vector": view_vector("ShaderNodeCameraData", "View Vector"),
    "parametric": view_vector("ShaderNodeNewGeometry", "Parametric"),
    "wireframe": wireframe(0.04),
    "wireframe_wide": wireframe(0.3),
    "wireframe_pixels": wireframe(3.0, pixels=True),
    "reflection": view_vector("ShaderNodeTexCoord", "Reflection"),
    "object_of_an_empty": object_of_an_empty,
}


def floor_and_bowl(build, resolution=(48, 36), uvs=False):
    """A 6 m floor and a smooth open bowl (its inside: back faces; with ``uvs`` a UV map) above it,
    both of the material whose colour ``build`` makes, seen at a slant by a perspective camera; the
    material."""
    import bmesh
    import bpy

    mat, _ = bs.texture_plane(build, resolution=resolution, size=6.0)
    bm = bmesh.new()
    if uvs:
        bm.loops.layers.uv.new("UVMap")                 # (calc_uvs fills an existing layer)
    bmesh.ops.create_uvsphere(bm, u_segments=32, v_segments=16, radius=1.0, calc_uvs=uvs)
    bmesh.ops.delete(bm, geom=[v for v in bm.verts if v.co.z > 0.3], context="VERTS")
    bowl = bs.mesh_object("Bowl", bm, mat, location=(0.3, 0.2, 1.0), rotation=(0.3, 0.0, 0.0))
    bowl.data.shade_smooth()
    bpy.data.objects.remove(bpy.data.objects["Camera"])
    bs.camera(location=(1.0, -5.0, 4.0), target=(0.2, 0.3, 0.5), lens=35.0)
    return mat


@pytest.mark.parametrize("case", list(VIEW_CASES))
def test_nodes_of_the_view_match_cycles(addon, tmp_path, case):
    """Fresnel, Layer Weight, Geometry's Incoming, Backfacing, Normal, True Normal and Parametric,
    Texture Coordinate's Normal, Camera Data and Wireframe on a floor and a smooth open bowl (its
    inside: back faces) seen at a slant by a perspective camera, ours along each pixel centre's
    camera ray against Cycles' (stop 40; before, Fresnel and Layer Weight took their means over
    view directions, Incoming, Backfacing, Parametric, Camera Data and Wireframe were unsupported,
    and the normals stayed on the front of a back face); Texture Coordinate's Reflection and Object
    of another object (an Empty) since stop 41 (before, unsupported outputs)."""
    mat = floor_and_bowl(VIEW_CASES[case])
    ours = our_values_through_the_camera()
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    on = np.isfinite(ours).all(axis=2)
    assert 0.5 < on.mean() and np.ptp(cycles[on], axis=0).max() > 0.3
    err = np.abs(ours[on] - np.maximum(cycles[on], 0.0)).max(axis=1)
    print(f"view {case}: max {err.max():.2e}, 99th percentile {np.percentile(err, 99):.2e}")
    assert np.percentile(err, 99) < 1e-4


def test_wireframe_in_pixels_matches_cycles_orthographic(addon, tmp_path):
    """Wireframe with Pixel Size (stop 42; before, noted and left out) under an orthographic
    camera, whose pixel is as wide everywhere: 4.5 pixels of the plane's diagonal and edges (a
    width that puts no pixel centre on a line's border: at 3 the centres 1.5 pixels from the
    plane's edges fall either way, in Cycles as in ours)."""
    mat, positions = bs.texture_plane(wireframe(4.5, pixels=True), resolution=(40, 40))
    ours = bs.our_texture_values(positions)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    lines = cycles[..., 0] > 0.5
    assert 0.05 < lines.mean() < 0.5
    compare(ours, cycles, "wireframe in pixels, orthographic")


TANGENT_CASES = {"geometry": view_vector("ShaderNodeNewGeometry", "Tangent"),
                 "radial_x": tangent("RADIAL", "X"), "radial_y": tangent("RADIAL", "Y"),
                 "uv_map": tangent("UV_MAP")}


@pytest.mark.parametrize("case", list(TANGENT_CASES))
def test_tangents_match_cycles(addon, tmp_path, case):
    """Geometry's Tangent (radial about the object's Z axis) and the Tangent node (radial about X
    or Y, or the UV map's) on the floor and the turned bowl, with UVs (stop 41; before, the Tangent
    node and Geometry's Tangent were unsupported, their socket's value).  Where the tangent lies
    along the normal (the radial X and Y ones on the flat floor) ours is 0 (a colour of 0.5) and
    Cycles' what its float32 rounding leaves (a unit vector of the error's direction, or NaN from
    normalize, which its film drops): those pixels are left out of the comparison."""
    mat = floor_and_bowl(TANGENT_CASES[case], uvs=True)
    ours = our_values_through_the_camera()
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    on = np.isfinite(ours).all(axis=2)
    degenerate = on & (np.abs(ours - 0.5).max(axis=2) < 1e-6)
    on &= ~degenerate
    assert on.mean() > 0.05 and np.ptp(cycles[on], axis=0).max() > 0.3          # (the bowl at least)
    err = np.abs(ours[on] - cycles[on]).max(axis=1)
    print(f"tangent {case}: {on.sum()} pixels ({degenerate.sum()} degenerate left out), max {err.max():.2e}, "
          f"99th percentile {np.percentile(err, 99):.2e}")
    assert np.percentile(err, 99) < 1e-4


def assert_matches_inside_silhouettes(name, ours, cycles):
    """Our values along the pixel centres' camera rays (NaN where they miss) within 1e-4 of Cycles'
    in 99 % of the pixels whose neighbours are all on the surface too (away from the silhouettes,
    where the two renderers' shapes differ), which must be a tenth of the image and span at least
    0.1 in each channel."""
    on = np.isfinite(ours).all(axis=2)
    inner = on.copy()
    for axis in (0, 1):
        for shift in (-1, 1):
            inner &= np.roll(on, shift, axis=axis)
    assert inner.mean() > 0.1 and np.ptp(cycles[inner], axis=0).min() > 0.1
    err = np.abs(ours[inner] - cycles[inner]).max(axis=1)
    print(f"{name}: {inner.sum()} pixels, max {err.max():.2e}, 99th percentile {np.percentile(err, 99):.2e}")
    assert np.percentile(err, 99) < 1e-4


def test_point_info_matches_cycles(addon, tmp_path):
    """Point Info on a point cloud (stop 41; before, point clouds were left out and the node
    unsupported): a 4 x 4 grid of spheres of random radii seen from above, coloured (Random,
    4 Radius, Position x / 2 + 1/2), each sphere its point's values; ours along each pixel
    centre's camera ray (inside our icospheres, so inside Cycles' spheres) against Cycles'."""
    import bpy

    def build(nt):
        info = nt.nodes.new("ShaderNodePointInfo")
        comb = nt.nodes.new("ShaderNodeCombineXYZ")
        radius = node(nt, "ShaderNodeMath", operation="MULTIPLY")
        radius.inputs[1].default_value = 4.0
        nt.links.new(info.outputs["Radius"], radius.inputs[0])
        x = nt.nodes.new("ShaderNodeSeparateXYZ")
        nt.links.new(info.outputs["Position"], x.inputs[0])
        half = node(nt, "ShaderNodeMath", operation="MULTIPLY_ADD")
        half.inputs[1].default_value, half.inputs[2].default_value = 0.5, 0.5
        nt.links.new(x.outputs["X"], half.inputs[0])
        for output, axis in ((info.outputs["Random"], "X"), (radius.outputs[0], "Y"), (half.outputs[0], "Z")):
            nt.links.new(output, comb.inputs[axis])
        return comb.outputs[0]

    mat, _ = bs.texture_plane(build, resolution=(64, 64))
    bpy.data.objects.remove(bpy.data.objects["Plane"])
    grid = [(x, y, 0.0) for x in (-0.66, -0.22, 0.22, 0.66) for y in (-0.66, -0.22, 0.22, 0.66)]
    bs.point_cloud("Beads", grid, material=mat, random_radius=(0.1, 0.2))
    ours = our_values_through_the_camera()
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    assert_matches_inside_silhouettes("point info", ours, cycles)


@pytest.mark.parametrize("case", ["ao", "ao_color_inside", "ao_only_local"])
def test_ambient_occlusion_matches_cycles(addon, tmp_path, case):
    """Ambient Occlusion (stop 40; before, unsupported) on the floor and the open bowl: the AO
    output (reach 1.5 m), the Color output of a checker inside, and AO of the hit's own object
    only.  Cycles draws 16 rays at each evaluation: ours is the mean of 64 evaluations at each
    pixel centre (rays a hair apart, so new numbers), Cycles' that of 256 samples: 0.0004 apart on
    average, 0.025 at the 99th percentile of pixels (noise)."""
    def build(nt):
        ao = node(nt, "ShaderNodeAmbientOcclusion", Distance=1.5, inside=case == "ao_color_inside",
                  only_local=case == "ao_only_local")
        if case == "ao_color_inside":
            nt.links.new(checker_default(nt), ao.inputs["Color"])
            return ao.outputs["Color"]
        return ao.outputs["AO"]

    mat = floor_and_bowl(build)
    offsets = np.random.default_rng(4).uniform(-0.004, 0.004, (64, 2))
    ours = our_values_through_the_camera(offsets)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr", samples=256)
    on = np.isfinite(ours).all(axis=2)
    assert 0.5 < on.mean() and np.ptp(cycles[on], axis=0).max() > 0.3
    diff = ours[on] - cycles[on]
    err = np.abs(diff).max(axis=1)
    print(f"{case}: mean difference {diff.mean():.4f}, 99th percentile {np.percentile(err, 99):.3f}, "
          f"mean value {cycles[on].mean():.3f}")
    assert abs(diff.mean()) < 0.002 and np.percentile(err, 99) < 0.04


@pytest.mark.parametrize("samples", [4, 16])
def test_bevel_matches_cycles(addon, tmp_path, samples):
    """Bevel (stop 40; before, unsupported: the surface's own normal) of radius 0.15 on a turned
    cube's sharp edges and the smooth open bowl, its normal both as a colour and as the Diffuse
    BSDF's Normal (our shading normal), the mean of 64 evaluations at each pixel centre against
    Cycles' mean of 256 samples (Cycles draws ``samples`` rays at each), everywhere and on the
    pixels where the bevel shows.  (With the axes' pick chances wrong, the wall of an edge at half
    its weight, everywhere passed; the bevelled pixels did not.  The cube rests on the floor: its
    bottom face lies in the floor's plane, which Cycles' local intersection sees; rays through the
    whole scene, passing on past the floor, did not: 0.009 off on the bevelled pixels, now 0.0006
    with 16 rays.  Our rays' numbers are stratified as Cycles': with 4 rays, independent numbers
    left a 0.016 bias and twice the noise.)"""
    def build(nt):
        bevel = node(nt, "ShaderNodeBevel", Radius=0.15, samples=samples)
        nt.links.new(bevel.outputs["Normal"], nt.nodes["Diffuse BSDF"].inputs["Normal"])
        return half_unit(nt, bevel.outputs["Normal"])

    mat = floor_and_bowl(build, resolution=(96, 72))
    bs.cube("Cube", size=1.2, material=mat, location=(-1.2, 0.8, 0.6), rotation=(0.0, 0.0, 0.5))
    offsets = np.random.default_rng(5).uniform(-0.004, 0.004, (64, 2))
    colour = our_values_through_the_camera(offsets)
    shading = our_values_through_the_camera(offsets, normals=True)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr", samples=256)
    plain = our_values_through_the_camera(normals=True, sharp=False)       # (no bevel)
    on = np.isfinite(colour).all(axis=2)
    assert 0.5 < on.mean() and np.ptp(cycles[on], axis=0).max() > 0.3
    # Where the bevel shows: Cycles' normal off the surface's own by more than 0.05.
    bevelled = on & (np.abs(cycles - plain).max(axis=2) > 0.05)
    assert bevelled.sum() > 30
    for name, ours in (("colour", colour), ("shading normal", shading)):
        diff = ours[on] - cycles[on]
        err = np.abs(diff).max(axis=1)
        # On the bevelled pixels: the mean difference (a bias) and the mean largest one (with noise).
        bias = np.abs((ours[bevelled] - cycles[bevelled]).mean(axis=0)).max()
        edge = np.abs(ours[bevelled] - cycles[bevelled]).max(axis=1).mean()
        print(f"bevel {samples} samples, {name}: mean difference {np.abs(diff.mean(axis=0)).max():.4f}, "
              f"99th percentile {np.percentile(err, 99):.3f}; on the {bevelled.sum()} bevelled pixels "
              f"{bias:.4f}, {edge:.3f} (without the bevel "
              f"{np.abs((plain[bevelled] - cycles[bevelled]).mean(axis=0)).max():.4f}, "
              f"{np.abs(plain[bevelled] - cycles[bevelled]).max(axis=1).mean():.3f})")
        assert np.abs(diff.mean(axis=0)).max() < 0.002 and np.percentile(err, 99) < 0.03
        assert bias < 0.006 and edge < 0.03


def test_light_path_through_a_mirror_matches_cycles(addon, tmp_path):
    """An emitting panel seen directly and in a mirror floor (a Glossy BSDF of roughness 0), its
    colour the Light Path's Is Camera Ray, Is Glossy Ray and Is Reflection Ray and its strength 1 +
    Ray Depth: red directly, cyan twice as bright in the mirror, as Cycles flags its rays (stop 40;
    before, Light Path outside a Mix with a clear Transparent was an unsupported node).  Each
    half of the frame against Cycles' render, channel by channel."""
    import bpy

    scene = bs.empty_scene((40, 30))
    panel = bs.emission("Panel")
    nt = panel.node_tree
    lp = nt.nodes.new("ShaderNodeLightPath")
    comb = nt.nodes.new("ShaderNodeCombineColor")
    for output, channel in (("Is Camera Ray", "Red"), ("Is Glossy Ray", "Green"),
                            ("Is Reflection Ray", "Blue")):
        nt.links.new(lp.outputs[output], comb.inputs[channel])
    strength = node(nt, "ShaderNodeMath", operation="ADD")
    nt.links.new(lp.outputs["Ray Depth"], strength.inputs[0])
    strength.inputs[1].default_value = 1.0
    nt.links.new(comb.outputs[0], nt.nodes["Emission"].inputs["Color"])
    nt.links.new(strength.outputs[0], nt.nodes["Emission"].inputs["Strength"])
    bs.plane("Panel", size=3.0, material=panel, location=(0.0, 2.0, 1.6), rotation=(math.pi / 2, 0.0, 0.0))
    bs.plane("Mirror", size=8.0, material=bs._material("Mirror", "ShaderNodeBsdfGlossy", Roughness=0.0))
    bs.camera(location=(0.0, -4.0, 1.5), target=(0.0, 1.0, 0.6), lens=30.0)
    scene.amcmcppm.passes = 8
    ours = bs.render_exr(tmp_path / "ours.exr")[..., :3]
    scene.render.engine = "CYCLES"
    scene.cycles.device, scene.cycles.samples, scene.cycles.use_denoising = "CPU", 64, False
    cycles = bs.render_exr(tmp_path / "cycles.exr")[..., :3]
    assert np.isfinite(ours).all()
    for half, rows in (("direct", slice(0, 15)), ("mirror", slice(15, 30))):
        c, o = cycles[rows].reshape(-1, 3).mean(axis=0), ours[rows].reshape(-1, 3).mean(axis=0)
        print(f"light path {half}: cycles {np.round(c, 4)}, ours {np.round(o, 4)}")
        np.testing.assert_allclose(o, c, atol=0.01, rtol=0.02)
    assert cycles[:15, :, 0].max() > 0.5 and cycles[15:, :, 1].max() > 1.5        # (both halves show it)


def surface_errors(mat, positions, tmp_path, least_coverage):
    """(n,) largest channel difference of ours and Cycles' values of ``mat`` where our rays from
    above hit a surface at ``positions`` (:func:`bs.our_texture_values`), which must be at least
    ``least_coverage`` of them; Cycles' values must vary by 0.3."""
    ours = bs.our_texture_values(positions)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    on = np.isfinite(ours).all(axis=2)
    assert least_coverage < on.mean() and np.ptp(cycles[on], axis=0).max() > 0.3
    return np.abs(ours[on] - cycles[on]).max(axis=1)


def test_random_per_island_matches_cycles(addon, tmp_path):
    """Geometry's Random Per Island on one mesh of 24 separate quads (planks: their islands joined
    in Blender's edge order, two of them bridged by an edge) and the Attribute node's
    'random_per_island' (Cycles' standard name): each island's own number, as Cycles'."""
    import bmesh
    import bpy

    def build(nt):
        geometry = nt.nodes.new("ShaderNodeNewGeometry")
        attr = node(nt, "ShaderNodeAttribute", attribute_name="random_per_island")
        mix = node(nt, "ShaderNodeMix", data_type="RGBA", blend_type="MIX")
        nt.links.new(geometry.outputs["Random Per Island"], socket(mix.inputs, "Factor_Float"))
        socket(mix.inputs, "A_Color").default_value = (0.9, 0.1, 0.2, 1.0)
        nt.links.new(attr.outputs["Color"], socket(mix.inputs, "B_Color"))
        return socket(mix.outputs, "Result_Color")

    mat, positions = bs.texture_plane(build, size=2.0)
    bpy.data.objects.remove(bpy.data.objects["Plane"])
    bm = bmesh.new()
    rng = np.random.default_rng(3)
    quads = []
    for row in range(6):
        for col in range(4):
            x0, y0 = -1.0 + col * 0.5, -1.0 + row * 0.3333
            corners = [bm.verts.new((x0 + dx, y0 + dy, 0.0)) for dx, dy in ((0.02, 0.02), (0.48, 0.02),
                                                                              (0.48, 0.31), (0.02, 0.31))]
            quads.append(bm.faces.new(corners))
    bm.verts.ensure_lookup_table()
    bm.edges.new((quads[0].verts[1], quads[1].verts[0]))             # two planks joined by an edge
    order = rng.permutation(len(bm.verts))
    for i, v in enumerate(bm.verts):
        v.index = int(order[i])
    bm.verts.sort()
    bs.mesh_object("Planks", bm, mat)
    err = surface_errors(mat, positions, tmp_path, 0.6)
    print(f"random per island: max {err.max():.2e}, share within 1e-4 {(err < 1e-4).mean():.3f}")
    assert (err < 1e-4).mean() > 0.99


def test_pointiness_matches_cycles(addon, tmp_path):
    """Geometry's Pointiness on a lumpy sphere (vertices pushed in and out), stretched from
    [0.4, 0.6] to [0, 1]: each vertex's angle between its normal and its mean edge, blurred once
    over its neighbours, interpolated over the triangles as Cycles'."""
    import bmesh
    import bpy

    def build(nt):
        stretch = node(nt, "ShaderNodeMapRange")
        stretch.inputs["From Min"].default_value, stretch.inputs["From Max"].default_value = 0.4, 0.6
        nt.links.new(nt.nodes.new("ShaderNodeNewGeometry").outputs["Pointiness"], stretch.inputs["Value"])
        return stretch.outputs["Result"]

    mat, positions = bs.texture_plane(build, size=2.0)
    bpy.data.objects.remove(bpy.data.objects["Plane"])
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=32, v_segments=16, radius=0.8)
    rng = np.random.default_rng(5)
    for v in bm.verts:                      # (below z = 1, where our_texture_values' rays start)
        v.co *= 1.0 + 0.1 * np.clip(rng.standard_normal(), -2.0, 2.0)
    ob = bs.mesh_object("Lumpy", bm, mat)
    ob.data.shade_smooth()
    err = surface_errors(mat, positions, tmp_path, 0.4)
    print(f"pointiness: max {err.max():.2e}, 99th percentile {np.percentile(err, 99):.2e}")
    assert err.max() < 1e-3


def quarter_objects(mat, second):
    """The texture plane (``bs.texture_plane``, 2 m) made its top-left quarter, two more quarter
    planes of material ``mat`` (the top-right one named ``second``), and the fourth a collection
    instance of a plane kept out of the scene: ([three planes], the instanced plane, its empty)."""
    import bpy
    first = bpy.data.objects["Plane"]
    first.scale, first.location = (0.5, 0.5, 1.0), (-0.5, 0.5, 0.0)
    quarters = [first, bs.plane(second, size=1.0, material=mat, location=(0.5, 0.5, 0.0)),
                bs.plane("Q3", size=1.0, material=mat, location=(-0.5, -0.5, 0.0))]
    coll = bpy.data.collections.new("Tile")
    tile = bpy.data.objects.new("Tile plane", bs.plane("Tile source", size=1.0, material=mat).data)
    bpy.data.objects.remove(bpy.data.objects["Tile source"])
    coll.objects.link(tile)
    holder = bpy.data.objects.new("Tile holder", None)
    holder.instance_type, holder.instance_collection = "COLLECTION", coll
    holder.location = (0.5, -0.5, 0.0)
    bpy.context.scene.collection.objects.link(holder)
    return quarters, tile, holder


@pytest.mark.parametrize("kind, path", [("OBJECT", '["tint"]'), ("OBJECT", '["level"]'), ("OBJECT", "color"),
                                        ("OBJECT", '["wear"]'), ("INSTANCER", '["tint"]'),
                                        ("OBJECT", "tint"), ("INSTANCER", "wear"), ("OBJECT", "missing")])
def test_object_and_instancer_attributes_match_cycles(addon, tmp_path, kind, path):
    """The Attribute node of the Object and Instancer types (stop 39; before, unsupported): four
    quarter planes, one a collection instance, with custom properties (a colour array, a number,
    an integer on some), their RNA colour, and a property of their mesh data; the Instancer type
    reads the instancer's first (the collection instance's empty).  Cycles resolves the name as an
    RNA path on the object, then its data; 0 where none resolves."""
    import bpy

    def build(nt):
        attr = node(nt, "ShaderNodeAttribute", attribute_type=kind, attribute_name=path)
        return attr.outputs["Color"]

    mat, positions = bs.texture_plane(build, size=2.0)
    quarters, tile, holder = quarter_objects(mat, "Q2")
    for k, ob in enumerate(quarters + [tile]):
        ob.color = (0.2 * k, 0.9 - 0.2 * k, 0.5, 1.0)
        ob["tint"] = [0.9 - 0.2 * k, 0.1 + 0.2 * k, 0.3]
        if k != 2:
            ob["level"] = 0.25 * k if k != 1 else 1                       # (an integer on one)
        ob.data["wear"] = 0.1 + 0.2 * k
    holder["tint"] = [0.2, 0.4, 0.6]
    ours = bs.our_texture_values(positions)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    assert np.isfinite(ours).all()
    if path != "missing":
        assert np.ptp(cycles, axis=(0, 1)).max() > 0.1
    compare(ours, cycles, f"{kind.lower()} attribute {path}")


@pytest.mark.parametrize("name", ["tint", '["tint"]', "glow", "haze", "frame_current", "missing"])
def test_view_layer_attributes_match_cycles(addon, tmp_path, name):
    """The Attribute node of the View Layer type (stop 40; before, unsupported and noted): one
    value for the render, the view layer's custom property or RNA path of that name, else the
    scene's, else the world's, as Cycles looks it up ('tint' on the view layer and the scene, 'glow'
    on the scene, 'haze' on the world, the scene's frame_current, and a missing name: 0), on a
    plane whose colour adds a gradient (so that it varies)."""
    import bpy

    def build(nt):
        attr = node(nt, "ShaderNodeAttribute", attribute_type="VIEW_LAYER", attribute_name=name)
        return with_gradient(nt, attr.outputs["Color"], blend="ADD")

    mat, positions = bs.texture_plane(build, size=2.0)
    scene = bpy.context.scene
    bpy.context.view_layer["tint"] = [0.2, 0.7, 0.4]
    scene["tint"], scene["glow"] = [0.9, 0.1, 0.1], 0.6
    scene.frame_current = 3
    scene.world = bpy.data.worlds.new("World")
    scene.world.color = (0.0, 0.0, 0.0)
    scene.world["haze"] = 0.35
    export = bs.export()
    assert not [w for w in export.warnings if "Attribute" in w], export.warnings
    ours = bs.our_texture_values(positions)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    compare(ours, cycles, f"view layer attribute {name}")


def test_particle_info_matches_cycles(addon, tmp_path):
    """Particle Info (stop 42; before, unsupported: the socket's value) on tiles instanced by a
    particle system over the plane (a 3 x 3 grid) at frame 10: each tile its particle's Random,
    Index, Age, Lifetime, Size, Velocity and Location, as Cycles syncs them; the colour is (Random,
    Index / 8 + Age / 40, Lifetime / 100 + Size / 4 + Velocity z / 10) + Location / 10 (the
    emitter itself is not rendered)."""
    import bmesh
    import bpy

    def build(nt):
        info = nt.nodes.new("ShaderNodeParticleInfo")
        def scaled(output, factor):
            m = node(nt, "ShaderNodeMath", operation="MULTIPLY")
            nt.links.new(info.outputs[output], m.inputs[0])
            m.inputs[1].default_value = factor
            return m.outputs[0]
        def plus(a, b):
            m = node(nt, "ShaderNodeMath", operation="ADD")
            nt.links.new(a, m.inputs[0])
            nt.links.new(b, m.inputs[1])
            return m.outputs[0]
        velocity_z = nt.nodes.new("ShaderNodeSeparateXYZ")
        nt.links.new(info.outputs["Velocity"], velocity_z.inputs[0])
        vz = node(nt, "ShaderNodeMath", operation="MULTIPLY")
        nt.links.new(velocity_z.outputs["Z"], vz.inputs[0])
        vz.inputs[1].default_value = 0.1
        xyz = nt.nodes.new("ShaderNodeCombineXYZ")
        nt.links.new(info.outputs["Random"], xyz.inputs["X"])
        nt.links.new(plus(scaled("Index", 1 / 8), scaled("Age", 1 / 40)), xyz.inputs["Y"])
        lifetime_and_size = plus(scaled("Lifetime", 0.01), scaled("Size", 0.25))
        nt.links.new(plus(lifetime_and_size, vz.outputs[0]), xyz.inputs["Z"])
        where = node(nt, "ShaderNodeVectorMath", operation="MULTIPLY_ADD")
        nt.links.new(info.outputs["Location"], where.inputs[0])
        where.inputs[1].default_value = (0.1, 0.1, 0.1)
        nt.links.new(xyz.outputs[0], where.inputs[2])
        return where.outputs[0]

    mat, positions = bs.texture_plane(build, size=2.0)
    emitter = bpy.data.objects["Plane"]
    bm = bmesh.new()
    bmesh.ops.create_grid(bm, x_segments=1, y_segments=1, size=0.25)
    tile = bs.mesh_object("Tile", bm, mat, location=(50.0, 0.0, 0.0))          # (out of view)
    settings = emitter.modifiers.new("Particles", "PARTICLE_SYSTEM").particle_system.settings
    settings.count, settings.frame_start, settings.frame_end, settings.lifetime = 6, 1, 1, 50
    settings.render_type, settings.instance_object, settings.particle_size = "OBJECT", tile, 1.0
    settings.physics_type = "NO"
    settings.use_rotations, settings.rotation_mode = True, "NONE"           # (tiles lying flat)
    settings.distribution, settings.grid_resolution = "GRID", 3             # (apart: no overlaps)
    # (the emitter unseen: the exporter here reads the viewport's depsgraph, renders the render's)
    emitter.show_instancer_for_render = emitter.show_instancer_for_viewport = False
    bpy.context.scene.frame_set(10)
    ours = bs.our_texture_values(positions)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    seen = np.isfinite(ours).all(axis=2)
    assert 0.05 < seen.mean() < 0.9 and (cycles[~seen] == 0).all()
    assert np.ptp(cycles[seen][:, 0]) > 0.05                  # the particles' Random differ
    compare(ours[seen][None], cycles[seen][None], "particle info")


def test_object_info_matches_cycles(addon, tmp_path):
    """Object Info, per object as Cycles sets it: four quarter planes sharing one material, named
    in ASCII and not (Cycles hashes the name of an object that is not an instance: its Random),
    one of them a collection instance (Random from the instance), with their own colours, alphas
    and pass indices, the material its own pass index (Material Index).  The colour is
    (Random, Object Index / 10 + Material Index / 20, Alpha) + Color / 2 + (Location + 1) / 10.
    Cycles takes an instance's Color and Alpha from its instancer (the empty), its Object Index
    from the instanced object, and hashes a name's UTF-8 bytes as unsigned (all three were seen
    here first: signed bytes and the instanced object's colour failed)."""
    import bpy

    def build(nt):
        info = nt.nodes.new("ShaderNodeObjectInfo")
        index = node(nt, "ShaderNodeMath", operation="MULTIPLY_ADD")
        nt.links.new(info.outputs["Object Index"], index.inputs[0])
        index.inputs[1].default_value = 0.1
        material = node(nt, "ShaderNodeMath", operation="MULTIPLY")
        nt.links.new(info.outputs["Material Index"], material.inputs[0])
        material.inputs[1].default_value = 0.05
        nt.links.new(material.outputs[0], index.inputs[2])
        xyz = nt.nodes.new("ShaderNodeCombineXYZ")
        nt.links.new(info.outputs["Random"], xyz.inputs["X"])
        nt.links.new(index.outputs[0], xyz.inputs["Y"])
        nt.links.new(info.outputs["Alpha"], xyz.inputs["Z"])
        color = node(nt, "ShaderNodeVectorMath", operation="MULTIPLY_ADD")
        nt.links.new(info.outputs["Color"], color.inputs[0])
        color.inputs[1].default_value = (0.5, 0.5, 0.5)
        nt.links.new(xyz.outputs[0], color.inputs[2])
        where = node(nt, "ShaderNodeVectorMath", operation="MULTIPLY_ADD")
        nt.links.new(info.outputs["Location"], where.inputs[0])
        where.inputs[1].default_value = (0.1, 0.1, 0.1)
        where.inputs[2].default_value = (0.1, 0.1, 0.1)
        total = node(nt, "ShaderNodeVectorMath", operation="ADD")
        nt.links.new(color.outputs[0], total.inputs[0])
        nt.links.new(where.outputs[0], total.inputs[1])
        return total.outputs[0]

    mat, positions = bs.texture_plane(build, size=2.0)
    mat.pass_index = 3
    quarters, tile, holder = quarter_objects(mat, "Quarter ünï")
    colors = ((0.9, 0.2, 0.1, 0.3), (0.1, 0.7, 0.3, 0.6), (0.2, 0.3, 0.8, 0.9), (0.5, 0.5, 0.1, 0.4))
    for ob, color, index in zip(quarters + [tile], colors, (1, 2, 5, 7)):
        ob.color, ob.pass_index = color, index
    holder.color = (0.3, 0.6, 0.9, 0.8)          # an instance's colour and alpha: its instancer's
    ours = bs.our_texture_values(positions)
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    assert np.isfinite(ours).all()
    h, w = ours.shape[:2]
    quarters = [cycles[:h // 2, :w // 2], cycles[:h // 2, w // 2:], cycles[h // 2:, :w // 2],
                cycles[h // 2:, w // 2:]]
    red = [float(np.median(q[..., 0])) for q in quarters]
    print("object info: Cycles' quarters' red", np.round(red, 4))
    assert np.ptp(red) > 0.05                 # the objects' Random differ
    compare(ours, cycles, "object info")


def test_curves_info_matches_cycles(addon, tmp_path):
    """Curves Info on hair curves (stop 56; before, curves were left out and the node unsupported):
    five straight poly curves of unevenly spaced points and different lengths seen from above,
    coloured (Random, Intercept, Length / 4), each pixel its curve's values where it crosses the
    tube; ours along each pixel centre's camera ray against Cycles' (its Rounded Ribbons: the same
    place along the curve)."""
    import bpy

    def build(nt):
        info = nt.nodes.new("ShaderNodeHairInfo")
        comb = nt.nodes.new("ShaderNodeCombineXYZ")
        length = node(nt, "ShaderNodeMath", operation="MULTIPLY")
        length.inputs[1].default_value = 0.25
        nt.links.new(info.outputs["Length"], length.inputs[0])
        for output, axis in ((info.outputs["Random"], "X"), (info.outputs["Intercept"], "Y"),
                             (length.outputs[0], "Z")):
            nt.links.new(output, comb.inputs[axis])
        return comb.outputs[0]

    mat, _ = bs.texture_plane(build, resolution=(64, 64))
    bpy.data.objects.remove(bpy.data.objects["Plane"])
    curves = [[(-0.9 + 0.1 * i, y, 0.0), (-0.5, y, 0.0), (0.1 - 0.1 * i, y, 0.0), (0.9 - 0.15 * i, y, 0.0)]
              for i, y in enumerate(np.linspace(-0.64, 0.64, 5))]
    bs.hair_curves("Strands", curves, radius=0.09, material=mat, kind="POLY")
    ours = our_values_through_the_camera()
    cycles = bs.cycles_texture_values(mat, tmp_path / "cycles.exr")
    assert_matches_inside_silhouettes("curves info", ours, cycles)
