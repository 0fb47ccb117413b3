"""The ``alphaprk`` command: ``systems``, ``run``, ``compare``, ``analyze`` over the library functions.

- :mod:`.parser`: :func:`build_parser`, one ``_add_*_parser`` per command.
- :mod:`.commands`: one ``cmd_*`` per command, a call of the library and its printout.
- times and lengths with units (``2fs``, ``8A``): :mod:`openmm_alphaprk._units`.

:func:`main` runs a command and turns the errors the user can fix into one line on
stderr (exit status 2), a run that blew up into exit status 1, Ctrl-C into exit status
130 with a line that says what the same command will do.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence

import openmm as mm

from .._units import InputError, InputTypeError, QuantityError, parse_length, parse_time
from ..systems import UnknownSystemError
from .commands import COMMANDS
from .parser import build_parser

__all__ = ["QuantityError", "build_parser", "main", "parse_length", "parse_time"]

#: Errors that are the user's to fix: reported in one line, exit status 2. The package
#: raises every error about the user's input as an ``InputError`` / ``InputTypeError``
#: (named subclasses included); any other ValueError or TypeError is a bug and keeps its
#: traceback.
_INPUT_ERRORS = (InputError, InputTypeError, UnknownSystemError, FileNotFoundError, ImportError)


#: What the same command does after a Ctrl-C that came while no run was stepping.
_RESUMES = (
    "; the same command resumes each unfinished run from its last checkpoint (from step 0 where it has "
    "none) and reports finished ones."
)
_INTERRUPTED = {
    "run": " while no run was stepping" + _RESUMES,
    "compare": " while no run was stepping" + _RESUMES,
    "sweep": "; the same command skips finished cells and resumes the others from their last checkpoints.",
}


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``alphaprk`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    from ..runs import RunFailedError, RunInterrupted

    if os.environ.get("ALPHAPRK_DEBUG"):  # full tracebacks
        return COMMANDS[args.command](args)
    try:
        return COMMANDS[args.command](args)
    except RunFailedError as error:
        print(f"alphaprk {args.command}: run failed: {error}", file=sys.stderr)
        return 1
    except mm.OpenMMException as error:
        print(f"alphaprk {args.command}: OpenMM error: {error}", file=sys.stderr)
        return 1
    except _INPUT_ERRORS as error:
        print(f"alphaprk {args.command}: error: {error}", file=sys.stderr)
        return 2
    except RunInterrupted as interrupt:  # says from which step the same command resumes
        print(f"alphaprk {args.command}: {interrupt}", file=sys.stderr)
        return 130
    except KeyboardInterrupt:
        print(f"alphaprk {args.command}: interrupted{_INTERRUPTED.get(args.command, '.')}", file=sys.stderr)
        return 130
