"""Ready-to-run systems: declarative definitions (``*.toml``), built with OpenMM and cached.

The default systems' equilibrated start states are shipped with the package
(:mod:`.shipped`), so they start from the same state on every machine.
"""

from .cache import CACHE_ENV, PreparedSystem, default_cache_dir, is_cached, prepare_system
from .definitions import (
    DefinitionError,
    SystemDefinition,
    UnknownSystemError,
    list_systems,
    load_definition,
)
from .shipped import ShippedStateWarning, find_shipped_state
from .water_box import build_water_box, water_box_definition

__all__ = [
    "CACHE_ENV",
    "DefinitionError",
    "PreparedSystem",
    "ShippedStateWarning",
    "SystemDefinition",
    "UnknownSystemError",
    "build_water_box",
    "default_cache_dir",
    "find_shipped_state",
    "is_cached",
    "list_systems",
    "load_definition",
    "prepare_system",
    "water_box_definition",
]
