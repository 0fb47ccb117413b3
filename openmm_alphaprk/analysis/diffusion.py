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


#: Yeh and Hummer's constant ξ for a cubic periodic box (J. Phys. Chem. B 108 (2004) 15873,
#: Eq. 13); it is the magnitude of the cubic lattice sum of the Oseen tensor (the Madelung-like
#: constant 2.837297 of a simple cubic lattice).
YEH_HUMMER_XI = 2.837297

#: Shear viscosity of rigid TIP3P at 298 K and 1 bar, in mPa·s: 0.321 (González and Abascal,
#: J. Chem. Phys. 132 (2010) 096101, Green–Kubo). Experiment: 0.896 mPa·s. Other water models
#: differ (TIP4P: 0.494, same paper); pass their own value.
TIP3P_SHEAR_VISCOSITY_MPA_S = 0.321

_BOLTZMANN_J_PER_K = 1.380649e-23  # exact (SI 2019)
#: 1 m²/s in 1e-5 cm²/s.
_M2_PER_S_IN_1E5_CM2_PER_S = 1e9


def yeh_hummer_correction(
    temperature: object,
    box_length: object,
    viscosity: object = TIP3P_SHEAR_VISCOSITY_MPA_S,
) -> float:
    """Finite-size correction of a diffusion coefficient in a cubic periodic box, ξ k_B T / (6 π η L).

    The self-diffusion coefficient of a periodic system of edge L is smaller than the
    infinite system's by this amount (Yeh and Hummer, J. Phys. Chem. B 108 (2004) 15873:
    D₀ = D_PBC + ξ k_B T / (6 π η L), ξ = :data:`YEH_HUMMER_XI` = 2.837297).

    Parameters
    ----------
    temperature : float or openmm.unit.Quantity
        T in K (a plain number) or a temperature Quantity.
    box_length : float or openmm.unit.Quantity
        Edge L of the cubic box in nm (a plain number) or a length Quantity.
    viscosity : float or openmm.unit.Quantity, default TIP3P_SHEAR_VISCOSITY_MPA_S
        Shear viscosity η of the model in mPa·s (a plain number) or a Quantity in pressure ×
        time units (e.g. ``0.321 * unit.millipascal * unit.second``). The default is rigid
        TIP3P's at 298 K (:data:`TIP3P_SHEAR_VISCOSITY_MPA_S`); give your model's.

    Returns
    -------
    float
        The correction in 1e-5 cm²/s (the unit of :class:`Diffusion`'s results).

    Raises
    ------
    InputError
        If a value is not a positive finite number; ``InputTypeError`` if a Quantity has
        the wrong dimension.

    Examples
    --------
    A 2 nm box of TIP3P water at 298 K: the correction is about 1e-5 cm²/s, a sixth of
    the model's D (≈ 5.5e-5 cm²/s):

    >>> import openmm.unit as unit
    >>> from openmm_alphaprk.analysis import yeh_hummer_correction
    >>> round(yeh_hummer_correction(298.0, 2.0), 4)  # K, nm; TIP3P's η = 0.321 mPa·s
    0.9646
    >>> round(yeh_hummer_correction(298.0 * unit.kelvin, 20.0 * unit.angstrom,
    ...                             0.321 * unit.millipascal * unit.second), 4)
    0.9646
    """
    from openmm import unit

    from .._units import to_float

    t = to_float(temperature, unit.kelvin, "temperature", positive=True)
    length_m = to_float(box_length, unit.nanometer, "box_length", positive=True) * 1e-9
    eta = to_float(viscosity, unit.millipascal * unit.second, "viscosity", positive=True) * 1e-3
    correction = YEH_HUMMER_XI * _BOLTZMANN_J_PER_K * t / (6.0 * np.pi * eta * length_m)
    return float(correction * _M2_PER_S_IN_1E5_CM2_PER_S)


def corrected_diffusion(
    diffusion_pbc: float,
    temperature: object,
    box_length: object,
    viscosity: object = TIP3P_SHEAR_VISCOSITY_MPA_S,
) -> float:
    """Infinite-system diffusion coefficient D₀ = D_PBC + ξ k_B T / (6 π η L) (Yeh–Hummer).

    Parameters
    ----------
    diffusion_pbc : float
        D measured in the periodic box, in 1e-5 cm²/s (e.g.
        ``Diffusion(...).results.diffusion_coefficient``).
    temperature : float or openmm.unit.Quantity
        Temperature (K), as for :func:`yeh_hummer_correction`.
    box_length : float or openmm.unit.Quantity
        Edge of the cubic box (nm).
    viscosity : float or openmm.unit.Quantity, default TIP3P_SHEAR_VISCOSITY_MPA_S
        Shear viscosity of the solvent (mPa·s).

    Returns
    -------
    float
        D₀ in 1e-5 cm²/s. A NaN ``diffusion_pbc`` gives NaN.

    Examples
    --------
    >>> from openmm_alphaprk.analysis import corrected_diffusion
    >>> round(corrected_diffusion(4.5, 298.0, 2.0), 4)  # 1e-5 cm²/s
    5.4646
    """
    return float(diffusion_pbc) + yeh_hummer_correction(temperature, box_length, viscosity)
