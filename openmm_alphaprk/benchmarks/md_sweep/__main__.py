"""``python -m openmm_alphaprk.benchmarks.md_sweep``: the MD benchmark, see the package's docstring."""

import sys

from . import main

if __name__ == "__main__":
    sys.exit(main())
