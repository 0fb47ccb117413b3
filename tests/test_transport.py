"""Transport and structure of water: Yeh–Hummer correction, dipole reorientation, g(r) peak, run folders."""

from __future__ import annotations

import json
import math

import MDAnalysis as mda
import numpy as np
import openmm.unit as unit
import pytest
from MDAnalysis.coordinates.memory import MemoryReader

from openmm_alphaprk._units import InputError, InputTypeError
from openmm_alphaprk.analysis import (
    DipoleReorientation,
    corrected_diffusion,
    first_peak,
    yeh_hummer_correction,
)

# --- Yeh–Hummer ---------------------------------------------------------------------------


def test_yeh_hummer_against_hand_value():
    # ξ k_B T / (6 π η L), SI by hand: T = 298 K, η = 0.321e-3 Pa s, L = 2e-9 m.
    by_hand = 2.837297 * 1.380649e-23 * 298.0 / (6 * math.pi * 0.321e-3 * 2e-9)  # m²/s
    assert by_hand == pytest.approx(9.64647e-10, rel=1e-5)
    assert yeh_hummer_correction(298.0, 2.0) == pytest.approx(by_hand * 1e9, rel=1e-12)  # 1e-5 cm²/s
    # The correction goes as T / (η L).
    assert yeh_hummer_correction(596.0, 4.0, 0.642) == pytest.approx(0.5 * by_hand * 1e9, rel=1e-12)
    assert corrected_diffusion(5.0, 298.0, 2.0) == pytest.approx(5.0 + by_hand * 1e9, rel=1e-12)


def test_yeh_hummer_takes_quantities():
    plain = yeh_hummer_correction(300.0, 3.0, 0.5)
    quantity = yeh_hummer_correction(
        300.0 * unit.kelvin, 30.0 * unit.angstrom, 0.5e-3 * unit.pascal * unit.second
    )
    assert quantity == pytest.approx(plain, rel=1e-12)


@pytest.mark.parametrize(
    ("arguments", "error"),
    [
        ((-1.0, 2.0), InputError),
        ((298.0, 0.0), InputError),
        ((298.0, 2.0, 0.0), InputError),
        ((298.0, 2.0 * unit.picosecond), InputTypeError),
    ],
)
def test_yeh_hummer_refuses_bad_input(arguments, error):
    with pytest.raises(error):
        yeh_hummer_correction(*arguments)


# --- g(r) first peak ----------------------------------------------------------------------


def test_first_peak_exact_for_a_parabola():
    r = np.arange(2.0, 4.0, 0.1) + 0.05
    g = 3.0 - 7.0 * (r - 2.8123) ** 2
    position, height = first_peak(r, g)
    assert position == pytest.approx(2.8123, abs=1e-9)
    assert height == pytest.approx(3.0, abs=1e-9)


def test_first_peak_refines_a_gaussian_between_bins():
    r = np.arange(0.0, 8.0, 0.08) + 0.04
    g = 1.0 + 2.0 * np.exp(-0.5 * ((r - 2.81) / 0.15) ** 2) + 0.3 * np.exp(-0.5 * ((r - 4.5) / 0.4) ** 2)
    position, height = first_peak(r, g)
    top = int(np.argmax(g))
    assert abs(r[top] - 2.81) > 0.02  # the highest bin alone is off ...
    assert position == pytest.approx(2.81, abs=0.005)  # ... the parabola is not
    assert height == pytest.approx(3.0, abs=0.03)
    assert height > g[top]
    # A window: the second shell's maximum.
    assert first_peak(r, g, r_min=3.8)[0] == pytest.approx(4.5, abs=0.05)


def test_first_peak_refuses_bad_input():
    with pytest.raises(InputError, match="evenly spaced"):
        first_peak([1.0, 2.0, 4.0], [0.0, 1.0, 0.0])
    with pytest.raises(InputError, match="no bin"):
        first_peak(np.arange(5.0), np.ones(5), r_min=10.0)


# --- dipole reorientation on synthetic trajectories ---------------------------------------

R_OH = 0.9572  # Å
HALF_ANGLE = math.radians(104.52 / 2)


def _water_universe(
    dipoles: np.ndarray, dt: float, box: float | None = None, origins: np.ndarray | None = None
) -> mda.Universe:
    """Waters whose dipole (bisector) directions are ``dipoles`` (n_frames, n_molecules, 3)."""
    n_frames, n_molecules, _ = dipoles.shape
    universe = mda.Universe.empty(
        3 * n_molecules,
        n_residues=n_molecules,
        atom_resindex=np.repeat(np.arange(n_molecules), 3),
        trajectory=True,
    )
    universe.add_TopologyAttr("name", ["O", "H1", "H2"] * n_molecules)
    universe.add_TopologyAttr("resname", ["HOH"] * n_molecules)
    rng = np.random.default_rng(0)
    if origins is None:
        origins = rng.uniform(0.0, 20.0, size=(n_molecules, 3))
    u = dipoles / np.linalg.norm(dipoles, axis=-1, keepdims=True)
    # Any direction perpendicular to u puts the molecule's plane; it may change freely.
    helper = np.where(np.abs(u[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    w = np.cross(u, helper)
    w /= np.linalg.norm(w, axis=-1, keepdims=True)
    positions = np.empty((n_frames, n_molecules, 3, 3))
    positions[:, :, 0] = origins
    for k, sign in ((1, 1.0), (2, -1.0)):
        positions[:, :, k] = origins + R_OH * (math.cos(HALF_ANGLE) * u + sign * math.sin(HALF_ANGLE) * w)
    coordinates = positions.reshape(n_frames, 3 * n_molecules, 3).astype(np.float32)
    dimensions = None if box is None else np.array([box, box, box, 90.0, 90.0, 90.0], dtype=np.float32)
    if box is not None:
        coordinates = coordinates % box  # atoms wrapped into the box: molecules split at its edges
    universe.load_new(coordinates, format=MemoryReader, dt=dt, dimensions=dimensions)
    return universe


def test_frozen_dipoles_give_one():
    rng = np.random.default_rng(1)
    fixed = rng.normal(size=(1, 30, 3))
    rotation = DipoleReorientation(_water_universe(np.repeat(fixed, 50, axis=0), dt=0.01)).run()
    np.testing.assert_allclose(rotation.results.c1, 1.0, atol=1e-6)
    np.testing.assert_allclose(rotation.results.c2, 1.0, atol=1e-6)
    assert math.isnan(rotation.results.tau2)  # never falls below the threshold
    assert rotation.results.tau2_fit == math.inf
    assert rotation.results.n_molecules == 30
    assert rotation.results.max_lag == pytest.approx(0.24)  # half of 49 frames' 0.49 ps, on the grid


def test_constant_rotation_gives_legendre_cosines():
    # Each dipole turns at ω about an axis perpendicular to it: u(t0)·u(t0 + t) = cos ωt.
    omega, dt, n_frames = 2.0, 0.005, 600  # rad/ps, ps
    rng = np.random.default_rng(2)
    n_molecules = 12
    axes = rng.normal(size=(n_molecules, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    start = np.cross(axes, rng.normal(size=(n_molecules, 3)))
    start /= np.linalg.norm(start, axis=1, keepdims=True)
    other = np.cross(axes, start)
    angle = omega * dt * np.arange(n_frames)[:, None, None]
    dipoles = np.cos(angle) * start + np.sin(angle) * other
    # Wrapped into a 6 Å box: molecules across its edge must be taken whole.
    rotation = DipoleReorientation(
        _water_universe(dipoles, dt, box=6.0, origins=rng.uniform(0, 6.0, (n_molecules, 3)))
    ).run()
    lags = rotation.results.lags
    np.testing.assert_allclose(rotation.results.c1, np.cos(omega * lags), atol=1e-5)
    np.testing.assert_allclose(rotation.results.c2, 1.5 * np.cos(omega * lags) ** 2 - 0.5, atol=1e-5)
    # ∫ C₂ to where it falls to 0.05: (3 cos² x − 1)/2 = 0.05 at x* = arccos √(1.1/3);
    # ∫₀ᵗ C₂ = t/4 + 3 sin 2ωt / (8ω).
    crossing = math.acos(math.sqrt(1.1 / 3)) / omega
    integral = crossing / 4 + 3 * math.sin(2 * omega * crossing) / (8 * omega)
    assert rotation.results.crossing2 == pytest.approx(crossing, abs=1e-4)
    assert rotation.results.tau2 == pytest.approx(integral, rel=1e-3)


def test_rotational_diffusion_gives_exponentials():
    # Brownian rotation, D_r: C_l = exp(-l (l + 1) D_r t), so τ₂ = 1 / (6 D_r), τ₁ = 1 / (2 D_r).
    d_r, dt, n_frames, n_molecules = 0.5, 0.002, 3000, 400  # 1/ps, ps
    rng = np.random.default_rng(3)
    u = rng.normal(size=(n_molecules, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    sigma = math.sqrt(2 * d_r * dt)  # per tangent component: <Δθ²> = 2σ² = 4 D_r dt
    dipoles = np.empty((n_frames, n_molecules, 3))
    for frame in range(n_frames):
        dipoles[frame] = u
        kick = rng.normal(scale=sigma, size=(n_molecules, 3))
        kick -= np.sum(kick * u, axis=1, keepdims=True) * u
        u = u + kick
        u /= np.linalg.norm(u, axis=1, keepdims=True)
    rotation = DipoleReorientation(_water_universe(dipoles, dt), max_lag=1.0, fit_start=0.0).run()
    lags = rotation.results.lags
    early = lags <= 0.5
    np.testing.assert_allclose(rotation.results.c2[early], np.exp(-6 * d_r * lags[early]), atol=0.03)
    np.testing.assert_allclose(rotation.results.c1[early], np.exp(-2 * d_r * lags[early]), atol=0.03)
    tau2 = 1 / (6 * d_r)
    assert rotation.results.tau2_fit == pytest.approx(tau2, rel=0.06)
    # The integral stops at C₂ = 0.05: (1 − 0.05) τ₂ for an exponential.
    assert rotation.results.tau2 == pytest.approx(0.95 * tau2, rel=0.06)


def test_rotation_refuses_non_water_residues():
    universe = _water_universe(np.ones((5, 2, 3)), dt=0.01)
    with pytest.raises(InputError, match="1 O, 2 H"):
        DipoleReorientation(universe, select="name O H1")
    with pytest.raises(InputError, match="threshold"):
        DipoleReorientation(universe, threshold=1.5)


# --- run directories ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    from openmm_alphaprk.runs import run_nve

    folder = tmp_path_factory.mktemp("transport")
    paths = []
    for integrator in ("rattle", "rattle+rescale"):
        for seed in (1, 2):
            path = folder / f"{integrator}-{seed}"
            run_nve(
                "tip3p-2nm",
                integrator,
                path,
                steps=200,
                platform="CPU",
                progress=False,
                trajectory_interval=4,
                velocity_interval=2,
                velocity_seed=seed,
                cpu_threads=1,
            )
            paths.append(path)
    return paths


def test_transport_of_runs_groups_segments_into_settings(runs):
    from openmm_alphaprk.workflows.transport import QUANTITIES, transport_of_runs

    result = transport_of_runs(runs)
    assert [(s.integrator, len(s.runs)) for s in result.settings] == [("rattle", 2), ("rattle+rescale", 2)]
    segments = result.segments
    assert len(segments) == 4
    for segment in segments:
        assert segment.frames == 50
        assert segment.box_length_nm == pytest.approx(2.0, rel=1e-5)
        assert 250 < segment.temperature_k < 350
        assert segment.diffusion_correction == pytest.approx(
            yeh_hummer_correction(segment.temperature_k, segment.box_length_nm), rel=1e-6
        )
        assert segment.diffusion == pytest.approx(segment.diffusion_pbc + segment.diffusion_correction)
        assert 2.65 < segment.rdf_peak_r_angstrom < 2.95
        assert 2.0 < segment.rdf_peak_g < 4.0
        assert math.isnan(segment.tau2_ps)  # 0.2 ps of C₂: still far above 0.05
        assert segment.tau2_fit_ps > 0
        assert segment.vacf_source == "trajectory.trr"  # positions, velocities (Å/ps) and box
        # Half the velocities' span (0.4 ps), on the 4 fs grid of velocity_interval × timestep.
        assert 0.19 <= segment.vacf_max_lag_ps <= 0.2
        assert segment.vacf_max_lag_ps / 0.004 == pytest.approx(round(segment.vacf_max_lag_ps / 0.004))
    # Mean and standard error of each quantity over the two segments of a setting.
    rattle = result.settings[0]
    for name in QUANTITIES:
        values = [getattr(segment, name) for segment in segments[:2]]
        finite = [v for v in values if math.isfinite(v)]
        assert rattle.count[name] == len(finite)
        if len(finite) == 2:
            assert rattle.mean[name] == pytest.approx(np.mean(finite))
            assert rattle.standard_error[name] == pytest.approx(abs(finite[0] - finite[1]) / 2)
    # Plain JSON: NaN written as null.
    data = json.loads(result.to_json())
    assert data["settings"][0]["mean"]["tau2_ps"] is None
    assert data["parameters"]["viscosity_mpa_s"] == pytest.approx(0.321)


def test_transport_of_runs_refuses_a_folder_without_run_json(tmp_path):
    from openmm_alphaprk.workflows.transport import transport_of_runs

    with pytest.raises(InputError, match="run.json"):
        transport_of_runs([tmp_path])
    with pytest.raises(InputError, match="no run directories"):
        transport_of_runs([])
