"""The ``lightcurve`` command line.

Subcommands live in :mod:`lightcurve.commands`, one module each. A command module defines

``NAME``
    The subcommand name (``str``).
``HELP``
    One line for ``lightcurve --help``.
``ORDER``
    Sort key in the help listing (``int``; workflow order).
``add_arguments(parser)``
    Adds the command's arguments (or its own sub-subcommands) to an
    :class:`argparse.ArgumentParser`.
``run(args) -> int``
    Executes the command and returns the process exit code.

Modules are discovered at start-up, so adding a command means adding one file. User errors
(:class:`ValueError`, :class:`OSError` and their subclasses, which every package in this
project uses for bad input) are printed as one line ``lightcurve <cmd>: error: ...`` with
exit code 2; ``-v`` shows the traceback and debug logging.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import pkgutil
import sys
from collections.abc import Sequence
from types import ModuleType

from lightcurve import __version__

logger = logging.getLogger("lightcurve")


def _command_modules() -> list[ModuleType]:
    from lightcurve import commands

    modules = []
    for info in pkgutil.iter_modules(commands.__path__):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"lightcurve.commands.{info.name}")
        if hasattr(module, "NAME") and hasattr(module, "run"):
            modules.append(module)
    return sorted(modules, key=lambda m: (getattr(m, "ORDER", 100), m.NAME))


def build_parser() -> argparse.ArgumentParser:
    """Return the top-level argument parser with every discovered subcommand."""
    parser = argparse.ArgumentParser(
        prog="lightcurve",
        description="Simulate and invert light curves of space objects.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument(
        "-v", "--verbose", action="count", default=0, help="more logging; -v shows tracebacks"
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in _command_modules():
        cmd = sub.add_parser(
            module.NAME, help=module.HELP, description=getattr(module, "__doc__", None)
        )
        cmd.add_argument(
            "-v", "--verbose", action="count", default=argparse.SUPPRESS, help=argparse.SUPPRESS
        )
        module.add_arguments(cmd)
        cmd.set_defaults(_run=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``lightcurve`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG
        if args.verbose > 1
        else logging.INFO
        if args.verbose
        else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    try:
        return int(args._run(args) or 0)
    except (ValueError, OSError) as exc:
        if args.verbose:
            raise
        print(f"lightcurve {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("lightcurve: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
