"""``python -m openmm_alphaprk``: the same as the ``alphaprk`` command."""

import sys

from .cli import main

sys.exit(main())
