"""Analyses of NVE runs with MDAnalysis: constraints, O–O RDF, MSD/diffusion, energy drift."""

from .constraints import ConstraintDeviation, system_constraints
from .diffusion import Diffusion
from .energy import EnergyDrift, energy_drift
from .run import analyze_run
from .structure import WATER_OXYGENS, oxygen_rdf

__all__ = [
    "WATER_OXYGENS",
    "ConstraintDeviation",
    "Diffusion",
    "EnergyDrift",
    "analyze_run",
    "energy_drift",
    "oxygen_rdf",
    "system_constraints",
]
