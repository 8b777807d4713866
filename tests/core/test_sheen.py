"""Sheen (``Materials.sheen_color``): Cycles' microfiber sheen against formulas written here from
Cycles' ``bsdf_sheen.h`` (scalar, per direction), a chi-square test of its sampling, and closed
forms under a constant sky: alone it reflects E(mu) of the sky, laid over a white material
(``sheen_cover`` 1) it keeps the sky exactly, and under it (cover 0) the material would show
1 + E."""
import math

import numpy as np
import pytest

from chi2 import ChiSquareTest
from core import RenderSettings, bsdf, render
from core.scene import Materials
from core.testing.scenes import sky_over_floor
from test_rough_diffuse import scatter_at_view, view_cosines

METHODS = [dict(method="ppm"), dict(method="amcmcppm", chains=4096)]


def fit(mu, r):
    """(E, a, b) of Zeltner et al. 2022's fits (scalars), roughness clamped as Cycles does."""
    y = min(max(r, 1e-3), 1.0)
    x = min(max(mu, 0.0), 1.0)
    s = y * (0.0206607 + 1.58491 * y) / (0.0379424 + y * (1.32227 + y))
    m = y * (-0.193854 + y * (-1.14885 + y * (1.7932 - 0.95943 * y * y))) / (0.046391 + y)
    o = y * (0.000654023 + (-0.0207818 + 0.119681 * y) * y) / (1.26264 + y * (-1.92021 + y))
    e = math.exp(-0.5 * ((x - m) / s) ** 2) / (s * math.sqrt(2 * math.pi)) + o
    a = (2.58126 * x + 0.813703 * y) * y / (1 + 0.310327 * x * x + 2.60994 * x * y)
    b = math.sqrt(1 - x) * (y - 1) * y ** 3 / (0.0000254053 + 1.71228 * x - 1.71506 * x * y + 1.34174 * y * y)
    return min(max(e, 0.0), 1.0), a, b


def reference(view, light, r):
    """Cycles' sheen f cos(light) per unit colour (E times ``bsdf_sheen_eval``) for unit vectors
    about the normal +z: its frame's x axis is the view along the surface."""
    e, a, b = fit(view[2], r)
    t = np.array([view[0], view[1], 0.0])
    t = t / np.linalg.norm(t)
    bt = np.cross([0.0, 0.0, 1.0], t)
    x, y, z = light @ t, light @ bt, light[2]
    len_sq = (a * x + b * z) ** 2 + (a * y) ** 2 + z * z
    return e * max(z, 0.0) / math.pi * (a / len_sq) ** 2


def sheen_table(r, colour=1.0):
    return bsdf.MaterialTable.from_materials(Materials.build([{"name": "velvet", "sheen": colour,
                                                               "sheen_roughness": r}]))


def test_the_fits_are_cycles_own_at_their_nodes():
    """Spot values of the fits (checked against the furnace albedo Cycles renders: a white Sheen
    BSDF sphere under a white world, 256 samples, within 1 % over the disc at roughness 0.3-1),
    and Cycles' cut: a sheen whose a or E is below 1e-5 is left out."""
    e, a, b = bsdf.sheen_albedo(np.array([0.5, 0.05, 0.95]), np.array([0.5, 1.0, 0.001]))
    assert e[0] == pytest.approx(fit(0.5, 0.5)[0], rel=1e-12) and 0.14 < e[0] < 0.16
    assert e[1] == pytest.approx(fit(0.05, 1.0)[0], rel=1e-12) and a[1] > 0 and b[1] == 0.0
    assert e[2] == 0.0                                    # roughness 1e-3: no sheen at all


@pytest.mark.parametrize("r", [0.3, 0.5, 1.0])
@pytest.mark.parametrize("mu", [0.1, 0.5, 0.95])
def test_photons_scatter_off_the_sheen_as_cycles_evaluates_it(r, mu):
    """A photon arriving from ``wo`` leaves cosine-distributed: its weight is f(wi, wo) cos / pdf
    with the new direction wi as the view (the adjoint), per sample equal to the reference, and
    its mean the integral of f(v, wo) cos(v) over views (midpoint rule)."""
    table = sheen_table(r, 0.8)
    assert table.has_sheen and table.lobes == 6
    wi, w, alive, wo = scatter_at_view(table, bsdf.SHEEN, mu, seed=3)
    assert np.isfinite(w).all() and (w >= 0).all()
    for k in np.random.default_rng(4).integers(0, len(w), 20):
        ref = 0.8 * reference(wi[k], wo[k], r) / mu * math.pi       # f(wi, wo) cos(wi) / (cos(wi) / pi)
        assert w[k, 0] == pytest.approx(ref, rel=1e-5, abs=1e-12)
    m = 128
    total = 0.0
    for i in range(m):
        c = (i + 0.5) / m
        s = math.sqrt(1 - c * c)
        for j in range(m):
            phi = (j + 0.5) / m * 2 * math.pi
            v = np.array([s * math.cos(phi), s * math.sin(phi), c])
            total += reference(v, wo[0], r) / mu * c
    want = 0.8 * total * (1.0 / m) * (2 * math.pi / m)
    assert w[:, 0].mean() == pytest.approx(want, rel=0.02, abs=2e-4)


@pytest.mark.parametrize("r, mu", [(0.5, 0.3), (1.0, 0.8), (0.3, 0.1)])
def test_camera_paths_sample_the_sheen_as_its_density(r, mu):
    """Camera paths sample the transformed cosine itself (Cycles' ``bsdf_sheen_sample``): a
    chi-square test of the directions in (cos theta, phi) against the lobe's density, each of
    weight E(mu) times the colour."""
    table = sheen_table(r)
    e, _, _ = fit(mu, r)
    view = np.array([math.sqrt(1 - mu * mu), 0.0, mu])

    def sample(n):
        wi, w, alive, _ = scatter_at_view(table, bsdf.SHEEN, mu, "radiance", n, seed=11)
        assert np.allclose(w[alive, 0], e, rtol=1e-6)
        return np.stack([wi[:, 2], np.arctan2(wi[:, 1], wi[:, 0]) % (2 * math.pi)], axis=1), alive * 1.0

    def density(xy):
        out = np.empty(len(xy))
        for i, (c, phi) in enumerate(xy):
            s = math.sqrt(max(1 - c * c, 0.0))
            out[i] = reference(view, np.array([s * math.cos(phi), s * math.sin(phi), c]), r) / e
        return out

    test = ChiSquareTest(sample, density, ((0.0, 1.0), (0.0, 2 * math.pi)), sample_count=200_000, res=24,
                         ires=3)
    assert test.run(1e-4), test.message


def sheen_floor(spec):
    return sky_over_floor(resolution=(32, 32), material=spec)


def halves(image, rows=32):
    h = rows // 2
    return np.array([image[:h].mean(), image[h:].mean()])


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m["method"])
def test_a_sheen_under_a_constant_sky_reflects_its_albedo_and_keeps_what_it_covers(method):
    """An open floor under a white sky: a white sheen alone (roughness 0.5) shows E(mu) of each
    pixel's view, in the far (grazing, E about 0.29) and near (face on, 0.065) half; over a
    white diffuse with cover 1 (Cycles' Principled layering) the floor keeps the sky exactly,
    where without the cover (0) it would be 1 + E.  2 seeds x 8 passes, 8 seeds with the chains:
    their near half spread over 0.87-1.15 of E a seed (seeds 0-7; the mean 0.99-1.00)."""
    mu = view_cosines(sheen_floor({"sheen": 1.0}))
    want = halves(np.vectorize(lambda c: fit(c, 0.5)[0])(mu))
    seeds = 8 if method["method"] == "amcmcppm" else 2

    def image(spec):
        settings = [RenderSettings(workers=1, passes=8, photons_per_pass=40_000, seed=s, **method)
                    for s in range(seeds)]
        return np.mean([render(sheen_floor(spec), k).image[..., :3].mean(axis=2) for k in settings], axis=0)
    alone = halves(image({"sheen": 1.0, "sheen_roughness": 0.5}))
    np.testing.assert_allclose(alone, want, rtol=0.08)
    covered = halves(image({"diffuse": 1.0, "sheen": 1.0, "sheen_roughness": 0.5, "sheen_cover": 1.0}))
    np.testing.assert_allclose(covered, 1.0, atol=0.06)
    uncovered = halves(image({"diffuse": 1.0, "sheen": 1.0, "sheen_roughness": 0.5}))
    assert uncovered[0] > 1.2, uncovered


def test_a_sheen_lies_over_a_coat():
    """A white diffuse under a coat (IOR 1.5) keeps the sky, and so does a white sheen over both
    (the sheen moves to the coat's material, ``coat_variants``, which its cover dims as what lies
    under the coat).  A check of the bookkeeping (the coat rows' sheen, the dims at both layers),
    not of the order: a white sheen under the coat would keep the sky too, and one that left the
    coat undimmed would be only C E (a few per cent) too bright.  The order is Cycles' (its
    Principled allocates the sheen first)."""
    spec = {"diffuse": 1.0, "coat": 1.0, "coat_roughness": 0.2, "coat_ior": 1.5}
    out = []
    for extra in ({}, {"sheen": 1.0, "sheen_roughness": 0.5, "sheen_cover": 1.0}):
        out.append(np.mean([halves(render(sheen_floor({**spec, **extra}),
                                          RenderSettings(workers=1, passes=8, photons_per_pass=40_000, seed=s,
                                                         method="ppm")).image[..., :3].mean(axis=2))
                            for s in range(2)], axis=0))
    np.testing.assert_allclose(out[0], 1.0, atol=0.06)
    np.testing.assert_allclose(out[1], out[0], atol=0.04)


def test_a_sheen_is_an_effect_of_its_own():
    """A scene with a sheen names it among its effects (``RenderContext.effects``), and its sixth
    lobe column does not make the translucent column's empty lobe an effect."""
    from core.context import RenderContext
    effects = RenderContext(sheen_floor({"diffuse": 0.5, "sheen": 1.0, "sheen_cover": 1.0})).effects
    assert "sheen" in effects and "translucency" not in effects, effects
    assert "sheen" not in RenderContext(sheen_floor({"diffuse": 0.5})).effects
