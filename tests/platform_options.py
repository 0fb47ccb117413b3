"""Which common-platform (CUDA, OpenCL, HIP) configurations the tests run on.

``ALPHAPRK_TEST_PLATFORMS`` lists them as ``NAME:precision`` separated by commas
(default ``OpenCL:double,OpenCL:mixed``); e.g. ``CUDA:double,CUDA:mixed`` on a GPU
machine. A configuration whose platform is not installed is skipped with the reason,
unless ``ALPHAPRK_REQUIRE_PLATFORMS=1`` (set by CI), which turns the skip into a
failure so that the common-platform tests cannot silently vanish.
"""

from __future__ import annotations

import os

import openmm as mm
import pytest

DEFAULT = "OpenCL:double,OpenCL:mixed"


def configured() -> list[str]:
    """The configurations named by ``ALPHAPRK_TEST_PLATFORMS``."""
    return [spec.strip() for spec in os.environ.get("ALPHAPRK_TEST_PLATFORMS", DEFAULT).split(",") if spec]


def with_precision(precision: str) -> list[str]:
    """The configured platforms with ``precision`` (e.g. for a test that needs mixed)."""
    return [spec for spec in configured() if spec.endswith(f":{precision}")]


def slow(specs: list[str]) -> list:
    """``specs`` as parameters marked ``slow``: run with ``pytest -m slow``, not by default."""
    return [pytest.param(spec, marks=pytest.mark.slow) for spec in specs]


def available(name: str) -> bool:
    try:
        mm.Platform.getPlatformByName(name)
    except mm.OpenMMException:
        return False
    return True


def platform_and_properties(spec: str) -> tuple[mm.Platform, dict[str, str]]:
    """The platform of ``NAME:precision`` and its properties; skip (or fail) if it is absent."""
    name, _, precision = spec.partition(":")
    if not available(name):
        message = (
            f"OpenMM platform {name} is not available here (loaded: "
            f"{[mm.Platform.getPlatform(i).getName() for i in range(mm.Platform.getNumPlatforms())]}); "
            "install pocl (Debian: pocl-opencl-icd ocl-icd-libopencl1) for OpenCL on the CPU"
        )
        if os.environ.get("ALPHAPRK_REQUIRE_PLATFORMS") == "1":
            pytest.fail(message + " — ALPHAPRK_REQUIRE_PLATFORMS=1 makes this a failure")
        pytest.skip(message)
    return mm.Platform.getPlatformByName(name), ({"Precision": precision} if precision else {})
