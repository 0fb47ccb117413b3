"""Analyses of NVE runs with MDAnalysis: constraints, O–O RDF, MSD/diffusion, energy drift, VACF."""

from .constraints import ConstraintDeviation, system_constraints
from .diffusion import (
    TIP3P_SHEAR_VISCOSITY_MPA_S,
    YEH_HUMMER_XI,
    Diffusion,
    corrected_diffusion,
    yeh_hummer_correction,
)
from .energy import EnergyDrift, energy_drift
from .equipartition import (
    Equipartition,
    combine_segments,
    compare_settings,
    molecules_of,
    partition_temperature,
)
from .rotation import WATER_MOLECULES, DipoleReorientation
from .structure import WATER_OXYGENS, first_peak, oxygen_rdf
from .vacf import VelocityAutocorrelation, band_summary, spectrum_difference

__all__ = [
    "TIP3P_SHEAR_VISCOSITY_MPA_S",
    "WATER_MOLECULES",
    "WATER_OXYGENS",
    "YEH_HUMMER_XI",
    "ConstraintDeviation",
    "Diffusion",
    "DipoleReorientation",
    "EnergyDrift",
    "Equipartition",
    "VelocityAutocorrelation",
    "band_summary",
    "combine_segments",
    "compare_settings",
    "corrected_diffusion",
    "energy_drift",
    "first_peak",
    "molecules_of",
    "oxygen_rdf",
    "partition_temperature",
    "spectrum_difference",
    "system_constraints",
    "yeh_hummer_correction",
]
