"""The quantities every room measures, each in one place.

Energy, drift, RMS, DOF, constraints, momenta, α*, trajectory errors against a
reference, block averages, temperature.

Runs, analyses, benchmarks, reports and tests import these; nothing here imports
anything of the package above it (integrators, runs, workflows).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass

import numpy as np
import openmm as mm
import openmm.unit as unit

from ._units import InputError, positive_int

#: Percentiles of α* reported by runs, benchmarks and reports (as ``p1`` … ``p99``).
ALPHA_PERCENTILES = (1, 5, 25, 50, 75, 95, 99)

#: Why ``openmm.VerletIntegrator``'s H − E_ref is not comparable step for step.
VERLET_IS_LEAPFROG = (
    "openmm.VerletIntegrator is leapfrog: its State kinetic energy is a half-step estimate, so its "
    "H - E_ref is not comparable step for step with the velocity-Verlet integrators; its drift is."
)


def total_energy(source: mm.Context | mm.State) -> float:
    """Potential + kinetic energy (kJ/mol) of a context's current state or of a State with energies."""
    state = source.getState(getEnergy=True) if isinstance(source, mm.Context) else source
    return (state.getPotentialEnergy() + state.getKineticEnergy()).value_in_unit(unit.kilojoules_per_mole)


@dataclass
class EnergyTrace:
    """H − E_ref (kJ/mol) after each sample; ``blew_up_at``: the sample where the run stopped, if it did."""

    residuals: np.ndarray
    e_ref: float
    blew_up_at: int | None = None
    error: str | None = None


def energy_residuals(
    context: mm.Context,
    integrator: mm.Integrator,
    samples: int,
    *,
    steps_per_sample: int = 1,
    e_ref: float | None = None,
    blow_up: float | None = None,
    each_sample: Callable[[int, float], None] | None = None,
    progress: Callable[[range], Iterable[int]] | None = None,
) -> EnergyTrace:
    """Step ``integrator`` and read H − E_ref after every ``steps_per_sample`` steps.

    The one per-step energy measurement of benchmarks and tests: E_ref is the context's
    total energy before the first step unless given. With ``blow_up`` (kJ/mol) a step
    that raises, a non-finite energy or |H − E_ref| above it ends the run at that
    sample (``blew_up_at``; later residuals stay NaN, ``error`` names an exception);
    without it an exception propagates. ``each_sample(i, residual)`` is called after
    each sample; ``progress`` wraps the range of samples (e.g. ``tqdm``).
    """
    e_ref = total_energy(context) if e_ref is None else e_ref
    residuals = np.full(samples, np.nan)
    trace = EnergyTrace(residuals, e_ref)
    for i in (progress or iter)(range(samples)):
        if blow_up is None:
            integrator.step(steps_per_sample)
        else:
            try:
                integrator.step(steps_per_sample)
            except Exception as error:  # a failed step is the blow-up the caller measures
                trace.blew_up_at, trace.error = i, type(error).__name__
                break
        residuals[i] = total_energy(context) - e_ref
        if each_sample is not None:
            each_sample(i, residuals[i])
        if blow_up is not None and not abs(residuals[i]) <= blow_up:
            trace.blew_up_at = i
            break
    return trace


def convergence_order(step_sizes: np.ndarray, errors: np.ndarray) -> float:
    """Return the observed order of convergence: the least-squares slope of log(error) against log(h)."""
    return float(np.polyfit(np.log(step_sizes), np.log(errors), 1)[0])


def degrees_of_freedom(system: mm.System) -> int:
    """3 N − constraints − 3 if the system removes centre-of-mass motion (massive particles only)."""
    massive = sum(
        system.getParticleMass(i).value_in_unit(unit.dalton) > 0 for i in range(system.getNumParticles())
    )
    removes_cm = any(isinstance(system.getForce(i), mm.CMMotionRemover) for i in range(system.getNumForces()))
    return 3 * massive - system.getNumConstraints() - (3 if removes_cm else 0)


def rms(values: np.ndarray, axis: int | None = None) -> float | np.ndarray:
    """Root mean square, √(mean x²), of ``values`` (along ``axis``); NaN for no values.

    The one definition of every "RMS" the package reports (RMS |H − E_ref| of runs,
    comparisons, figures, benchmarks).
    """
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return float("nan")
    result = np.sqrt(np.mean(np.square(values), axis=axis))
    return float(result) if axis is None else result


def residual_statistics(residuals: np.ndarray) -> tuple[float, float]:
    """RMS and max |H − E_ref| (kJ/mol) of a trace of H − E_ref that starts at the start state.

    The first sample is the start state itself (H − E_ref = 0 by definition of E_ref)
    and is left out; NaN for a trace of one sample.
    """
    after_start = np.asarray(residuals, dtype=float)[1:]
    if after_start.size == 0:
        return float("nan"), float("nan")
    return rms(after_start), float(np.max(np.abs(after_start)))


@dataclass(frozen=True)
class DriftFit:
    """A least-squares line through H − E_ref against time, with the standard error of its slope.

    Attributes
    ----------
    slope
        The drift: slope of the line, in kJ/mol/ns (or the unit of the values per ns).
    standard_error
        Standard error of ``slope`` (same unit), widened for correlated samples (see
        :func:`fit_drift`); NaN with fewer than three samples, infinite when the samples
        are so correlated that fewer than three are effectively independent.
    intercept
        Value of the line at time 0 (kJ/mol).
    scatter
        RMS of the samples about the line (kJ/mol): the noise the slope is measured against.
    lag1_correlation
        Lag-1 autocorrelation of the samples about the line, clipped to [0, 1).
    samples
        Number of samples fitted.
    """

    slope: float
    standard_error: float
    intercept: float
    scatter: float
    lag1_correlation: float
    samples: int

    @property
    def resolved(self) -> bool:
        """Whether |slope| ≥ :data:`DRIFT_RESOLVED_AT` standard errors (False when the error is unknown)."""
        error = self.standard_error
        return bool(np.isfinite(error) and abs(self.slope) >= DRIFT_RESOLVED_AT * error)

    def line(self, times_ps: np.ndarray) -> np.ndarray:
        """Return the fitted line at ``times_ps`` (ps)."""
        return self.intercept + self.slope / 1000.0 * np.asarray(times_ps, dtype=float)

    def per_dof(self, dof: int) -> tuple[float, float]:
        """Slope and standard error divided by ``dof`` degrees of freedom."""
        return self.slope / dof, self.standard_error / dof


#: A drift is stated as a number only when |drift| is at least this many standard errors.
DRIFT_RESOLVED_AT = 2.0


def fit_drift(times_ps: np.ndarray, values: np.ndarray) -> DriftFit:
    """Fit a line to ``values`` (H − E_ref, kJ/mol) against ``times_ps``; its slope is the drift per ns.

    The one drift fit of the package (runs, comparisons, figures, analyses, benchmarks).
    The standard error of the slope is that of ordinary least squares with the number of
    samples replaced by an effective number n_eff = n (1 − ρ)/(1 + ρ), ρ the lag-1
    autocorrelation of the samples about the line (clipped to [0, 1)): energy samples
    taken a few steps apart are correlated, and the plain least-squares error would then
    call a drift resolved that is noise (Santer et al., J. Geophys. Res. 105, 7337 (2000)).
    SE = √(Σ e² / (n_eff − 2) / Σ (t − t̄)²); infinite when n_eff ≤ 2, NaN for n < 3.

    Raises
    ------
    ValueError
        If times and values differ in length, or a value is not finite.
    """
    t = np.asarray(times_ps, dtype=float)
    y = np.asarray(values, dtype=float)
    if t.shape != y.shape or t.ndim != 1:
        raise InputError(f"times and values must be 1-d of the same length, got {t.shape} and {y.shape}.")
    if not np.all(np.isfinite(y)):
        raise InputError("the energies contain NaN or infinity: the run blew up; no drift can be fitted.")
    n = t.size
    if n < 2:
        nan = float("nan")
        return DriftFit(nan, nan, nan, nan, nan, n)
    dt = t - t.mean()
    s_tt = float(np.dot(dt, dt))
    slope_per_ps = float(np.dot(dt, y - y.mean()) / s_tt)
    intercept = float(y.mean() - slope_per_ps * t.mean())
    e = y - (intercept + slope_per_ps * t)
    sum_squares = float(np.dot(e, e))
    rho = float(np.dot(e[:-1], e[1:]) / sum_squares) if sum_squares > 0 else 0.0
    rho = min(max(rho, 0.0), 1.0 - 1e-12)
    n_eff = n * (1.0 - rho) / (1.0 + rho)
    if n < 3:
        error = float("nan")
    elif n_eff <= 2.0:
        error = float("inf")
    else:
        error = float(np.sqrt(sum_squares / (n_eff - 2.0) / s_tt)) * 1000.0
    return DriftFit(slope_per_ps * 1000.0, error, intercept, rms(e), rho, n)


def block_drift(times_ps: np.ndarray, values: np.ndarray, blocks: int = 10) -> DriftFit:
    """Fit the drift through the means of ``blocks`` contiguous blocks of H − E_ref; its SE from them.

    The samples are cut into ``blocks`` blocks of equal length (a remainder at the end
    is left out); a least-squares line is fitted through the block means at the block
    mean times, and the standard error of its slope is the ordinary least-squares one
    of those ``blocks`` points (``blocks − 2`` degrees of freedom). Blocks long compared
    with the correlation time of the energy are independent samples where the energies
    themselves are not, so this error needs no correlation model (:func:`fit_drift`
    widens the per-sample error with the lag-1 correlation instead). The slope is in
    kJ/mol/ns (per ns: times in ps); ``lag1_correlation`` is that of the block means
    about the line.

    Raises
    ------
    ValueError
        For fewer than 3 blocks, fewer samples than blocks, or a value that is not finite.

    Examples
    --------
    A steady drift of 2 kJ/mol/ns under noise, 1 ns sampled every ps:

    >>> import numpy as np
    >>> from openmm_alphaprk.observables import block_drift
    >>> t = np.arange(1001.0)
    >>> noise = np.random.default_rng(0).normal(0.0, 0.05, t.size)
    >>> fit = block_drift(t, 0.002 * t + noise, blocks=10)
    >>> round(fit.slope, 1), fit.samples, fit.resolved
    (2.0, 10, True)
    """
    blocks = positive_int(blocks, "blocks")
    t = np.asarray(times_ps, dtype=float)
    y = np.asarray(values, dtype=float)
    if t.shape != y.shape or t.ndim != 1:
        raise InputError(f"times and values must be 1-d of the same length, got {t.shape} and {y.shape}.")
    if blocks < 3 or t.size < blocks:
        raise InputError(
            f"a block drift needs at least 3 blocks and a sample per block; got {blocks} blocks for "
            f"{t.size} samples (sample the energy more often, or use fewer blocks)."
        )
    if not np.all(np.isfinite(y)):
        raise InputError("the energies contain NaN or infinity: the run blew up; no drift can be fitted.")
    size = t.size // blocks
    block_t = t[: size * blocks].reshape(blocks, size).mean(axis=1)
    block_y = y[: size * blocks].reshape(blocks, size).mean(axis=1)
    dt = block_t - block_t.mean()
    s_tt = float(np.dot(dt, dt))
    slope_per_ps = float(np.dot(dt, block_y - block_y.mean()) / s_tt)
    intercept = float(block_y.mean() - slope_per_ps * block_t.mean())
    e = block_y - (intercept + slope_per_ps * block_t)
    sum_squares = float(np.dot(e, e))
    rho = float(np.dot(e[:-1], e[1:]) / sum_squares) if sum_squares > 0 else 0.0
    error = float(np.sqrt(sum_squares / (blocks - 2) / s_tt)) * 1000.0
    return DriftFit(slope_per_ps * 1000.0, error, intercept, rms(e), min(max(rho, 0.0), 1.0), blocks)


@dataclass(frozen=True)
class ResidualWindows:
    """RMS and max |H − E_ref| (kJ/mol) over consecutive windows of a run.

    Attributes
    ----------
    window_ps : float
        Length of a window (ps).
    starts_ps : numpy.ndarray
        Start time of each window (ps); the last window may be shorter.
    rms, max_abs : numpy.ndarray
        RMS and max |H − E_ref| of the samples in each window.
    samples : numpy.ndarray
        Samples in each window.
    """

    window_ps: float
    starts_ps: np.ndarray
    rms: np.ndarray
    max_abs: np.ndarray
    samples: np.ndarray

    def as_dict(self) -> dict:
        return {
            "window_ps": self.window_ps,
            "starts_ps": self.starts_ps.tolist(),
            "rms": self.rms.tolist(),
            "max_abs": self.max_abs.tolist(),
            "samples": self.samples.tolist(),
        }


def residual_windows(times_ps: np.ndarray, residuals: np.ndarray, window_ps: float) -> ResidualWindows:
    """Cut a trace of H − E_ref into windows of ``window_ps`` and give each one's RMS and max.

    Windows start at the first sample's time t₀ and follow each other without overlap;
    window k holds the samples with t₀ + k·window < t ≤ t₀ + (k + 1)·window (to 1e-6 of a
    window: OpenMM's time accumulates round-off). The first sample (the start
    state, H − E_ref = 0 by definition) is left out, as in :func:`residual_statistics`.

    Raises
    ------
    ValueError
        For a window that is not positive, or times and residuals of different lengths.

    Examples
    --------
    >>> from openmm_alphaprk.observables import residual_windows
    >>> windows = residual_windows([0, 1, 2, 3, 4, 5], [0.0, 0.1, -0.1, 0.3, -0.4, 0.2], window_ps=2.5)
    >>> windows.starts_ps.tolist(), windows.samples.tolist()
    ([0.0, 2.5], [2, 3])
    >>> [round(float(x), 3) for x in windows.max_abs]
    [0.1, 0.4]
    >>> [round(float(x), 3) for x in windows.rms]  # √((0.01 + 0.01)/2), √((0.09 + 0.16 + 0.04)/3)
    [0.1, 0.311]
    """
    window = float(window_ps)
    if not window > 0 or not math.isfinite(window):
        raise InputError(f"window_ps must be a positive number of ps, got {window_ps!r}.")
    t = np.asarray(times_ps, dtype=float)
    y = np.asarray(residuals, dtype=float)
    if t.shape != y.shape or t.ndim != 1:
        raise InputError(f"times and residuals must be 1-d of the same length, got {t.shape} and {y.shape}.")
    if t.size < 2:
        empty = np.array([])
        return ResidualWindows(window, empty, empty, empty, empty.astype(int))
    # a time within 1e-6 of a window of a boundary is on it (OpenMM's time accumulates round-off)
    index = np.maximum(np.ceil((t[1:] - t[0]) / window - 1e-6).astype(int) - 1, 0)
    count = int(index.max()) + 1
    samples = np.bincount(index, minlength=count)
    squares = np.bincount(index, weights=np.square(y[1:]), minlength=count)
    kept = samples > 0
    largest = np.zeros(count)
    np.maximum.at(largest, index, np.abs(y[1:]))
    starts = t[0] + window * np.arange(count)
    return ResidualWindows(
        window,
        starts[kept],
        np.sqrt(squares[kept] / samples[kept]),
        largest[kept],
        samples[kept],
    )


def drift_text(drift: float, standard_error: float, unit: str = "") -> str:
    """Return a drift as printed everywhere: ``-0.043 ± 0.011 kJ/mol/ns`` or ``not resolved (±0.011 …)``.

    A drift smaller than :data:`DRIFT_RESOLVED_AT` standard errors is not shown as a
    number: the run is too short (or too noisy) to tell it from zero.
    """
    suffix = f" {unit}" if unit else ""
    if not np.isfinite(standard_error):
        reason = "too few samples" if np.isnan(standard_error) else "samples too correlated"
        return f"not resolved ({reason})"
    if abs(drift) < DRIFT_RESOLVED_AT * standard_error:
        return f"not resolved (±{standard_error:.2g}{suffix})"
    return f"{drift:+.3g} ± {standard_error:.2g}{suffix}"


@dataclass
class EnergyDrift:
    """H − E_ref of a run's energy samples: E_ref, the drift fit, RMS and max (kJ/mol, ps, ns).

    E_ref is the total energy of the first sample, the start state. RMS and max
    |H − E_ref| are over the samples after the first (:func:`residual_statistics`).

    Attributes
    ----------
    e_ref : float
        Total energy of the first sample (kJ/mol).
    samples : int
        Number of samples, the first included.
    duration_ps : float
        Time from the first sample to the last (ps).
    drift_kj_per_mol_per_ns, drift_standard_error_kj_per_mol_per_ns : float
        Slope of the line fitted to H − E_ref (:func:`fit_drift`) and its standard error.
    drift_per_dof, drift_per_dof_standard_error : float
        The same per degree of freedom (kJ/mol/ns).
    drift_resolved : bool
        Whether |drift| is at least :data:`DRIFT_RESOLVED_AT` standard errors.
    scatter_about_fit : float
        RMS of the samples about the line (kJ/mol).
    rms_residual, max_abs_residual : float
        RMS and max |H − E_ref| after the first sample (kJ/mol).

    Examples
    --------
    Made by :func:`energy_drift`:

    >>> from openmm_alphaprk.analysis import energy_drift
    >>> drift = energy_drift([0.0, 1.0, 2.0, 3.0], [-100.0, -99.9, -99.8, -99.7], dof=10)
    >>> drift.e_ref, drift.samples, drift.duration_ps
    (-100.0, 4, 3.0)
    >>> round(drift.drift_kj_per_mol_per_ns, 6), round(drift.drift_per_dof, 6)
    (100.0, 10.0)
    >>> sorted(drift.as_dict())[:2]
    ['drift_kj_per_mol_per_ns', 'drift_per_dof']
    """

    e_ref: float
    samples: int
    duration_ps: float
    drift_kj_per_mol_per_ns: float
    drift_standard_error_kj_per_mol_per_ns: float
    drift_per_dof: float  # kJ/mol/ns per degree of freedom
    drift_per_dof_standard_error: float
    drift_resolved: bool
    scatter_about_fit: float
    rms_residual: float
    max_abs_residual: float

    def as_dict(self) -> dict:
        return asdict(self)


def energy_drift(times_ps: np.ndarray, total_energies: np.ndarray, dof: int) -> EnergyDrift:
    """E_ref, drift (:func:`fit_drift`), RMS and max |H − E_ref| of energy samples.

    Parameters
    ----------
    times_ps : array_like of float
        Sample times (ps).
    total_energies : array_like of float
        Total energies (kJ/mol); the first is E_ref (the start state). A trace of
        H − E_ref that starts at 0 gives the same result.
    dof : int
        Degrees of freedom, for the drift per degree of freedom.

    Returns
    -------
    EnergyDrift

    Raises
    ------
    ValueError
        With fewer than two samples, or a value that is not finite.

    Examples
    --------
    The ``energies.csv`` of a short RATTLE run (columns: step, time, potential, kinetic,
    total, temperature):

    >>> import os, tempfile
    >>> from openmm_alphaprk.analysis import energy_drift
    >>> from openmm_alphaprk.runs import read_energies, run_nve
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     run = os.path.join(folder, "run")
    ...     summary = run_nve("water-cluster", "rattle", run, steps=20, energy_interval=5,
    ...                       platform="Reference", progress=False)
    ...     energies = read_energies(os.path.join(run, "energies.csv"))
    >>> drift = energy_drift(energies[:, 1], energies[:, 4], summary.degrees_of_freedom)
    >>> drift.samples, round(drift.duration_ps, 6)
    (5, 0.04)
    >>> drift.rms_residual == summary.rms_residual  # the run's summary is this fit
    True
    """
    times_ps = np.asarray(times_ps, dtype=float)
    total = np.asarray(total_energies, dtype=float)
    if len(total) < 2:
        raise InputError("need at least two energy samples to fit a drift.")
    residual = total - total[0]
    fit = fit_drift(times_ps, residual)
    per_dof, per_dof_error = fit.per_dof(dof)
    rms_residual, max_abs_residual = residual_statistics(residual)
    return EnergyDrift(
        e_ref=float(total[0]),
        samples=len(total),
        duration_ps=float(times_ps[-1] - times_ps[0]),
        drift_kj_per_mol_per_ns=fit.slope,
        drift_standard_error_kj_per_mol_per_ns=fit.standard_error,
        drift_per_dof=per_dof,
        drift_per_dof_standard_error=per_dof_error,
        drift_resolved=fit.resolved,
        scatter_about_fit=fit.scatter,
        rms_residual=rms_residual,
        max_abs_residual=max_abs_residual,
    )


def masses(system: mm.System) -> np.ndarray:
    """Particle masses (amu), shape (N,)."""
    return np.array(
        [system.getParticleMass(i).value_in_unit(unit.dalton) for i in range(system.getNumParticles())]
    )


def system_constraints(system: mm.System) -> tuple[np.ndarray, np.ndarray]:
    """Constrained pairs (k, 2) and their lengths (nm) from an OpenMM System.

    Parameters
    ----------
    system : openmm.System
        The System.

    Returns
    -------
    pairs : numpy.ndarray
        (k, 2) atom indices.
    lengths : numpy.ndarray
        (k,) lengths in nm.

    Examples
    --------
    >>> from openmm_alphaprk.analysis import system_constraints
    >>> from openmm_alphaprk.systems import prepare_system
    >>> pairs, lengths = system_constraints(prepare_system("water-cluster").system)
    >>> pairs.shape, pairs[:2].tolist()  # three per rigid water, the first its two O-H
    ((222, 2), [[0, 1], [0, 2]])
    >>> sorted(set(lengths.round(5).tolist()))  # TIP3P's O-H and H-H distances
    [0.09572, 0.15139]
    """
    n = system.getNumConstraints()
    pairs = np.empty((n, 2), dtype=np.intp)
    lengths = np.empty(n)
    for k in range(n):
        i, j, d = system.getConstraintParameters(k)
        pairs[k] = i, j
        lengths[k] = d.value_in_unit(unit.nanometers)
    return pairs, lengths


def constraint_errors(
    pairs: np.ndarray, lengths: np.ndarray, x: np.ndarray, v: np.ndarray
) -> tuple[float, float]:
    """Max relative bond-length error |r − d|/d and max |relative velocity along the bond| (nm/ps).

    ``x`` in nm and ``v`` in nm/ps, shape (N, 3); no minimum image (constrained pairs
    are within one molecule, which OpenMM keeps whole). (0, 0) without constraints.
    """
    if len(pairs) == 0:
        return 0.0, 0.0
    r = x[pairs[:, 1]] - x[pairs[:, 0]]
    norm = np.linalg.norm(r, axis=1)
    dv = v[pairs[:, 1]] - v[pairs[:, 0]]
    return (
        float(np.max(np.abs(norm - lengths) / lengths)),
        float(np.max(np.abs(np.einsum("ij,ij->i", dv, r)) / norm)),
    )


def system_constraint_errors(system: mm.System, x: np.ndarray, v: np.ndarray) -> tuple[float, float]:
    """:func:`constraint_errors` for the constraints of ``system``."""
    return constraint_errors(*system_constraints(system), x, v)


def momenta(particle_masses: np.ndarray, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Total linear (amu nm/ps) and angular momentum about the origin (amu nm²/ps)."""
    m = np.asarray(particle_masses)[:, None]
    return (m * v).sum(0), (m * np.cross(x, v)).sum(0)


def trajectory_error(
    values: np.ndarray, reference: np.ndarray, box: np.ndarray | None = None
) -> tuple[float, float]:
    """RMS over atoms and maximum of |values − reference| per atom (positions in nm or velocities in nm/ps).

    ``values`` and ``reference`` have shape (N, 3). With ``box`` (the edge lengths of a
    rectangular periodic box, nm) a position difference is taken by the minimum image,
    so that an atom wrapped into the box by one run and not the other counts by how far
    it is from the reference, not by a box length.
    """
    difference = np.asarray(values, dtype=float) - np.asarray(reference, dtype=float)
    if box is not None:
        edges = np.asarray(box, dtype=float)
        difference -= edges * np.round(difference / edges)
    per_atom = np.linalg.norm(difference, axis=1)
    return float(np.sqrt(np.mean(per_atom**2))), float(np.max(per_atom))


def block_average(values: np.ndarray, blocks: int) -> tuple[float, float]:
    """Mean of ``values`` and its standard error from ``blocks`` contiguous block means.

    SE = std(block means, ddof=1)/√blocks: blocks long compared with the correlation time
    of the series are independent samples, where the samples themselves are not. A
    remainder of ``len(values) % blocks`` samples at the end is left out.

    Raises
    ------
    ValueError
        For fewer than two blocks, or fewer samples than blocks.
    """
    values = np.asarray(values, dtype=float)
    blocks = positive_int(blocks, "blocks")
    if blocks < 2 or values.size < blocks:
        raise InputError(
            f"a block average needs at least 2 blocks and a sample per block; got {blocks} "
            f"blocks for {values.size} samples."
        )
    size = values.size // blocks
    means = values[: size * blocks].reshape(blocks, size).mean(axis=1)
    return float(means.mean()), float(means.std(ddof=1) / math.sqrt(blocks))


#: Boltzmann's constant in kJ/mol/K.
BOLTZMANN = (unit.MOLAR_GAS_CONSTANT_R).value_in_unit(unit.kilojoules_per_mole / unit.kelvin)


def temperature(kinetic_energy: np.ndarray | float, dof: int) -> np.ndarray | float:
    """Kinetic temperature (K) of a kinetic energy (kJ/mol) over ``dof`` degrees of freedom: 2K/(dof k_B)."""
    return 2.0 * np.asarray(kinetic_energy) / (dof * BOLTZMANN)


def alpha_percentiles(alphas: np.ndarray) -> dict[str, float]:
    """α* percentiles :data:`ALPHA_PERCENTILES` as ``{"p1": …, "p99": …}``, NaN ignored (all NaN if none)."""
    alphas = np.asarray(alphas, dtype=float)
    finite = alphas[np.isfinite(alphas)]
    if finite.size == 0:
        return {f"p{p}": float("nan") for p in ALPHA_PERCENTILES}
    return {f"p{p}": float(v) for p, v in zip(ALPHA_PERCENTILES, np.percentile(finite, ALPHA_PERCENTILES))}
