"""Reorientation of water molecules: Legendre autocorrelations of the dipole direction.

The MDAKit ``waterdynamics`` (split out of MDAnalysis 2.8; not a dependency of this
package) has ``WaterOrientationalRelaxation``, which gives the second-Legendre correlation
of the dipole (and of OH, HH) only, with a selection re-evaluated at every frame and Python
loops over molecules and origins. :class:`DipoleReorientation` gives C₁ and C₂ of all
selected molecules, averaged over every time origin by FFT, and correlation times.
"""

from __future__ import annotations

import numpy as np
from MDAnalysis.analysis.base import AnalysisBase
from MDAnalysis.lib.distances import minimize_vectors

from .._units import InputError
from .vacf import _autocorrelation_sum

#: Water molecules in topologies written by OpenMM (TIP3P, SPC/E, TIP4P-Ew, Amber's HOH).
WATER_MOLECULES = "resname HOH WAT SOL"

#: Default longest lag of the correlation functions (ps), if the trajectory is long enough.
DEFAULT_MAX_LAG = 10.0


def _correlation_time(lags: np.ndarray, c: np.ndarray, threshold: float) -> tuple[float, float]:
    """∫ C dt from 0 to where C first falls below ``threshold`` (linear interpolation), and that time.

    NaN for both if C stays at or above ``threshold`` over all lags.
    """
    below = np.flatnonzero(c < threshold)
    if len(below) == 0 or below[0] == 0:
        return float("nan"), float("nan")
    k = int(below[0])
    fraction = (c[k - 1] - threshold) / (c[k - 1] - c[k])
    crossing = lags[k - 1] + fraction * (lags[k] - lags[k - 1])
    head = float(np.sum(0.5 * (c[1:k] + c[: k - 1]) * np.diff(lags[:k])))
    return head + 0.5 * (c[k - 1] + threshold) * (crossing - lags[k - 1]), float(crossing)


def _exponential_time(
    lags: np.ndarray, c: np.ndarray, start: float, stop: float
) -> tuple[float, tuple[float, float]]:
    """τ of a least-squares fit ln C = a − t/τ over lags in [start, stop) with C > 0.

    Returns τ (ps; ``inf`` if the fitted C decays by less than 1e-6 over the window, NaN
    below three points)
    and the first and last lag fitted.
    """
    window = (lags >= start) & (lags < stop) & (c > 0)
    if window.sum() < 3:
        return float("nan"), (float("nan"), float("nan"))
    first, last = float(lags[window][0]), float(lags[window][-1])
    slope = float(np.polyfit(lags[window], np.log(c[window]), 1)[0])
    # A fitted decay below 1e-6 over the window is within the float32 directions' rounding.
    tau = -1.0 / slope if -slope * (last - first) > 1e-6 else float("inf")
    return tau, (first, last)


class DipoleReorientation(AnalysisBase):
    """Rotational correlation of water dipoles: C₁(t), C₂(t) and correlation times.

    For each molecule the dipole direction is the unit vector along the H–O–H bisector,
    u ∝ (r_H1 − r_O) + (r_H2 − r_O), the O–H vectors taken at their minimum image when the
    trajectory has a box (so molecules split across the box edge count as whole). For any
    water model with two equal H charges (TIP3P, SPC/E, TIP4P's massless M site on the
    bisector) this is the direction of the molecular dipole. Then

    C_ℓ(t) = ⟨P_ℓ(u_i(t₀)·u_i(t₀ + t))⟩, P₁(x) = x, P₂(x) = (3x² − 1)/2,

    averaged over the molecules and over all time origins t₀ (unbiased: each lag divided by
    its own number of origins). Both are computed by FFT: C₁ from the autocorrelation of u,
    C₂ from that of the tensor u⊗u (⟨(u·u′)²⟩ = Σ_ab ⟨u_a u_b u′_a u′_b⟩).

    Correlation times, in ps, two ways:

    - ``tau2`` (and ``tau1``): the integral of C₂ (C₁) from 0 to the time where it first
      falls below ``threshold`` (default 0.05, linear interpolation between frames); NaN if
      it never does within ``max_lag`` (the run is too short for this estimate). Cutting
      the integral at C = 0.05 leaves out the tail, ≈ 0.05 τ for an exponential.
    - ``tau2_fit`` (and ``tau1_fit``): τ of a single exponential, a least-squares line
      through ln C over the lags from ``fit_start`` (past the sub-100 fs librational drop of
      water) to where C falls below ``threshold`` (or ``max_lag``). It extrapolates a short
      run's decay; in liquid water C₂ is not exactly exponential, so the two differ.

    The selection's dipole directions are held in memory as float32, n_frames × n_molecules
    × 3 (12 bytes per molecule and frame).

    Parameters
    ----------
    universe : MDAnalysis.Universe or MDAnalysis.AtomGroup
        Universe or AtomGroup; ``select`` is applied to it.
    select : str, default WATER_MOLECULES
        The water molecules (whole residues): each selected residue must hold exactly one
        atom whose name begins with O and two whose names begin with H (other atoms, e.g.
        TIP4P's M site, are ignored).
    dt : float, optional
        Time between consecutive trajectory frames in ps; default the trajectory's ``dt``.
    max_lag : float, optional
        Longest lag (ps); default the shorter of 10 ps and half the analysed time span.
    threshold : float, default 0.05
        Where the correlation integrals stop, and the fit window ends.
    fit_start : float, default 0.1
        First lag (ps) of the exponential fit.
    **kwargs
        Passed on to ``AnalysisBase`` (e.g. ``verbose``).

    Attributes
    ----------
    results.lags : numpy.ndarray
        Lag times (ps), 0 to ``max_lag``.
    results.c1, results.c2 : numpy.ndarray
        C₁(t) and C₂(t) (1 at t = 0).
    results.n_origins : numpy.ndarray
        Time origins averaged at each lag.
    results.tau1, results.tau2 : float
        Integral correlation times (ps); NaN if C does not fall below ``threshold``.
    results.crossing1, results.crossing2 : float
        Where C₁, C₂ fall below ``threshold`` (ps); NaN if they do not.
    results.tau1_fit, results.tau2_fit : float
        Exponential-fit correlation times (ps); ``inf`` if the fitted C decays by less than
        1e-6 over the fit window (frozen molecules), NaN if the window holds fewer than three
        lags.
    results.fit_window1, results.fit_window2 : tuple of (float, float)
        First and last lag (ps) of each fit.
    results.threshold : float
        The threshold used.
    results.n_molecules : int
        Molecules averaged.
    results.dt : float
        Time between analysed frames (ps).
    results.max_lag : float
        The longest lag used (ps).

    Examples
    --------
    The 2 nm water box over a short RATTLE run (40 fs: far too short for τ₂ ≈ 1–2 ps;
    this shows the call):

    >>> import os, tempfile
    >>> from openmm_alphaprk.analysis import DipoleReorientation
    >>> from openmm_alphaprk.runs import run_nve
    >>> from openmm_alphaprk.runs.rundir import open_universe
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     run = os.path.join(folder, "run")
    ...     _ = run_nve("tip3p-2nm", "rattle", run, steps=20, trajectory_interval=2, progress=False)
    ...     rotation = DipoleReorientation(open_universe(run)).run()
    >>> rotation.results.n_molecules, round(rotation.results.max_lag, 6)  # ps: ≤ half of 10 frames' span
    (258, 0.016)
    >>> round(float(rotation.results.c2[0]), 6), bool(rotation.results.c2[-1] < 1.0)  # float32 directions
    (1.0, True)
    >>> import math
    >>> math.isnan(rotation.results.tau2)  # C₂ is still near 1: no integral time yet
    True
    """

    def __init__(
        self,
        universe,
        select: str = WATER_MOLECULES,
        dt: float | None = None,
        max_lag: float | None = None,
        *,
        threshold: float = 0.05,
        fit_start: float = 0.1,
        **kwargs,
    ):
        super().__init__(universe.universe.trajectory, **kwargs)
        if dt is not None and not dt > 0:
            raise InputError(f"dt must be a positive time between frames in ps, got {dt}.")
        if max_lag is not None and not max_lag > 0:
            raise InputError(f"max_lag must be a positive time in ps, got {max_lag}.")
        if not 0.0 < threshold < 1.0:
            raise InputError(f"threshold must lie between 0 and 1 (e.g. 0.05), got {threshold}.")
        if not fit_start >= 0.0:
            raise InputError(f"fit_start must be a lag time >= 0 in ps, got {fit_start}.")
        atoms = universe.select_atoms(select)
        if len(atoms) == 0:
            raise InputError(f"selection {select!r} matches no atoms; select the water residues by resname.")
        oxygens, hydrogens = [], []
        for residue in atoms.residues:
            members = residue.atoms & atoms
            o = [a.index for a in members if a.name.upper().startswith("O")]
            h = [a.index for a in members if a.name.upper().startswith("H")]
            if len(o) != 1 or len(h) != 2:
                raise InputError(
                    f"residue {residue.resname} (index {residue.resindex}) has {len(o)} atom(s) named O* and "
                    f"{len(h)} named H*; each selected residue must be one water (1 O, 2 H): "
                    "narrow the selection to the water residues."
                )
            oxygens.append(o[0])
            hydrogens.append(h)
        universe_atoms = universe.universe.atoms
        self._oxygens = universe_atoms[np.array(oxygens)]
        self._h1 = universe_atoms[np.array([h[0] for h in hydrogens])]
        self._h2 = universe_atoms[np.array([h[1] for h in hydrogens])]
        self._dt = None if dt is None else float(dt)
        self._max_lag = None if max_lag is None else float(max_lag)
        self._threshold = float(threshold)
        self._fit_start = float(fit_start)

    def _prepare(self):
        if self.n_frames < 3:
            raise InputError(
                f"{self.n_frames} frame(s) to analyse; a correlation function needs at least 3 "
                "(write the trajectory more often or run longer)."
            )
        self._directions = np.zeros((self.n_frames, len(self._oxygens), 3), dtype=np.float32)

    def _single_frame(self):
        o = self._oxygens.positions
        arms = np.concatenate([self._h1.positions - o, self._h2.positions - o])
        box = self._ts.dimensions
        if box is not None and np.all(box[:3] > 0):
            arms = minimize_vectors(arms.astype(np.float32), box)
        n = len(o)
        bisector = arms[:n].astype(np.float64) + arms[n:]
        norms = np.linalg.norm(bisector, axis=1)
        if not np.all(norms > 0):
            raise InputError(f"frame {self._ts.frame}: a water's two O–H vectors cancel (linear molecule?).")
        self._directions[self._frame_index] = bisector / norms[:, None]

    def _spacing(self) -> float:
        steps = np.diff(self.frames)
        if len(steps) == 0 or np.any(steps != steps[0]) or steps[0] <= 0:
            raise InputError("the analysed frames must be evenly spaced (use start/stop/step, not frames=).")
        dt = self._dt if self._dt is not None else float(self._trajectory.dt)
        if not dt > 0:
            raise InputError(
                f"the trajectory reports {dt} ps between frames; pass dt=<ps between frames> to "
                "DipoleReorientation."
            )
        return dt * int(steps[0])

    def _conclude(self):
        spacing = self._spacing()
        span = (self.n_frames - 1) * spacing
        if self._max_lag is None:
            max_lag = min(DEFAULT_MAX_LAG, 0.5 * span)
        elif self._max_lag > span * (1 + 1e-9):
            raise InputError(
                f"max_lag = {self._max_lag} ps is longer than the analysed trajectory ({span:.6g} ps); "
                "pass a shorter max_lag or more frames."
            )
        else:
            max_lag = self._max_lag
        n_lags = max(2, int(np.floor(max_lag / spacing + 1e-6)) + 1)
        n_molecules = self._directions.shape[1]
        chunk = max(1, 2_000_000 // (9 * 2 * self.n_frames))
        first = _autocorrelation_sum(self._directions, n_lags, None, chunk)
        second = np.zeros(n_lags)
        for start in range(0, n_molecules, chunk):
            u = self._directions[:, start : start + chunk].astype(np.float64)
            tensor = (u[..., :, None] * u[..., None, :]).reshape(self.n_frames, u.shape[1], 9)
            second += _autocorrelation_sum(tensor, n_lags, None, chunk)
        n_origins = self.n_frames - np.arange(n_lags)
        c1 = first / (n_origins * n_molecules)
        c2 = 1.5 * second / (n_origins * n_molecules) - 0.5
        lags = np.arange(n_lags) * spacing

        self.results.lags = lags
        self.results.c1 = c1
        self.results.c2 = c2
        self.results.n_origins = n_origins
        for order, c in ((1, c1), (2, c2)):
            tau, crossing = _correlation_time(lags, c, self._threshold)
            stop = crossing if np.isfinite(crossing) else np.inf
            fit, window = _exponential_time(lags, c, self._fit_start, stop)
            self.results[f"tau{order}"] = tau
            self.results[f"crossing{order}"] = crossing
            self.results[f"tau{order}_fit"] = fit
            self.results[f"fit_window{order}"] = window
        self.results.threshold = self._threshold
        self.results.n_molecules = int(n_molecules)
        self.results.dt = spacing
        self.results.max_lag = float(lags[-1])
