"""The shared quantities: RMS, the drift fit and its standard error, how a drift is printed."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from openmm_alphaprk.observables import (
    DRIFT_RESOLVED_AT,
    drift_text,
    energy_drift,
    fit_drift,
    rms,
)


def _ar1(n: int, rho: float, rng: np.random.Generator) -> np.ndarray:
    """Stationary AR(1) noise of unit innovation: correlated like energy samples a few steps apart."""
    innovations = rng.standard_normal(n)
    x = np.empty(n)
    x[0] = innovations[0] / np.sqrt(1.0 - rho**2)
    for i in range(1, n):
        x[i] = rho * x[i - 1] + innovations[i]
    return x


def test_rms_is_the_root_mean_square():
    assert rms([3.0, -4.0]) == pytest.approx(np.sqrt(12.5))
    assert np.isnan(rms([]))
    assert rms(np.array([[1.0, 1.0], [2.0, 2.0]]), axis=1) == pytest.approx([1.0, 2.0])


def test_fit_recovers_a_known_drift_within_its_standard_error():
    rng = np.random.default_rng(6)
    t = np.linspace(0.0, 20.0, 401)  # ps
    values = 0.05 * t + rng.normal(0.0, 0.01, t.size)  # 50 kJ/mol/ns
    fit = fit_drift(t, values)
    assert fit.resolved
    assert abs(fit.slope - 50.0) < 3 * fit.standard_error
    assert fit.standard_error == pytest.approx(0.01 / np.sqrt(np.sum((t - t.mean()) ** 2)) * 1000, rel=0.2)
    assert fit.scatter == pytest.approx(0.01, rel=0.1)
    assert fit.line(t) == pytest.approx(0.05 * t, abs=0.005)


@pytest.mark.parametrize("rho", [0.0, 0.9])
def test_standard_error_matches_the_spread_of_slopes_and_flags_noise_as_unresolved(rho):
    """Zero true drift: the standard error is the slopes' spread; |slope| ≥ 2 SE in about 5 % of runs.

    With correlated samples (ρ = 0.9) the plain least-squares error would call about
    half of these noise-only runs resolved; the effective-sample correction does not.
    """
    rng = np.random.default_rng(1)
    t = np.linspace(0.0, 2.0, 201)
    fits = [fit_drift(t, _ar1(t.size, rho, rng)) for _ in range(500)]
    slopes = np.array([fit.slope for fit in fits])
    errors = np.array([fit.standard_error for fit in fits])
    assert np.median(errors) == pytest.approx(np.std(slopes), rel=0.2)
    assert np.mean([fit.resolved for fit in fits]) < 0.15
    assert np.median([fit.lag1_correlation for fit in fits]) == pytest.approx(rho, abs=0.05)


def test_drift_text_states_a_drift_only_when_it_is_resolved():
    assert drift_text(-486.0, 30.0, "kJ/mol/ns") == "-486 ± 30 kJ/mol/ns"
    assert drift_text(-486.0, 300.0, "kJ/mol/ns") == "not resolved (±3e+02 kJ/mol/ns)"
    assert drift_text(1.9 * 0.1, 0.1) == "not resolved (±0.1)"
    assert drift_text(DRIFT_RESOLVED_AT * 0.1, 0.1) == "+0.2 ± 0.1"
    assert drift_text(1.0, float("nan")) == "not resolved (too few samples)"
    assert drift_text(1.0, float("inf")) == "not resolved (samples too correlated)"


def test_energy_drift_of_a_short_noisy_run_is_not_resolved():
    rng = np.random.default_rng(3)
    t = np.arange(11) * 0.02  # 0.2 ps, 11 samples
    total = -1000.0 + rng.normal(0.0, 0.5, t.size)
    drift = energy_drift(t, total, dof=100)
    assert not drift.drift_resolved
    assert drift.drift_per_dof_standard_error == pytest.approx(
        drift.drift_standard_error_kj_per_mol_per_ns / 100
    )
    assert drift_text(drift.drift_per_dof, drift.drift_per_dof_standard_error).startswith("not resolved")
    assert drift.rms_residual == pytest.approx(rms(total[1:] - total[0]))
    # a trace of H − E_ref starting at 0 gives the same numbers as the total energies
    assert replace(energy_drift(t, total - total[0], dof=100), e_ref=drift.e_ref) == drift
    assert fit_drift(t[:2], total[:2]).resolved is False


def test_energy_residuals_stop_at_a_blow_up_and_propagate_errors_without_a_threshold():
    import openmm as mm
    import openmm.unit as unit

    from openmm_alphaprk.observables import energy_residuals, total_energy

    system = mm.System()
    for _ in range(2):
        system.addParticle(1.0)
    bond = mm.HarmonicBondForce()
    bond.addBond(0, 1, 0.1, 1000.0)
    system.addForce(bond)
    verlet = mm.VerletIntegrator(0.001)
    context = mm.Context(system, verlet, mm.Platform.getPlatformByName("Reference"))
    context.setPositions([[0, 0, 0], [0.12, 0, 0]] * unit.nanometers)
    e_ref = total_energy(context)

    class FailsAtThirdStep:
        calls = 0

        def step(self, n):
            self.calls += 1
            if self.calls == 3:
                raise RuntimeError("NaN")
            verlet.step(n)

    trace = energy_residuals(context, FailsAtThirdStep(), 5, blow_up=1e4)
    assert trace.e_ref == e_ref and trace.blew_up_at == 2 and trace.error == "RuntimeError"
    assert np.isfinite(trace.residuals[:2]).all() and np.isnan(trace.residuals[2:]).all()
    with pytest.raises(RuntimeError):
        energy_residuals(context, FailsAtThirdStep(), 5)
    kicked = energy_residuals(context, verlet, 4, e_ref=e_ref - 100.0, blow_up=50.0)
    assert kicked.blew_up_at == 0 and kicked.error is None and kicked.residuals[0] > 50
