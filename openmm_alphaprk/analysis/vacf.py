"""Velocity autocorrelation function and vibrational spectrum (an MDAnalysis ``AnalysisBase``).

The run driver stores velocities in ``trajectory.trr`` beside the positions; trajectories
with velocities (TRR, NetCDF) are read with ``source="velocities"``, in Å/ps as MDAnalysis
gives them. ``source="positions"`` reads files whose "positions" are velocities (a DCD
written by OpenMM's ``app.DCDFile`` handed nm/ps velocities typed as nm: Å/ps).

The frame spacing MDAnalysis reports for a DCD written by ``app.DCDFile(file, topology, dt,
firstStep, interval)`` is ``dt * interval`` in ps (OpenMM stores the step in AKMA time units
and the save interval in the header; MDAnalysis converts back), e.g. 0.004 ps for a 1 fs step
saved every 4 steps, good to single precision (~3e-9 relative).
"""

from __future__ import annotations

import numpy as np
from MDAnalysis.analysis.base import AnalysisBase
from scipy import fft as sp_fft

from .._units import InputError

#: 1 ps⁻¹ in cm⁻¹ (1 / c, with c = 0.0299792458 cm/ps).
PS_INV_IN_CM_INV = 1.0 / 0.0299792458

#: Default longest lag of the VACF and of the spectrum's transform (ps).
DEFAULT_MAX_LAG = 1.0

_SOURCES = ("positions", "velocities")


def _autocorrelation_sum(v: np.ndarray, n_lags: int, weights: np.ndarray | None, chunk: int) -> np.ndarray:
    """Sum over atoms (weighted) and components of the raw lagged products, lags 0 .. n_lags-1.

    ``v`` is (n_frames, n_atoms, 3). Returns Σ_i w_i Σ_t0 v_i(t0)·v_i(t0 + lag) (not yet
    divided by the number of origins), computed by FFT with zero padding to ≥ 2 n_frames − 1
    so that the correlation is linear, not circular.
    """
    n_frames, n_atoms, _ = v.shape
    n_fft = sp_fft.next_fast_len(2 * n_frames - 1, real=True)
    total = np.zeros(n_lags)
    for first in range(0, n_atoms, chunk):
        block = np.asarray(v[:, first : first + chunk], dtype=np.float64)
        spectrum = sp_fft.rfft(block, n=n_fft, axis=0)
        power = spectrum.real**2 + spectrum.imag**2
        if weights is not None:
            power *= weights[first : first + chunk, None]
        total += sp_fft.irfft(power.sum(axis=(1, 2)), n=n_fft)[:n_lags]
    return total


def _cosine_transform(vacf: np.ndarray, spacing: float, zero_pad: int) -> tuple[np.ndarray, np.ndarray]:
    """Hann-windowed one-sided cosine transform of ``vacf`` sampled every ``spacing`` ps.

    Returns frequencies (ps⁻¹, 0 to the Nyquist frequency) and
    S(ν) = Δt [w₀C₀ + 2 Σ_{j≥1} w_j C_j cos(2π ν j Δt)], w_j = ½ (1 + cos(π j / (n − 1))).
    """
    n = len(vacf)
    window = 0.5 * (1.0 + np.cos(np.pi * np.arange(n) / (n - 1)))
    windowed = vacf * window
    n_fft = 2 * sp_fft.next_fast_len(max(zero_pad, 1) * n, real=True)  # even: the grid ends at Nyquist
    transform = sp_fft.rfft(windowed, n=n_fft).real
    spectrum = spacing * (2.0 * transform - windowed[0])
    frequencies = sp_fft.rfftfreq(n_fft, d=spacing)
    return frequencies, spectrum


def _trapezoid_weights(x: np.ndarray) -> np.ndarray:
    """Per-point weights w with Σ w f = trapezoid(f, x) for any f on the (sorted) grid x."""
    x = np.asarray(x, dtype=float)
    w = np.zeros_like(x)
    if len(x) > 1:
        dx = np.diff(x)
        w[:-1] += 0.5 * dx
        w[1:] += 0.5 * dx
    return w


class VelocityAutocorrelation(AnalysisBase):
    """Velocity autocorrelation function (VACF) of a selection and its vibrational spectrum.

    C(t) = ⟨v_i(t₀)·v_i(t₀ + t)⟩, averaged over the selected atoms and over all time origins
    t₀ (FFT, Wiener–Khinchin, zero padded; each lag divided by its own number of origins,
    n_frames − lag, i.e. unbiased). The spectrum (vibrational density of states) is the
    Hann-windowed cosine transform of C(t) up to ``max_lag``, normalized to unit area over
    wavenumber. Its resolution is set by ``max_lag``: independent points are 1/(2 max_lag)
    apart (16.7 cm⁻¹ for 1 ps), and the Hann window widens a line to a FWHM of ≈ 0.72/max_lag
    (24 cm⁻¹ for 1 ps).

    The selection's velocities are held in memory as float32, n_frames × n_atoms × 3
    (12 bytes per atom and frame).

    Parameters
    ----------
    universe : MDAnalysis.Universe or MDAnalysis.AtomGroup
        Universe or AtomGroup; ``select`` is applied to it.
    select : str, default "all"
        Atoms to follow, e.g. ``"name H*"`` for water hydrogens (libration band).
    source : {"positions", "velocities"}, default "positions"
        ``"positions"``: the frame's positions are velocities in Å/ps (velocities stored as
        DCD coordinates); ``"velocities"``: the trajectory's own velocities (Å/ps), e.g.
        the run driver's ``trajectory.trr``.
    dt : float, optional
        Time between consecutive trajectory frames in ps; default the trajectory's
        ``dt``. With ``run(step=k)`` the analysed frames are ``k * dt`` apart.
    max_lag : float, optional
        Longest lag (ps) of the VACF kept and transformed; default the shorter of 1 ps
        and half the analysed time span. Must not exceed the analysed time span.
    mass_weighted : bool, default False
        Average the atoms' autocorrelations with their masses as weights
        (Σ m_i C_i / Σ m_i, still in Å²/ps²) instead of uniformly.
    zero_pad : int, default 4
        Zero padding factor of the cosine transform (finer frequency grid, same
        resolution).
    **kwargs
        Passed on to ``AnalysisBase`` (e.g. ``verbose``).

    Attributes
    ----------
    results.lags : numpy.ndarray
        Lag times (ps), 0 to ``max_lag``.
    results.vacf : numpy.ndarray
        C(t) in Å²/ps²; C(0) = ⟨|v|²⟩.
    results.normalized_vacf : numpy.ndarray
        C(t) / C(0).
    results.n_origins : numpy.ndarray
        Time origins averaged at each lag (n_frames − lag index).
    results.frequencies : numpy.ndarray
        Wavenumbers (cm⁻¹) of the spectrum, 0 to the Nyquist frequency.
    results.spectrum : numpy.ndarray
        Vibrational spectrum in 1/cm⁻¹, unit area over ``results.frequencies``. Window
        side lobes can make it slightly negative far from the bands.
    results.frequency_resolution : float
        1 / (2 max_lag) in cm⁻¹.
    results.dt : float
        Time between analysed frames (ps).
    results.max_lag : float
        The longest lag used (ps).

    Examples
    --------
    The water hydrogens of the 2 nm box, velocities written every step of a short
    RATTLE run (40 fs: a spectrum needs picoseconds; this shows the call):

    >>> import os, tempfile
    >>> from openmm_alphaprk.analysis import VelocityAutocorrelation
    >>> from openmm_alphaprk.runs import run_nve
    >>> from openmm_alphaprk.runs.rundir import open_universe
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     run = os.path.join(folder, "run")
    ...     _ = run_nve("tip3p-2nm", "rattle", run, steps=20, velocity_interval=1, progress=False)
    ...     frames = open_universe(run, "trajectory.trr")  # positions and velocities
    ...     vacf = VelocityAutocorrelation(frames, select="name H*", source="velocities").run()
    >>> round(vacf.results.dt, 6), round(vacf.results.max_lag, 6)  # ps: half the 20 frames' span
    (0.002, 0.018)
    >>> float(vacf.results.normalized_vacf[0]), vacf.results.n_origins[:3].tolist()
    (1.0, [20, 19, 18])
    >>> round(vacf.results.frequency_resolution)  # cm⁻¹: 1/(2 max_lag), coarse for so short a lag
    927
    """

    def __init__(
        self,
        universe,
        select: str = "all",
        source: str = "positions",
        dt: float | None = None,
        max_lag: float | None = None,
        mass_weighted: bool = False,
        *,
        zero_pad: int = 4,
        **kwargs,
    ):
        super().__init__(universe.universe.trajectory, **kwargs)
        if source not in _SOURCES:
            raise InputError(
                f"unknown source {source!r}: use 'positions' (velocities stored as positions, "
                "as DCD coordinates) or 'velocities' (a trajectory with velocities, e.g. TRR)."
            )
        if dt is not None and not dt > 0:
            raise InputError(f"dt must be a positive time between frames in ps, got {dt}.")
        if max_lag is not None and not max_lag > 0:
            raise InputError(f"max_lag must be a positive time in ps, got {max_lag}.")
        if int(zero_pad) < 1:
            raise InputError(f"zero_pad must be a positive integer, got {zero_pad}.")
        self._atoms = universe.select_atoms(select)
        if len(self._atoms) == 0:
            raise InputError(f"selection {select!r} matches no atoms; check the atom names (e.g. 'name H*').")
        self._weights = None
        if mass_weighted:
            try:
                masses = np.asarray(self._atoms.masses, dtype=float)
            except AttributeError:
                masses = np.zeros(len(self._atoms))
            if not np.all(masses > 0):
                raise InputError(
                    "mass_weighted=True needs positive masses for all selected atoms; load a topology "
                    "with elements or masses (e.g. the PDB), or use mass_weighted=False."
                )
            self._weights = masses / masses.mean()
        self._source = source
        self._dt = None if dt is None else float(dt)
        self._max_lag = None if max_lag is None else float(max_lag)
        self._zero_pad = int(zero_pad)

    def _trajectory_dt(self) -> float:
        dt = self._dt if self._dt is not None else float(self._trajectory.dt)
        if not dt > 0:
            raise InputError(
                f"the trajectory reports a time step of {dt} ps between frames; pass dt=<ps between "
                "frames> to VelocityAutocorrelation."
            )
        return dt

    def _resolve_max_lag(self, spacing: float) -> float:
        span = (self.n_frames - 1) * spacing
        if self._max_lag is None:
            return min(DEFAULT_MAX_LAG, 0.5 * span)
        if self._max_lag > span * (1 + 1e-9):
            raise InputError(
                f"max_lag = {self._max_lag} ps is longer than the analysed trajectory "
                f"({self.n_frames} frames, {span:.6g} ps); pass a shorter max_lag or more frames."
            )
        if self._max_lag < spacing * (1 - 1e-9):
            raise InputError(
                f"max_lag = {self._max_lag} ps is shorter than the time between frames ({spacing:.6g} ps)."
            )
        return self._max_lag

    def _prepare(self):
        if self.n_frames < 3:
            raise InputError(
                f"{self.n_frames} frame(s) to analyse; a VACF needs at least 3 (write velocities more "
                "often or run longer)."
            )
        if self._source == "velocities" and not self._trajectory.ts.has_velocities:
            raise InputError(
                "source='velocities' but the trajectory has no velocities; for velocities stored as "
                "positions use source='positions'; a run writes velocities with --velocity-interval N."
            )
        dt = self._trajectory_dt()
        # start/stop/step slicing: check max_lag before reading the frames.
        if getattr(self, "step", None) is not None:
            self._resolve_max_lag(dt * self.step)
        self._velocities = np.zeros((self.n_frames, len(self._atoms), 3), dtype=np.float32)

    def _single_frame(self):
        if self._source == "positions":
            self._velocities[self._frame_index] = self._atoms.positions
        else:
            self._velocities[self._frame_index] = self._atoms.velocities

    def _conclude(self):
        steps = np.diff(self.frames)
        if len(steps) == 0 or np.any(steps != steps[0]) or steps[0] <= 0:
            raise InputError("the analysed frames must be evenly spaced (use start/stop/step, not frames=).")
        spacing = self._trajectory_dt() * int(steps[0])
        max_lag = self._resolve_max_lag(spacing)
        n_lags = int(np.floor(max_lag / spacing + 1e-6)) + 1

        chunk = max(1, 2_000_000 // (3 * (2 * self.n_frames)))
        raw = _autocorrelation_sum(self._velocities, n_lags, self._weights, chunk)
        n_origins = self.n_frames - np.arange(n_lags)
        vacf = raw / (n_origins * len(self._atoms))

        frequencies, spectrum = _cosine_transform(vacf, spacing, self._zero_pad)
        frequencies = frequencies * PS_INV_IN_CM_INV
        area = float((_trapezoid_weights(frequencies) * spectrum).sum())

        self.results.lags = np.arange(n_lags) * spacing
        self.results.vacf = vacf
        self.results.normalized_vacf = vacf / vacf[0] if vacf[0] > 0 else np.full(n_lags, np.nan)
        self.results.n_origins = n_origins
        self.results.frequencies = frequencies
        self.results.spectrum = spectrum / area if area > 0 else np.full_like(spectrum, np.nan)
        self.results.frequency_resolution = PS_INV_IN_CM_INV / (2.0 * (n_lags - 1) * spacing)
        self.results.dt = spacing
        self.results.max_lag = (n_lags - 1) * spacing


def _band_mask(frequencies: np.ndarray, low: float | None, high: float | None) -> np.ndarray:
    lo = -np.inf if low is None else low
    hi = np.inf if high is None else high
    if lo >= hi:
        raise InputError(f"need low < high, got {low}, {high}.")
    return (frequencies >= lo) & (frequencies <= hi)


def band_summary(
    frequencies: np.ndarray, spectrum: np.ndarray, low: float | None = None, high: float | None = None
) -> dict[str, float]:
    """Peak, centroid and weight of a band of a spectrum.

    Parameters
    ----------
    frequencies : array_like of float
        Wavenumbers (cm⁻¹), increasing.
    spectrum : array_like of float
        Spectrum on ``frequencies`` (any normalization).
    low, high : float, optional
        Band limits in cm⁻¹ (inclusive); ``None`` for no limit.

    Returns
    -------
    dict
        ``peak`` (cm⁻¹ of the band's maximum), ``centroid`` (cm⁻¹, ∫ν S / ∫S over the band)
        and ``weight`` (the band's fraction of the total area; bands that tile the axis
        add up to 1).

    Raises
    ------
    ValueError
        If the arrays differ in shape, ``low >= high``, or no grid point falls in the band.

    Examples
    --------
    >>> import numpy as np
    >>> from openmm_alphaprk.analysis import band_summary
    >>> wavenumbers = np.linspace(0, 4000, 801)  # cm⁻¹
    >>> def band(centre, width):
    ...     return np.exp(-(((wavenumbers - centre) / width) ** 2))
    >>> spectrum = band(1650, 50) + 2 * band(3400, 100)  # a bend and a stretch band
    >>> bend = band_summary(wavenumbers, spectrum, low=1000, high=2500)
    >>> bend["peak"], round(bend["centroid"], 6), round(bend["weight"], 6)
    (1650.0, 1650.0, 0.2)
    >>> round(band_summary(wavenumbers, spectrum, low=2500)["weight"], 6)  # the two tile the axis
    0.8
    """
    frequencies = np.asarray(frequencies, dtype=float)
    spectrum = np.asarray(spectrum, dtype=float)
    if frequencies.shape != spectrum.shape or frequencies.ndim != 1:
        raise InputError(f"frequencies {frequencies.shape} and spectrum {spectrum.shape} must be equal 1-D.")
    mask = _band_mask(frequencies, low, high)
    if not mask.any():
        raise InputError(
            f"no frequency in the band [{low}, {high}] cm⁻¹ "
            f"(grid {frequencies[0]:.4g}–{frequencies[-1]:.4g})."
        )
    # Per-point trapezoid weights of the whole axis, so that adjacent bands add up.
    weights = _trapezoid_weights(frequencies) * spectrum
    band_area = weights[mask].sum()
    total = weights.sum()
    band_freqs = frequencies[mask]
    return {
        "peak": float(band_freqs[np.argmax(spectrum[mask])]),
        "centroid": float((weights[mask] * band_freqs).sum() / band_area) if band_area else float("nan"),
        "weight": float(band_area / total) if total else float("nan"),
    }


def spectrum_difference(
    freq: np.ndarray,
    spec: np.ndarray,
    freq_ref: np.ndarray,
    spec_ref: np.ndarray,
    low: float | None = None,
    high: float | None = None,
) -> float:
    """Half the L1 distance between the shapes of two spectra over a band.

    Both spectra are clipped at zero (window side lobes), interpolated linearly onto the
    union of the two grids within the band, and normalized to unit area there; the result
    is ½ ∫|S − S_ref| dν: 0 for identical shapes, 1 for disjoint ones. Symmetric.

    Parameters
    ----------
    freq, spec : array_like of float
        Wavenumbers (cm⁻¹, increasing) and spectrum of the run.
    freq_ref, spec_ref : array_like of float
        The same for the reference.
    low, high : float, optional
        Band limits in cm⁻¹; ``None``: where both grids overlap.

    Returns
    -------
    float
        The distance, between 0 and 1.

    Raises
    ------
    ValueError
        If the band holds no grid point or either spectrum has no positive area in it.

    Examples
    --------
    >>> import numpy as np
    >>> from openmm_alphaprk.analysis import spectrum_difference
    >>> wavenumbers = np.linspace(0, 4000, 801)  # cm⁻¹
    >>> def band(centre, width):
    ...     return np.exp(-(((wavenumbers - centre) / width) ** 2))
    >>> spectrum = band(1650, 50) + 2 * band(3400, 100)  # a bend and a stretch band
    >>> shifted = band(1650, 50) + 2 * band(3450, 100)  # the stretch 50 cm⁻¹ higher
    >>> spectrum_difference(wavenumbers, spectrum, wavenumbers, spectrum)
    0.0
    >>> round(spectrum_difference(wavenumbers, spectrum, wavenumbers, shifted), 3)
    0.221
    >>> round(spectrum_difference(wavenumbers, spectrum, wavenumbers, shifted, low=1000, high=2500), 6)
    0.0
    """
    freq, spec = np.asarray(freq, dtype=float), np.asarray(spec, dtype=float)
    freq_ref, spec_ref = np.asarray(freq_ref, dtype=float), np.asarray(spec_ref, dtype=float)
    for f, s, name in ((freq, spec, "spec"), (freq_ref, spec_ref, "spec_ref")):
        if f.shape != s.shape or f.ndim != 1:
            raise InputError(f"{name} and its frequencies must be equal 1-D arrays ({f.shape}, {s.shape}).")
    lo = max(freq[0], freq_ref[0]) if low is None else max(low, freq[0], freq_ref[0])
    hi = min(freq[-1], freq_ref[-1]) if high is None else min(high, freq[-1], freq_ref[-1])
    grid = np.union1d(freq, freq_ref)
    grid = grid[_band_mask(grid, lo, hi)]
    if len(grid) < 2:
        raise InputError(f"the band [{low}, {high}] cm⁻¹ holds fewer than 2 points of the two grids.")
    a = np.clip(np.interp(grid, freq, spec), 0.0, None)
    b = np.clip(np.interp(grid, freq_ref, spec_ref), 0.0, None)
    w = _trapezoid_weights(grid)
    area_a, area_b = (w * a).sum(), (w * b).sum()
    if not (area_a > 0 and area_b > 0):
        raise InputError(f"a spectrum has no positive area in the band [{lo:.4g}, {hi:.4g}] cm⁻¹.")
    return float(0.5 * (w * np.abs(a / area_a - b / area_b)).sum())
