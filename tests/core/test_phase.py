"""Phase functions of scattering volumes (``core/phase.py``): Blender 5.0's Volume Scatter phases
(Henyey-Greenstein, Rayleigh, Draine, Fournier-Forand, Mie) as Cycles evaluates and samples them."""
from __future__ import annotations

import numpy as np
import pytest

from core import phase
from core.sampling import sample_hg
from core.scene import Materials, SceneError, World
from core.testing.scenes import MeshBuilder

# (kind, anisotropy g, params): each phase, and Mie across its four fitted ranges of diameter.
CASES = {"hg": (phase.HENYEY_GREENSTEIN, 0.7, (0, 0, 0)), "rayleigh": (phase.RAYLEIGH, 0.0, (0, 0, 0)),
         "draine": (phase.DRAINE, 0.5, (0.8, 0, 0)), "draine_small_g": (phase.DRAINE, 0.005, (0.6, 0, 0)),
         "fournier_forand": (phase.FOURNIER_FORAND, 0.0, (0.1, 1.1, 0)),
         "mie_0.05": (phase.MIE, 0.0, (0.05, 0, 0)), "mie_0.8": (phase.MIE, 0.0, (0.8, 0, 0)),
         "mie_3": (phase.MIE, 0.0, (3.0, 0, 0)), "mie_20": (phase.MIE, 0.0, (20.0, 0, 0))}


def rows_of(name, n=1):
    kind, g, params = CASES[name]
    return np.tile(phase.resolve([kind], [g], [params]), (n, 1))


def probability(rows, lo, hi, points=2001):
    """The chance that 1 - cos lies in [lo, hi] (quadrature in log(1 - cos), which resolves the
    forward peaks)."""
    t = np.linspace(np.log(lo), np.log(hi), points)
    one_minus = np.exp(t)
    values = phase.value(np.tile(rows[0], (len(t), 1)), 1.0 - one_minus)
    return 2.0 * np.pi * np.trapz(values * one_minus, t)


@pytest.mark.parametrize("name", sorted(CASES))
def test_each_phase_integrates_to_one(name):
    rows = rows_of(name)
    total = probability(rows, 1e-12, 2.0, points=400_001)
    # (Fournier-Forand's peak at cos = 1 is singular: the part within 1e-12 of it is left out)
    assert total == pytest.approx(1.0, abs=1e-4 if name == "fournier_forand" else 1e-6)


@pytest.mark.parametrize("name", sorted(CASES))
def test_each_sampler_draws_its_phase(name):
    """Chi-square of 200,000 sampled cosines in bins of log(1 - cos) (from 1e-5: Fournier-Forand's
    Newton steps, as Cycles', stop within 1e-6 of the cosine) against the phase's own probabilities;
    the sampled directions are unit vectors about the travel direction."""
    n = 200_000
    rng = np.random.default_rng(7)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    rows = rows_of(name, n)
    out = phase.sample(rows, d, rng.random(n), rng.random(n))
    assert np.isfinite(out).all()
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-9)
    one_minus = 1.0 - (out * d).sum(axis=1)
    edges = np.concatenate([[0.0], np.geomspace(1e-5, 2.0, 30)])
    counts = np.histogram(np.clip(one_minus, 0.0, 2.0), edges)[0]
    expected = n * np.array([probability(rows, max(a, 1e-12), b) for a, b in zip(edges[:-1], edges[1:])])
    used = expected > 20
    chi2 = (((counts - expected) ** 2 / expected)[used]).sum()
    dof = used.sum() - 1
    assert chi2 < dof + 5 * np.sqrt(2 * dof), (chi2, dof)


def test_henyey_greenstein_keeps_the_samples_it_had():
    """The same numbers give the same directions as the sampler before stop 51 (core.sampling.sample_hg):
    scenes of Henyey-Greenstein volumes render as they did."""
    rng = np.random.default_rng(3)
    n = 1000
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    g = rng.uniform(-0.9, 0.9, n)
    u1, u2 = rng.random(n), rng.random(n)
    rows = phase.resolve(np.zeros(n), g, np.zeros((n, 3)))
    assert np.array_equal(phase.sample(rows, d, u1, u2), sample_hg(d, g, u1, u2))
    assert phase.isotropic(phase.resolve([0, 0, 1, 2, 4], [0.0, 0.3, 0.0, 0.0, 0.0],
                                         np.zeros((5, 3)))).tolist() == [True, False, False, True, False]


def test_phases_round_trip_through_a_scene_file_and_are_validated(tmp_path):
    mats = Materials.build([{"name": "fog", "opacity": 0.0, "volume_scattering": 0.2,
                             "volume_phase": phase.MIE, "volume_phase_params": (2.5, 0.0, 0.0)}])
    m = MeshBuilder()
    m.add_box((-1, -1, -1), (1, 1, 1), 0)
    world = World(volume_scattering=np.full(3, 0.01, np.float32), volume_phase=phase.RAYLEIGH)
    scene = m.build(mats, world=world)
    scene.save(tmp_path / "fog.npz")
    loaded = type(scene).load(tmp_path / "fog.npz")
    assert loaded.materials.volume_phase[0] == phase.MIE and loaded.materials.volume_phase_params[0, 0] == 2.5
    assert loaded.world.volume_phase == phase.RAYLEIGH
    with pytest.raises(SceneError, match="volume_phase"):
        scene.replace(materials=Materials.build([{"name": "fog", "volume_phase": 7}])).validate()
    with pytest.raises(SceneError, match="world.volume_phase"):
        m.build(mats, world=World(volume_scattering=np.full(3, 0.01, np.float32), volume_phase=9))
