"""Ready-to-run systems: declarative definitions (``*.toml``), built with OpenMM and cached."""

from .cache import CACHE_ENV, PreparedSystem, default_cache_dir, is_cached, prepare_system
from .definitions import (
    DefinitionError,
    SystemDefinition,
    UnknownSystemError,
    list_systems,
    load_definition,
)
from .water_box import build_water_box

__all__ = [
    "CACHE_ENV",
    "DefinitionError",
    "PreparedSystem",
    "SystemDefinition",
    "UnknownSystemError",
    "build_water_box",
    "default_cache_dir",
    "is_cached",
    "list_systems",
    "load_definition",
    "prepare_system",
]
