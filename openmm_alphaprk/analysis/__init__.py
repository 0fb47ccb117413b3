"""Analyses of NVE runs with MDAnalysis: constraints, O–O RDF, MSD/diffusion, energy drift, VACF."""

from .constraints import ConstraintDeviation, system_constraints
from .diffusion import Diffusion
from .energy import EnergyDrift, energy_drift
from .structure import WATER_OXYGENS, oxygen_rdf
from .vacf import VelocityAutocorrelation, band_summary, spectrum_difference

__all__ = [
    "WATER_OXYGENS",
    "ConstraintDeviation",
    "Diffusion",
    "EnergyDrift",
    "VelocityAutocorrelation",
    "band_summary",
    "energy_drift",
    "oxygen_rdf",
    "spectrum_difference",
    "system_constraints",
]
