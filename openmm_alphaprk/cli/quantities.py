"""Command-line whole numbers (times and lengths with units: :mod:`openmm_alphaprk._units`)."""

from __future__ import annotations

import argparse

from .._units import InputError, positive_int


def positive(text: str) -> int:
    """Parse a positive whole number (an argparse ``type``) by :func:`openmm_alphaprk._units.positive_int`."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    try:
        return positive_int(value, "the number")
    except InputError:
        raise argparse.ArgumentTypeError(f"must be a positive whole number, got {value}") from None
