"""Ready-to-run systems: declarative definitions (``*.toml``), built with OpenMM and cached."""

from .cache import CACHE_ENV, PreparedSystem, default_cache_dir, is_cached, prepare_system
from .definitions import (
    DefinitionError,
    SystemDefinition,
    UnknownSystemError,
    list_systems,
    load_definition,
)

__all__ = [
    "CACHE_ENV",
    "DefinitionError",
    "PreparedSystem",
    "SystemDefinition",
    "UnknownSystemError",
    "default_cache_dir",
    "is_cached",
    "list_systems",
    "load_definition",
    "prepare_system",
]
