"""Analyses on synthetic trajectories with known answers, and analyze_run on a real run."""

from __future__ import annotations

import json

import MDAnalysis as mda
import numpy as np
import pytest
from MDAnalysis.coordinates.memory import MemoryReader
from quick_systems import quick_system

from openmm_alphaprk.analysis import ConstraintDeviation, Diffusion, energy_drift, oxygen_rdf
from openmm_alphaprk.runs import run_nve
from openmm_alphaprk.workflows import analyze_run

OH, HH = 0.09572, 0.15139  # nm, TIP3P's rigid geometry
WATER = np.array([[0.0, 0.0, 0.0], [OH, 0.0, 0.0], [OH * np.cos(1.824218), OH * np.sin(1.824218), 0.0]])


def _universe(coordinates_angstrom: np.ndarray, n_residues: int, names: list[str], box=None, dt=1.0):
    n_atoms = coordinates_angstrom.shape[1]
    u = mda.Universe.empty(
        n_atoms,
        n_residues=n_residues,
        atom_resindex=np.repeat(np.arange(n_residues), n_atoms // n_residues),
        trajectory=True,
    )
    u.add_TopologyAttr("name", names)
    u.add_TopologyAttr("resname", ["HOH"] * n_residues)
    u.load_new(coordinates_angstrom.astype(np.float32), format=MemoryReader, dimensions=box, dt=dt)
    return u


def _rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


def _rigid_water_trajectory(n_waters=8, n_frames=20, seed=1):
    """Waters moved as rigid bodies (random rotations and translations) every frame: in nm."""
    rng = np.random.default_rng(seed)
    frames = np.empty((n_frames, 3 * n_waters, 3))
    for f in range(n_frames):
        for w in range(n_waters):
            frames[f, 3 * w : 3 * w + 3] = WATER @ _rotation(rng).T + rng.uniform(0, 2.0, 3)
    pairs = np.array([(3 * w + a, 3 * w + b) for w in range(n_waters) for a, b in ((0, 1), (0, 2), (1, 2))])
    lengths = np.tile([OH, OH, HH], n_waters)
    return frames, pairs, lengths


def test_rigid_water_has_zero_constraint_deviation():
    frames, pairs, lengths = _rigid_water_trajectory()
    u = _universe(frames * 10.0, 8, ["O", "H1", "H2"] * 8)
    result = ConstraintDeviation(u, pairs, lengths).run().results
    assert result.max_relative_deviation.shape == (20,)
    assert result.overall_max_relative_deviation < 2e-6  # single-precision coordinates, in Å


def test_constraint_deviation_measures_a_known_stretch():
    frames, pairs, lengths = _rigid_water_trajectory()
    stretched = frames.copy()
    bond = stretched[5, 1] - stretched[5, 0]
    stretched[5, 1] = stretched[5, 0] + bond * 1.01  # O–H of water 0 in frame 5: +1 %
    u = _universe(stretched * 10.0, 8, ["O", "H1", "H2"] * 8)
    result = ConstraintDeviation(u, pairs, lengths).run().results
    assert result.max_relative_deviation[5] == pytest.approx(0.01, rel=1e-3)
    assert result.max_abs_deviation_nm[5] == pytest.approx(0.01 * OH, rel=1e-3)
    others = np.delete(result.max_relative_deviation, 5)
    assert others.max() < 2e-6


def test_constraint_deviation_uses_the_minimum_image():
    frames, pairs, lengths = _rigid_water_trajectory(n_frames=3)
    box_nm = 2.5
    wrapped = frames.copy()
    wrapped[:, 1::3] -= box_nm * np.floor(wrapped[:, 1::3] / box_nm)  # hydrogens wrapped alone
    u = _universe(wrapped * 10.0, 8, ["O", "H1", "H2"] * 8, box=[box_nm * 10] * 3 + [90.0] * 3)
    assert ConstraintDeviation(u, pairs, lengths).run().results.overall_max_relative_deviation < 2e-6


def test_random_walk_msd_gives_the_known_diffusion_coefficient():
    """Gaussian steps of σ per dimension per frame: MSD = 3σ²t/Δt, D = σ²/(2Δt)."""
    rng = np.random.default_rng(3)
    sigma, dt, n_frames, n_particles = 0.3, 0.5, 200, 2000  # Å, ps
    steps = rng.normal(0.0, sigma, size=(n_frames, n_particles, 3))
    steps[0] = rng.uniform(0, 30, size=(n_particles, 3))
    u = _universe(np.cumsum(steps, axis=0), n_particles, ["O"] * n_particles, dt=dt)
    msd = Diffusion(u, "name O").run()
    expected = sigma**2 / (2 * dt) * 10.0  # Å²/ps → 1e-5 cm²/s
    assert msd.results.slope == pytest.approx(3 * sigma**2 / dt, rel=0.03)
    assert msd.results.diffusion_coefficient == pytest.approx(expected, rel=0.03)


def test_diffusion_standard_error_is_the_spread_over_independent_walks():
    """D ± its standard error: the groups' error matches the spread of D over independent random walks."""
    rng = np.random.default_rng(4)
    sigma, dt, n_frames, n_particles = 0.3, 0.5, 60, 200
    results = []
    for _ in range(12):
        steps = rng.normal(0.0, sigma, size=(n_frames, n_particles, 3))
        u = _universe(np.cumsum(steps, axis=0), n_particles, ["O"] * n_particles, dt=dt)
        results.append(Diffusion(u, "name O", error_groups=10).run().results)
    d = np.array([r.diffusion_coefficient for r in results])
    errors = np.array([r.diffusion_coefficient_standard_error for r in results])
    assert np.median(errors) == pytest.approx(np.std(d, ddof=1), rel=0.5)
    assert results[0].frames == n_frames and results[0].error_groups == 10


def test_ballistic_msd_is_quadratic():
    """Free flight x = x0 + v t: MSD(t) = <|v|²> t² exactly."""
    rng = np.random.default_rng(4)
    v = rng.normal(0.0, 2.0, size=(50, 3))
    t = np.arange(30) * 0.1
    coordinates = rng.uniform(0, 20, size=(1, 50, 3)) + t[:, None, None] * v[None]
    u = _universe(coordinates, 50, ["O"] * 50, dt=0.1)
    msd = Diffusion(u, "name O").run()
    lag = msd.results.delta_t_values
    np.testing.assert_allclose(lag, t, rtol=1e-6)
    np.testing.assert_allclose(
        msd.results.timeseries, np.mean(np.sum(v**2, axis=1)) * t**2, rtol=1e-4, atol=1e-8
    )


def test_rdf_of_an_ideal_gas_is_one():
    rng = np.random.default_rng(5)
    coordinates = rng.uniform(0, 30.0, size=(20, 1500, 3))
    u = _universe(coordinates, 1500, ["O"] * 1500, box=[30.0] * 3 + [90.0] * 3)
    rdf = oxygen_rdf(u, "name O", nbins=20, r_max=12.0)
    g = rdf.results.rdf[rdf.results.bins > 4.0]
    assert np.all(np.abs(g - 1.0) < 0.05)
    with pytest.raises(ValueError, match="no periodic box"):
        oxygen_rdf(_universe(coordinates[:2], 1500, ["O"] * 1500), "name O")


def test_energy_drift_recovers_a_known_slope():
    rng = np.random.default_rng(6)
    t = np.linspace(0.0, 20.0, 401)  # ps
    total = -1000.0 + 0.05 * t + rng.normal(0.0, 0.01, t.size)
    total[0] = -1000.0
    drift = energy_drift(t, total, dof=500)
    assert drift.drift_kj_per_mol_per_ns == pytest.approx(50.0, rel=0.01)
    assert drift.drift_per_dof == pytest.approx(0.1, rel=0.01)
    assert drift.e_ref == -1000.0
    with pytest.raises(ValueError, match="NaN"):
        energy_drift(t, np.where(t > 10, np.nan, total), dof=500)


def test_analyze_run_writes_json_and_figures(tmp_path_factory):
    prepared = quick_system("tip3p-2nm", tmp_path_factory.mktemp("cache"))
    run = tmp_path_factory.mktemp("run") / "rattle"
    run_nve(prepared, "rattle", run, steps=40, energy_interval=2, trajectory_interval=4, progress=False)
    result = analyze_run(run)
    stored = json.loads((run / "analysis.json").read_text(encoding="utf-8"))
    assert stored["energy"] == result["energy"] and stored["constraints"]["frames"] == 10
    assert result["constraints"]["overall_max_relative_deviation"] < 1e-5
    assert 2.6 < result["rdf"]["first_peak_r_angstrom"] < 3.0  # water's first O–O shell
    assert np.isfinite(result["msd"]["diffusion_coefficient_1e-5_cm2_per_s"])
    for figure in ("energy", "constraint_deviation", "rdf", "msd"):
        assert (run / result["figures"][figure].split("/")[-1]).stat().st_size > 1000
    with pytest.raises(FileNotFoundError, match="not a run directory"):
        analyze_run(tmp_path_factory.mktemp("empty"))
