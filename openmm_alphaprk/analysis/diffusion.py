"""Mean-squared displacement and self-diffusion coefficient (MDAnalysis' ``EinsteinMSD`` + a fit)."""

from __future__ import annotations

import numpy as np
from MDAnalysis.analysis.msd import EinsteinMSD

from .._units import InputError

#: 1 Å²/ps in 1e-5 cm²/s (the unit diffusion coefficients of water are quoted in).
ANGSTROM2_PER_PS_IN_1E5_CM2_PER_S = 10.0


class Diffusion(EinsteinMSD):
    """Einstein MSD of a selection and D from a linear fit, MSD = 2 d D t.

    Needs unwrapped coordinates (this package's DCD files are written unwrapped).

    Parameters
    ----------
    universe : MDAnalysis.Universe
        The Universe.
    select : str, default "all"
        Atoms to follow (e.g. water oxygens, ``"resname HOH and name O"``).
    msd_type : str, default "xyz"
        Dimensions (``"xyz"``: d = 3).
    fit_start, fit_stop : float
        Fit window as fractions of the longest lag time (defaults 0.1, 0.6: past the
        ballistic start, before the noisy long lags).
    error_groups : int, default 4
        The standard error of D is the spread of D over this many disjoint groups of
        the selected atoms (every ``error_groups``-th atom), divided by √groups
        (at most the number of atoms).
    fft : bool, default False
        Passed on to ``EinsteinMSD``; ``True`` needs the ``tidynamics`` package.
    **kwargs
        Passed on to ``EinsteinMSD``.

    Attributes
    ----------
    results.timeseries, results.delta_t_values : numpy.ndarray
        MSD (Å²) against lag time (ps), from ``EinsteinMSD``.
    results.slope : float
        Fitted slope (Å²/ps).
    results.diffusion_coefficient : float
        D in 1e-5 cm²/s.
    results.diffusion_coefficient_standard_error : float
        Standard error of D (1e-5 cm²/s) from the groups; NaN with fewer than two
        groups. It measures the spread between molecules, not the error of a short run's
        unconverged MSD.
    results.error_groups : int
        The number of groups it was taken over.
    results.frames : int
        Frames analysed.
    results.fit_window : tuple of (float, float)
        Lag times (ps) of the first and last fitted point.

    Examples
    --------
    The water oxygens of the 2 nm box over a short RATTLE run (40 fs: far too short
    for a diffusion coefficient, long enough to show the call):

    >>> import os, tempfile
    >>> from openmm_alphaprk.runs import run_nve
    >>> from openmm_alphaprk.runs.rundir import open_universe
    >>> folder = tempfile.TemporaryDirectory()
    >>> run = os.path.join(folder.name, "run")
    >>> _ = run_nve("tip3p-2nm", "rattle", run, steps=20, trajectory_interval=2, progress=False)
    >>> universe = open_universe(run)  # topology.pdb and trajectory.dcd: 10 frames
    >>> from openmm_alphaprk.analysis import WATER_OXYGENS, Diffusion
    >>> msd = Diffusion(universe, select=WATER_OXYGENS).run()
    >>> msd.results.frames, msd.results.error_groups, len(msd.results.timeseries)
    (10, 4, 10)
    >>> [round(lag, 3) for lag in msd.results.fit_window]  # ps: 0.1 and 0.6 of the longest lag
    [0.004, 0.02]
    >>> bool(msd.results.diffusion_coefficient > 0)  # 1e-5 cm²/s
    True
    >>> folder.cleanup()
    """

    def __init__(
        self,
        universe,
        select: str = "all",
        msd_type: str = "xyz",
        *,
        fit_start: float = 0.1,
        fit_stop: float = 0.6,
        error_groups: int = 4,
        fft: bool = False,
        **kwargs,
    ):
        if not 0.0 <= fit_start < fit_stop <= 1.0:
            raise InputError(f"need 0 <= fit_start < fit_stop <= 1, got {fit_start}, {fit_stop}.")
        super().__init__(universe, select=select, msd_type=msd_type, fft=fft, **kwargs)
        if self.n_particles == 0:
            raise InputError(f"selection {select!r} matches no atoms.")
        self._fit = (fit_start, fit_stop)
        self._groups = max(1, min(int(error_groups), self.n_particles))

    def _conclude(self):
        super()._conclude()
        lags = self.results.delta_t_values
        longest = lags[-1] if len(lags) else 0.0
        window = (lags >= self._fit[0] * longest) & (lags <= self._fit[1] * longest) & (lags > 0)
        if window.sum() < 2:
            window = lags > 0
        by_particle = self.results.msds_by_particle
        groups = [by_particle[:, g :: self._groups].mean(axis=1) for g in range(self._groups)]
        self.results.slope = self._slope(lags, self.results.timeseries, window)
        self.results.fit_window = (
            (float(lags[window][0]), float(lags[window][-1])) if window.sum() >= 2 else (np.nan, np.nan)
        )
        to_d = ANGSTROM2_PER_PS_IN_1E5_CM2_PER_S / (2 * self.dim_fac)
        self.results.diffusion_coefficient = self.results.slope * to_d
        group_d = np.array([self._slope(lags, msd, window) for msd in groups]) * to_d
        self.results.diffusion_coefficient_standard_error = (
            float(np.std(group_d, ddof=1) / np.sqrt(len(group_d))) if len(group_d) > 1 else float("nan")
        )
        self.results.error_groups = self._groups
        self.results.frames = int(self.n_frames)

    @staticmethod
    def _slope(lags: np.ndarray, msd: np.ndarray, window: np.ndarray) -> float:
        """Least-squares slope of the MSD over the fit window (Å²/ps); NaN below two points."""
        if window.sum() < 2:
            return float("nan")
        return float(np.polyfit(lags[window], msd[window], 1)[0])
