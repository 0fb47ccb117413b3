"""``python -m openmm_alphaprk.benchmarks.validation``: run the validation, write its JSON."""

import sys

from . import main

if __name__ == "__main__":
    sys.exit(main())
