"""Command-line quantities: times and lengths with their units, positive whole numbers."""

from __future__ import annotations

import argparse
import re

from .._units import InputError

_TIME_UNITS = {"fs": 1e-3, "ps": 1.0, "ns": 1e3}
_LENGTH_UNITS = {"a": 1.0, "å": 1.0, "angstrom": 1.0, "nm": 10.0}


class QuantityError(InputError):
    """A command-line quantity with a missing or wrong unit."""


def parse_time(text: str, option: str) -> float:
    """Parse ``2fs``, ``2 fs``, ``0.002ps`` or ``1ns`` into picoseconds."""
    return _parse(text, option, _TIME_UNITS, "a time", "fs, ps or ns")


def parse_length(text: str, option: str) -> float:
    """Parse ``8A``, ``8 Å`` or ``0.8nm`` into Ångström."""
    return _parse(text, option, _LENGTH_UNITS, "a length", "A (Ångström) or nm")


def _parse(text: str, option: str, units: dict[str, float], what: str, allowed: str) -> float:
    match = re.fullmatch(r"\s*([-+]?[0-9.]+(?:[eE][-+]?[0-9]+)?)\s*([^\s0-9]*)\s*", str(text))
    if not match:
        raise QuantityError(f"{option} {text!r} is not a number with a unit; write e.g. 2fs or 0.8nm.")
    value, symbol = float(match.group(1)), match.group(2)
    if not symbol:
        raise QuantityError(f"{option} {text!r} has no unit; give {what} with a unit ({allowed}), e.g. 2fs.")
    factor = units.get(symbol.lower())
    if factor is None:
        raise QuantityError(f"{option} {text!r}: {symbol!r} is not a unit of {what}; use {allowed}.")
    if not value > 0:
        raise QuantityError(f"{option} must be positive, got {text!r}.")
    return value * factor


def positive(text: str) -> int:
    """Parse a positive whole number (an argparse ``type``)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive whole number, got {value}")
    return value
