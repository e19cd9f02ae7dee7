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

Modules are discovered at start-up (their ``NAME``/``HELP``/``ORDER`` are read from the
source, and only the invoked command's module is imported, so the CLI starts fast), so
adding a command means adding one file. User errors
(:class:`ValueError`, :class:`OSError` and their subclasses, which every package in this
project uses for bad input) and usage mistakes are printed as one line
``lightcurve <cmd>: error: ...`` with exit code 2; ``-v`` shows the traceback and debug
logging, ``-q`` keeps warnings and errors only: no progress bars, and no status lines from a
command that writes its results to files (``--out``); both work before the command and after
any command or sub-command (``lightcurve shapes list -q``), and repeat counts add up across
levels (``lightcurve -v invert … -v`` is ``-vv``). Every option's help ends with its default,
``(default: X)``.

Threads: ``lightcurve --threads N COMMAND …`` (or the ``LIGHTCURVE_THREADS`` environment
variable) sets how many threads a command computes on (torch's intra-op threads, the fused
renderer's row threads, the BLAS pool); the default is every CPU the process may use. Idle
threads sleep instead of spinning (``OMP_WAIT_POLICY=PASSIVE`` unless the environment says
otherwise), so a command beside other CPU-bound processes costs the CPU time it costs alone.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.util
import logging
import os
import pkgutil
import re
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import NoReturn

from lightcurve import __version__
from lightcurve.commands._args import positive_int

logger = logging.getLogger("lightcurve")


@dataclass(frozen=True)
class CommandSpec:
    """A command module's name, one-line help and sort key, read without importing it."""

    module: str
    name: str
    help: str
    order: int


def command_specs() -> list[CommandSpec]:
    """Every command module's ``NAME``/``HELP``/``ORDER``, read from its source with ``ast``.

    Reading the constants instead of importing the modules keeps ``lightcurve --help`` and
    the start of every command fast: only the invoked command's module (and its heavy
    dependencies such as torch or astropy) is imported.
    """
    from lightcurve import commands
    from lightcurve.commands._source import module_literals

    specs = []
    for info in pkgutil.iter_modules(commands.__path__):
        if info.name.startswith("_"):
            continue
        module = f"lightcurve.commands.{info.name}"
        constants = module_literals(module, ("NAME", "HELP", "ORDER"))
        if "NAME" in constants:
            specs.append(
                CommandSpec(
                    module,
                    constants["NAME"],
                    constants.get("HELP", ""),
                    int(constants.get("ORDER", 100)),
                )
            )
    return sorted(specs, key=lambda spec: (spec.order, spec.name))


def _default_text(value: object) -> str:
    """A default as typed on the command line: sequences comma-separated, no brackets."""
    if isinstance(value, str):
        return value
    if hasattr(value, "tolist"):
        value = value.tolist()
    if isinstance(value, list | tuple):
        return ",".join(_default_text(item) for item in value)
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _plain(text: str | None) -> str | None:
    """A docstring as plain help text: reStructuredText's ``literal`` quotes removed."""
    return None if text is None else re.sub(r"``([^`]*)``", r"\1", text)


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Appends ``(default: X)`` to every option whose default is a value.

    Options whose help already states the default (``default:``) are left as written; so are
    flags (default off) and options without a default (``None``), whose help says what their
    absence means when it means something.
    """

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        if (
            "default:" in text
            or default is None
            or default is False
            or default is argparse.SUPPRESS
            or (isinstance(default, list | tuple) and not default)
            or not action.option_strings
            or isinstance(action, argparse._CountAction)
        ):
            return text
        shown = _default_text(default).replace("%", "%%")
        return f"{text} (default: {shown})" if text else f"(default: {shown})"


class ArgumentParser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` with :class:`HelpFormatter` and one-line usage errors.

    Sub-command parsers are made of the same class (argparse's ``add_subparsers`` uses the
    parent's class), so every level formats and reports the same way, and each takes
    ``-v``/``-q`` (:class:`_SubParsersAction`).
    """

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)
        self.register("action", "parsers", _SubParsersAction)

    def error(self, message: str) -> NoReturn:
        """Print ``PROG: error: MESSAGE`` and a pointer to ``--help``; exit with status 2."""
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


#: The verbosity counters (``-v``/``-q``): the same destinations at every level.
_VERBOSITY_DESTS = ("verbose", "quiet")


def _add_verbosity(parser: argparse.ArgumentParser, default: object = argparse.SUPPRESS) -> None:
    """``-v``/``-q`` counters into ``args.verbose``/``args.quiet``.

    The top-level parser counts from ``default=0``; every sub-parser gets the same options
    with ``argparse.SUPPRESS`` as default, so a sub-parser that does not see them leaves the
    value given before the command alone (:class:`_SubParsersAction` adds up the counts).
    """
    parser.add_argument(
        "-v",
        "--verbose",
        action="count",
        default=default,
        dest="verbose",
        help="more logging (-v: info and tracebacks, -vv: debug)",
    )
    parser.add_argument(
        "-q",
        "--quiet",
        action="count",
        default=default,
        dest="quiet",
        help="less output: no progress bars or status lines (-q: warnings and errors, -qq: errors)",
    )


class _SubParsersAction(argparse._SubParsersAction):
    """Sub-commands that take ``-v``/``-q`` wherever they stand.

    Every sub-parser it makes gets the verbosity options (:func:`_add_verbosity`), whichever
    module adds the sub-parser, so ``lightcurve shapes list -v`` works like
    ``lightcurve -v shapes list``. argparse parses a sub-command's arguments into a fresh
    namespace and copies its values over the parent's; the counts given before the
    sub-command are added to those given after it instead of being replaced.
    """

    def add_parser(self, name: str, **kwargs) -> argparse.ArgumentParser:
        parser = super().add_parser(name, **kwargs)
        _add_verbosity(parser)
        return parser

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        given = {dest: vars(namespace).pop(dest) for dest in _VERBOSITY_DESTS if dest in namespace}
        super().__call__(parser, namespace, values, option_string)
        for dest, count in given.items():
            setattr(namespace, dest, count + getattr(namespace, dest, 0))


def build_parser(load: Iterable[str] | None = None) -> argparse.ArgumentParser:
    """Return the argument parser.

    Parameters
    ----------
    load : iterable of str, optional
        Commands whose modules are imported to add their arguments (all when None).
    """
    parser = ArgumentParser(
        prog="lightcurve",
        description="Simulate and invert light curves of space objects.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    _add_verbosity(parser, default=0)
    parser.add_argument(
        "--threads",
        type=positive_int,
        metavar="N",
        help="threads to compute on (default: $LIGHTCURVE_THREADS, else every available CPU)",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    wanted = None if load is None else set(load)
    for spec in command_specs():
        if wanted is not None and spec.name not in wanted:
            sub.add_parser(spec.name, help=spec.help, add_help=False)
            continue
        module = importlib.import_module(spec.module)
        cmd = sub.add_parser(spec.name, help=spec.help, description=_plain(module.__doc__))
        module.add_arguments(cmd)
        cmd.set_defaults(_run=module.run)
    parser.command_parsers = sub.choices  # the sub-command parsers by name (their errors)
    return parser


_NEGATIVE_VALUE = re.compile(r"^-(\d|\.\d)")


def _attach_negative_values(argv: list[str]) -> list[str]:
    """``--q0 -0.3,0.5,…`` → ``--q0=-0.3,0.5,…``: argparse would take the value for an option.

    A token that starts like a negative number and follows a long option without ``=`` is
    that option's value.
    """
    out: list[str] = []
    for token in argv:
        if out and _NEGATIVE_VALUE.match(token) and out[-1].startswith("--") and "=" not in out[-1]:
            out[-1] = f"{out[-1]}={token}"
        else:
            out.append(token)
    return out


#: Options before the command that take a separate value (``--threads N``).
_GLOBAL_VALUE_OPTIONS = ("--threads",)


def _invoked_command(argv: Sequence[str]) -> str | None:
    """The first argument that is neither an option nor a global option's value."""
    tokens = iter(argv)
    for arg in tokens:
        if arg in _GLOBAL_VALUE_OPTIONS:
            next(tokens, None)
        elif not arg.startswith("-"):
            return arg
    return None


def _requested_threads(argv: Sequence[str]) -> str | None:
    """The ``--threads`` value given before the command, else ``$LIGHTCURVE_THREADS``."""
    value = os.environ.get("LIGHTCURVE_THREADS")
    tokens = iter(argv)
    for arg in tokens:
        if arg == "--threads":
            value = next(tokens, value)
        elif arg.startswith("--threads="):
            value = arg.partition("=")[2]
        elif not arg.startswith("-"):
            break
    return value


def configure_threads(threads: str | int | None) -> None:
    """Set the thread environment before torch, numpy's BLAS or OpenMP start.

    Idle OpenMP threads sleep (``OMP_WAIT_POLICY=PASSIVE``) unless the environment sets a
    policy: spinning threads burn a shared machine's CPU while they wait for each other.
    With a thread count, torch's intra-op pool, the BLAS pool and the fused renderer's row
    threads all use that many threads. Has an effect only before those libraries load.
    """
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    if threads is None:
        return
    count = positive_int(str(threads))
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[name] = str(count)
    torch = sys.modules.get("torch")
    if torch is not None:  # already loaded (the CLI called in-process): set it directly
        torch.set_num_threads(count)


_LOG_FORMAT = "%(levelname)s %(name)s: %(message)s"


def _log_level(verbose: int, quiet: int) -> int:
    """``-vv`` debug, ``-v`` info, default and ``-q`` warnings, ``-qq`` errors only."""
    if verbose > 1:
        return logging.DEBUG
    if verbose:
        return logging.INFO
    return logging.ERROR if quiet > 1 else logging.WARNING


def _run(args: argparse.Namespace) -> int:
    """Run the command; with ``-q``, one that writes its results to ``--out`` prints no status
    lines (its standard output is discarded; warnings and errors go to standard error)."""
    if not (args.quiet and getattr(args, "out", None) is not None):
        return int(args._run(args) or 0)
    with open(os.devnull, "w") as devnull, contextlib.redirect_stdout(devnull):
        return int(args._run(args) or 0)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``lightcurve`` console script."""
    argv = _attach_negative_values(list(sys.argv[1:] if argv is None else argv))
    try:
        configure_threads(_requested_threads(argv))
    except argparse.ArgumentTypeError as exc:
        print(f"lightcurve: error: --threads/LIGHTCURVE_THREADS: {exc}", file=sys.stderr)
        return 2
    command = _invoked_command(argv)
    parser = build_parser(load=[command] if command else [])
    args, unrecognized = parser.parse_known_args(argv)
    if unrecognized:  # reported by the command's parser: its usage and its --help
        command_parser = parser.command_parsers.get(args.command) if args.command else None
        (command_parser or parser).error(f"unrecognized arguments: {' '.join(unrecognized)}")
    logging.basicConfig(level=_log_level(args.verbose, args.quiet), format=_LOG_FORMAT)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    try:
        return _run(args)
    except BrokenPipeError:  # output piped into `head` and the like: stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
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
