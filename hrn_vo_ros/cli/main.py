"""``hrn-vo``: the package's command-line tool, one error boundary for all subcommands.

Each subcommand lives in its own module under :mod:`hrn_vo_ros.cli` and exposes
``register(subparsers) -> None`` (adds its parser and sets ``func``) and a run function
``(args) -> int``. Known errors (:class:`hrn_vo_ros.errors.HrnVoError`) become a one-line
message on stderr and their class's exit code; unknown errors keep their traceback.
"""

from __future__ import annotations

import argparse
import importlib
import math
from pathlib import Path
import sys

from hrn_vo_ros.errors import ConfigError, exit_code_for, HrnVoError

# Subcommand modules, in the order `hrn-vo --help` lists them. A module missing from an
# installation (optional backends) is skipped.
SUBCOMMANDS = ('simulate', 'run', 'evaluate', 'convert', 'play', 'demo', 'check', 'recover',
               'spiking_report')

# What each subcommand writes (argument dests): the folder of every output must exist, a
# ``file`` output must not be an existing folder (a ``plot`` may be one: it writes into it);
# ``new`` outputs (folders or bags the command
# creates) are refused by the command when they exist. Checked before the command runs
# (:func:`check_outputs`).
OUTPUTS: dict[str, tuple[tuple[str, str], ...]] = {
    'simulate': (('out', 'new'),),
    'run': (('out', 'file'), ('tum', 'file')),
    'evaluate': (('plot', 'plot'),),
    'convert': (('dst', 'new'),),
}


def echo(*parts: object, err: bool = False) -> None:
    """The one place CLIs print (stdout, or stderr with ``err``)."""
    print(*parts, file=sys.stderr if err else sys.stdout, flush=True)


def finite_float(text: str) -> float:
    """A finite float (argparse type): NaN and infinities are refused at parse time."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a number') from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f'{text!r}: expected a finite number')
    return value


def _finite_floats(parser: argparse.ArgumentParser) -> None:
    """Every ``type=float`` option of ``parser`` and its subparsers becomes :func:`finite_float`
    (no option of the tool means anything by NaN or infinity)."""
    for action in parser._actions:
        if action.type is float:
            action.type = finite_float
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                _finite_floats(sub)


def check_outputs(args: argparse.Namespace) -> None:
    """Refuse, before any work, an output whose folder is missing or a file output that is an
    existing folder (:data:`OUTPUTS`).

    Raises:
        ConfigError: naming the option and the path.
    """
    for dest, kind in OUTPUTS.get(str(getattr(args, 'command', '')), ()):
        value = getattr(args, dest, None)
        if value is None:
            continue
        path = Path(value)
        name = f'--{dest}' if dest not in ('out', 'dst') or kind == 'file' else dest.upper()
        parent = path.parent if str(path.parent) else Path('.')
        if not parent.is_dir():
            raise ConfigError(f'{name} {path}: the folder {parent} does not exist (create it '
                              'first)')
        if kind == 'file' and path.is_dir():
            raise ConfigError(f'{name} {path} is a folder; give a file name in it')


def build_parser() -> argparse.ArgumentParser:
    """The ``hrn-vo`` parser with every available subcommand."""
    parser = argparse.ArgumentParser(
        prog='hrn-vo',
        description='Event-camera visual odometry with hierarchical resonator networks.')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND')
    sub.required = True
    for name in SUBCOMMANDS:
        try:
            module = importlib.import_module(f'hrn_vo_ros.cli.{name}')
        except ModuleNotFoundError as err:
            if err.name == f'hrn_vo_ros.cli.{name}':
                continue
            raise
        module.register(sub)
    _finite_floats(parser)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``hrn-vo``; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        check_outputs(args)
        return int(args.func(args))
    except HrnVoError as err:
        echo(f'hrn-vo {args.command}: error: {err}', err=True)
        return exit_code_for(err)
    except KeyboardInterrupt:
        echo(f'hrn-vo {args.command}: interrupted', err=True)
        return 130


if __name__ == '__main__':
    sys.exit(main())
