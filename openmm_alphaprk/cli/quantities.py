"""Command-line whole numbers (times and lengths with units: :mod:`openmm_alphaprk._units`)."""

from __future__ import annotations

import argparse


def positive(text: str) -> int:
    """Parse a positive whole number (an argparse ``type``)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive whole number, got {value}")
    return value
