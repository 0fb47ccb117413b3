"""VelocityAutocorrelation, band_summary, spectrum_difference on signals with known answers."""

from __future__ import annotations

import math
import warnings

import MDAnalysis as mda
import numpy as np
import openmm.app as app
import openmm.unit as unit
import pytest
from MDAnalysis.coordinates.memory import MemoryReader

from openmm_alphaprk.analysis import VelocityAutocorrelation, band_summary, spectrum_difference
from openmm_alphaprk.analysis.vacf import PS_INV_IN_CM_INV

DT = 0.004  # ps between frames, as in the run driver's velocity files


def _universe(velocities: np.ndarray, dt: float = DT, names=None, masses=None, as_velocities=False):
    """A Universe whose positions (or velocities) are the given (n_frames, n_atoms, 3) array."""
    n_atoms = velocities.shape[1]
    u = mda.Universe.empty(n_atoms, trajectory=True)
    u.add_TopologyAttr("name", names if names is not None else ["H"] * n_atoms)
    if masses is not None:
        u.add_TopologyAttr("masses", masses)
    data = velocities.astype(np.float32)
    if as_velocities:
        rng = np.random.default_rng(99)
        positions = rng.normal(size=data.shape).astype(np.float32)
        u.load_new(positions, format=MemoryReader, velocities=data, dt=dt)
    else:
        u.load_new(data, format=MemoryReader, dt=dt)
    return u


def _cosines(wavenumbers, amplitudes, n_frames=2000, n_atoms=40, seed=0, dt=DT):
    """Σ_k A_k cos(2π ν_k t + φ) per atom and component, random phases φ; Å/ps."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames)[:, None, None] * dt
    v = np.zeros((n_frames, n_atoms, 3))
    for wavenumber, amplitude in zip(wavenumbers, amplitudes):
        nu = wavenumber / PS_INV_IN_CM_INV  # ps⁻¹
        v += amplitude * np.cos(2 * np.pi * nu * t + rng.uniform(0, 2 * np.pi, size=(1, n_atoms, 3)))
    return v


def _direct_vacf(v: np.ndarray, n_lags: int, weights=None) -> np.ndarray:
    """Brute force: average over atoms (weighted) and over all origins of v(t0)·v(t0 + lag)."""
    n_frames, n_atoms, _ = v.shape
    w = np.ones(n_atoms) if weights is None else np.asarray(weights, dtype=float)
    out = np.empty(n_lags)
    for lag in range(n_lags):
        products = np.einsum("tij,tij->ti", v[: n_frames - lag], v[lag:])  # (origins, atoms)
        out[lag] = (products.mean(axis=0) * w).sum() / w.sum()
    return out


def test_single_cosine_vacf_spectrum_and_band():
    amplitude, wavenumber = 2.0, 600.0
    v = _cosines([wavenumber], [amplitude])
    r = VelocityAutocorrelation(_universe(v)).run().results
    assert r.max_lag == pytest.approx(1.0)  # default: 1 ps (the run is 8 ps)
    assert r.dt == pytest.approx(DT)
    np.testing.assert_allclose(np.diff(r.lags), DT, rtol=1e-6)
    omega = 2 * np.pi * wavenumber / PS_INV_IN_CM_INV
    np.testing.assert_allclose(r.normalized_vacf, np.cos(omega * r.lags), atol=2e-3)
    assert r.vacf[0] == pytest.approx(1.5 * amplitude**2, rel=2e-3)  # 3 components × A²/2

    assert r.frequency_resolution == pytest.approx(PS_INV_IN_CM_INV / 2.0)  # 16.7 cm⁻¹ for 1 ps
    assert np.sum(0.5 * (r.spectrum[1:] + r.spectrum[:-1]) * np.diff(r.frequencies)) == pytest.approx(1.0)
    peak = r.frequencies[np.argmax(r.spectrum)]
    assert abs(peak - wavenumber) < r.frequency_resolution
    band = band_summary(r.frequencies, r.spectrum, 400.0, 800.0)
    assert band["peak"] == peak
    assert band["centroid"] == pytest.approx(wavenumber, abs=3.0)
    assert band["weight"] == pytest.approx(1.0, abs=0.01)
    assert band_summary(r.frequencies, r.spectrum, 1000.0, 3000.0)["weight"] == pytest.approx(0.0, abs=0.01)


def test_two_cosines_band_weights_follow_amplitude_squared():
    v = _cosines([300.0, 900.0], [1.0, 2.0], seed=1)
    r = VelocityAutocorrelation(_universe(v)).run().results
    low = band_summary(r.frequencies, r.spectrum, 0.0, 600.0)
    high = band_summary(r.frequencies, r.spectrum, 600.0, 5000.0)
    assert low["weight"] == pytest.approx(0.2, abs=0.01)
    assert high["weight"] == pytest.approx(0.8, abs=0.01)
    assert low["weight"] + high["weight"] == pytest.approx(1.0, abs=1e-9)  # adjacent bands tile
    assert abs(low["peak"] - 300.0) < r.frequency_resolution
    assert abs(high["peak"] - 900.0) < r.frequency_resolution
    assert high["centroid"] == pytest.approx(900.0, abs=5.0)


def test_white_noise_vacf_is_variance_then_zero():
    sigma = 3.0
    v = np.random.default_rng(2).normal(scale=sigma, size=(1000, 100, 3))
    r = VelocityAutocorrelation(_universe(v)).run().results
    assert r.vacf[0] == pytest.approx(3 * sigma**2, rel=0.01)  # ⟨|v|²⟩ = 3σ²
    assert np.max(np.abs(r.normalized_vacf[1:])) < 0.012
    # Flat spectrum: the 0–2000 cm⁻¹ band holds 2000 / Nyquist of the area.
    nyquist = PS_INV_IN_CM_INV / (2 * DT)
    assert r.frequencies[-1] == pytest.approx(nyquist)
    assert band_summary(r.frequencies, r.spectrum, 0.0, 2000.0)["weight"] == pytest.approx(
        2000.0 / nyquist, abs=0.03
    )


def test_fft_matches_brute_force_unbiased_average():
    rng = np.random.default_rng(3)
    # Correlated, non-zero-mean signal: wrong padding (circular) or normalization shows up.
    v = np.cumsum(rng.normal(size=(60, 5, 3)), axis=0) + 4.0
    v = v.astype(np.float32).astype(float)
    r = VelocityAutocorrelation(_universe(v), max_lag=40 * DT).run().results
    assert len(r.lags) == 41
    np.testing.assert_array_equal(r.n_origins, 60 - np.arange(41))
    np.testing.assert_allclose(r.vacf, _direct_vacf(v, 41), rtol=1e-9)


def test_mass_weighted_average():
    rng = np.random.default_rng(4)
    v = rng.normal(size=(50, 4, 3)) * np.array([1.0, 2.0, 3.0, 4.0])[None, :, None]
    masses = np.array([1.008, 15.999, 1.008, 15.999])
    u = _universe(v, masses=masses)
    weighted = VelocityAutocorrelation(u, max_lag=20 * DT, mass_weighted=True).run().results
    plain = VelocityAutocorrelation(u, max_lag=20 * DT).run().results
    v32 = v.astype(np.float32).astype(float)
    np.testing.assert_allclose(weighted.vacf, _direct_vacf(v32, 21, masses), rtol=1e-9)
    np.testing.assert_allclose(plain.vacf, _direct_vacf(v32, 21), rtol=1e-9)
    assert weighted.vacf[0] > 1.2 * plain.vacf[0]  # the heavy atoms here are the fast ones


def test_selection_source_velocities_step_and_dt_override():
    v = _cosines([600.0], [1.0], n_frames=1000, n_atoms=6, seed=5)
    v[:, 3:] = _cosines([1500.0], [1.0], n_frames=1000, n_atoms=3, seed=6)
    names = ["H1", "H2", "H1", "O", "O", "O"]
    positions = VelocityAutocorrelation(_universe(v, names=names), select="name H*").run().results
    velocities = (
        VelocityAutocorrelation(
            _universe(v, names=names, as_velocities=True), select="name H*", source="velocities"
        )
        .run()
        .results
    )
    np.testing.assert_allclose(velocities.vacf, positions.vacf, rtol=1e-12)
    expected = _direct_vacf(v[:, :3].astype(np.float32).astype(float), 251)
    np.testing.assert_allclose(positions.vacf, expected, rtol=1e-6)
    assert band_summary(positions.frequencies, positions.spectrum, 1200.0, 1800.0)["weight"] < 0.01

    # run(step=2): frames 2 dt apart, the same as the subsampled array.
    stepped = VelocityAutocorrelation(_universe(v, names=names), select="name H*").run(step=2).results
    assert stepped.dt == pytest.approx(2 * DT)
    np.testing.assert_allclose(
        stepped.vacf, _direct_vacf(v[::2, :3].astype(np.float32).astype(float), len(stepped.lags)), rtol=1e-6
    )

    # dt override: frames said to be 2 fs apart, so the 600 cm⁻¹ line moves to 1200 cm⁻¹.
    halved = VelocityAutocorrelation(_universe(v, names=names), select="name H*", dt=DT / 2).run().results
    assert halved.dt == pytest.approx(DT / 2)
    np.testing.assert_allclose(halved.vacf[:100], positions.vacf[:100], rtol=1e-12)
    peak = band_summary(halved.frequencies, halved.spectrum)["peak"]
    assert abs(peak - 1200.0) < halved.frequency_resolution


def _gaussian(x, centre, width):
    return np.exp(-0.5 * ((x - centre) / width) ** 2) / (width * math.sqrt(2 * math.pi))


def test_spectrum_difference():
    grid = np.linspace(0.0, 4000.0, 4001)
    coarse = np.linspace(0.0, 4000.0, 1601)  # a different grid: interpolated
    a = _gaussian(grid, 600.0, 40.0)
    assert spectrum_difference(grid, a, grid, a) == 0.0
    assert spectrum_difference(coarse, _gaussian(coarse, 600.0, 40.0), grid, a) < 2e-3
    # Normalized within the band: a scaled copy is identical.
    assert spectrum_difference(grid, 3 * a, grid, a) == pytest.approx(0.0, abs=1e-12)

    b = _gaussian(grid, 1500.0, 40.0)
    assert spectrum_difference(grid, a, grid, b) == pytest.approx(1.0, abs=1e-6)
    # Two equal Gaussians d apart: ½ L1 = erf(d / (2√2 σ)).
    c = _gaussian(coarse, 650.0, 40.0)
    expected = math.erf(50.0 / (2 * math.sqrt(2) * 40.0))
    assert spectrum_difference(grid, a, coarse, c) == pytest.approx(expected, abs=2e-3)
    assert spectrum_difference(coarse, c, grid, a) == pytest.approx(spectrum_difference(grid, a, coarse, c))
    # Band limits: outside 1000–2000 only b lives, so a restricted comparison of a + b vs b is 0.
    assert spectrum_difference(grid, a + b, grid, b, low=1000.0, high=2000.0) == pytest.approx(0.0, abs=1e-9)
    assert spectrum_difference(grid, a + b, grid, b) == pytest.approx(0.5, abs=1e-6)
    with pytest.raises(ValueError, match="no positive area"):
        spectrum_difference(grid, np.where(grid < 900.0, a, 0.0), grid, b, low=1000.0, high=2000.0)


def test_band_summary_on_known_spectrum():
    grid = np.linspace(0.0, 3000.0, 3001)
    spectrum = 0.25 * _gaussian(grid, 500.0, 30.0) + 0.75 * _gaussian(grid, 1600.0, 50.0)
    band = band_summary(grid, spectrum, 1000.0, 2500.0)
    assert band["peak"] == 1600.0
    assert band["centroid"] == pytest.approx(1600.0, abs=1e-6)
    assert band["weight"] == pytest.approx(0.75, abs=1e-6)
    with pytest.raises(ValueError, match="no frequency"):
        band_summary(grid, spectrum, 5000.0, 6000.0)
    with pytest.raises(ValueError, match="low < high"):
        band_summary(grid, spectrum, 800.0, 700.0)


def test_errors():
    v = _cosines([600.0], [1.0], n_frames=50, n_atoms=3)
    u = _universe(v)
    with pytest.raises(ValueError, match="matches no atoms"):
        VelocityAutocorrelation(u, select="name O*")
    with pytest.raises(ValueError, match="unknown source"):
        VelocityAutocorrelation(u, source="forces")
    for bad in (0.0, -0.004):
        with pytest.raises(ValueError, match="dt must be a positive"):
            VelocityAutocorrelation(u, dt=bad)
    with pytest.raises(ValueError, match="time step of 0"):
        VelocityAutocorrelation(_universe(v, dt=0.0)).run()
    with pytest.raises(ValueError, match="at least 3"):
        VelocityAutocorrelation(u).run(stop=2)
    with pytest.raises(ValueError, match="longer than the analysed trajectory"):
        VelocityAutocorrelation(u, max_lag=49 * DT + 0.001).run()
    with pytest.raises(ValueError, match="longer than the analysed trajectory"):
        VelocityAutocorrelation(u, max_lag=0.194).run(step=2)  # 25 frames, 0.192 ps
    assert VelocityAutocorrelation(u, max_lag=49 * DT).run().results.lags[-1] == pytest.approx(49 * DT)
    with pytest.raises(ValueError, match="has no velocities"):
        VelocityAutocorrelation(u, source="velocities").run()
    with pytest.raises(ValueError, match="masses"):
        VelocityAutocorrelation(u, mass_weighted=True)
    with pytest.raises(ValueError, match="evenly spaced"):
        VelocityAutocorrelation(u, max_lag=0.01).run(frames=[0, 1, 3, 4])


def _water_topology(n_waters: int) -> app.Topology:
    topology = app.Topology()
    chain = topology.addChain()
    for _ in range(n_waters):
        residue = topology.addResidue("HOH", chain)
        for name, symbol in (("O", "O"), ("H1", "H"), ("H2", "H")):
            topology.addAtom(name, app.Element.getBySymbol(symbol), residue)
    return topology


def test_round_trip_through_openmm_dcd(tmp_path):
    """Velocities (nm/ps) written as DCD 'positions' by OpenMM: Å/ps, dt = step × interval."""
    n_waters, step_fs, interval = 3, 1.0, 4
    topology = _water_topology(n_waters)
    n_atoms = 3 * n_waters
    velocities_nm_ps = 0.1 * _cosines([700.0], [3.0], n_frames=600, n_atoms=n_atoms, seed=8)
    velocities_nm_ps += np.random.default_rng(9).normal(scale=0.05, size=velocities_nm_ps.shape)

    positions = np.arange(3 * n_atoms, dtype=float).reshape(n_atoms, 3) * 0.1
    with open(tmp_path / "topology.pdb", "w") as handle:
        app.PDBFile.writeFile(topology, positions * unit.nanometer, handle)
    with open(tmp_path / "velocities.dcd", "wb") as handle:
        dcd = app.DCDFile(handle, topology, step_fs * unit.femtoseconds, firstStep=0, interval=interval)
        for frame in velocities_nm_ps:
            dcd.writeModel(frame * unit.nanometer)  # nm/ps typed as nm, as the run driver does

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # PDB without box / CONECT
        u = mda.Universe(str(tmp_path / "topology.pdb"), str(tmp_path / "velocities.dcd"))
    assert u.trajectory.n_frames == len(velocities_nm_ps)
    assert u.trajectory.dt == pytest.approx(step_fs * interval / 1000.0, rel=1e-6)  # 0.004 ps
    np.testing.assert_allclose(u.trajectory[5].positions, 10.0 * velocities_nm_ps[5], rtol=1e-6)  # Å/ps

    from_dcd = VelocityAutocorrelation(u, select="name H*", max_lag=0.5).run().results
    hydrogens = [i for i in range(n_atoms) if i % 3]
    in_memory = (
        VelocityAutocorrelation(_universe(10.0 * velocities_nm_ps[:, hydrogens], dt=0.004), max_lag=0.5)
        .run()
        .results
    )
    np.testing.assert_allclose(from_dcd.lags, in_memory.lags, rtol=1e-6)
    np.testing.assert_allclose(from_dcd.vacf, in_memory.vacf, rtol=1e-5, atol=1e-5 * in_memory.vacf[0])
    np.testing.assert_allclose(from_dcd.frequencies, in_memory.frequencies, rtol=1e-6)
    np.testing.assert_allclose(from_dcd.spectrum, in_memory.spectrum, atol=1e-6 * in_memory.spectrum.max())
    assert from_dcd.vacf[0] == pytest.approx(100.0 * 1.5 * 0.3**2 + 100.0 * 3 * 0.05**2, rel=0.05)
    assert abs(band_summary(from_dcd.frequencies, from_dcd.spectrum, 300, 1100)["peak"] - 700.0) < 2 * (
        from_dcd.frequency_resolution
    )
