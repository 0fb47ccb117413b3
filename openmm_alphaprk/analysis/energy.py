"""Energy drift of a run's energy samples: the fit of :mod:`openmm_alphaprk.observables`, under the analyses.

:func:`energy_drift` and :class:`EnergyDrift` live in :mod:`openmm_alphaprk.observables`
(the one home of the drift fit, its standard error and the RMS); they are importable
from here with the other analyses.
"""

from __future__ import annotations

from ..observables import EnergyDrift, energy_drift

__all__ = ["EnergyDrift", "energy_drift"]
