"""Mean-squared displacement and self-diffusion coefficient (MDAnalysis' ``EinsteinMSD`` + a fit)."""

from __future__ import annotations

import numpy as np
from MDAnalysis.analysis.msd import EinsteinMSD

#: 1 Å²/ps in 1e-5 cm²/s (the unit diffusion coefficients of water are quoted in).
ANGSTROM2_PER_PS_IN_1E5_CM2_PER_S = 10.0


class Diffusion(EinsteinMSD):
    """Einstein MSD of a selection and D from a linear fit, MSD = 2 d D t.

    Needs unwrapped coordinates (this package's DCD files are written unwrapped).

    Parameters
    ----------
    universe
        The Universe.
    select
        Atoms to follow (e.g. water oxygens, ``"resname HOH and name O"``).
    msd_type
        Dimensions (``"xyz"``: d = 3).
    fit_start, fit_stop
        Fit window as fractions of the longest lag time (defaults 0.1, 0.6: past the
        ballistic start, before the noisy long lags).
    kwargs
        Passed on to ``EinsteinMSD`` (``fft=False`` is the default here, which needs no
        extra package).

    Attributes
    ----------
    results.timeseries, results.delta_t_values
        MSD (Å²) against lag time (ps), from ``EinsteinMSD``.
    results.slope
        Fitted slope (Å²/ps).
    results.diffusion_coefficient
        D in 1e-5 cm²/s.
    results.fit_window
        Lag times (ps) of the first and last fitted point.
    """

    def __init__(
        self,
        universe,
        select: str = "all",
        msd_type: str = "xyz",
        *,
        fit_start: float = 0.1,
        fit_stop: float = 0.6,
        fft: bool = False,
        **kwargs,
    ):
        if not 0.0 <= fit_start < fit_stop <= 1.0:
            raise ValueError(f"need 0 <= fit_start < fit_stop <= 1, got {fit_start}, {fit_stop}.")
        super().__init__(universe, select=select, msd_type=msd_type, fft=fft, **kwargs)
        if self.n_particles == 0:
            raise ValueError(f"selection {select!r} matches no atoms.")
        self._fit = (fit_start, fit_stop)

    def _conclude(self):
        super()._conclude()
        lags = self.results.delta_t_values
        msd = self.results.timeseries
        longest = lags[-1] if len(lags) else 0.0
        window = (lags >= self._fit[0] * longest) & (lags <= self._fit[1] * longest) & (lags > 0)
        if window.sum() < 2:
            window = lags > 0
        if window.sum() < 2:
            self.results.slope = float("nan")
            self.results.fit_window = (float("nan"), float("nan"))
        else:
            self.results.slope = float(np.polyfit(lags[window], msd[window], 1)[0])
            self.results.fit_window = (float(lags[window][0]), float(lags[window][-1]))
        self.results.diffusion_coefficient = (
            self.results.slope / (2 * self.dim_fac) * ANGSTROM2_PER_PS_IN_1E5_CM2_PER_S
        )
