"""``hrn-vo``: the package's command-line tool, one error boundary for all subcommands.

Each subcommand lives in its own module under :mod:`hrn_vo_ros.cli` and exposes
``register(subparsers) -> None`` (adds its parser and sets ``func``) and a run function
``(args) -> int``. Known errors (:class:`hrn_vo_ros.errors.HrnVoError`) become a one-line
message on stderr and their class's exit code; unknown errors keep their traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from hrn_vo_ros.errors import exit_code_for, HrnVoError

# Subcommand modules, in the order `hrn-vo --help` lists them. A module missing from an
# installation (optional backends) is skipped.
SUBCOMMANDS = ('simulate', 'run', 'evaluate', 'convert', 'play', 'demo', 'check')


def echo(*parts: object, err: bool = False) -> None:
    """The one place CLIs print (stdout, or stderr with ``err``)."""
    print(*parts, file=sys.stderr if err else sys.stdout, flush=True)


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
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``hrn-vo``; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except HrnVoError as err:
        echo(f'hrn-vo {args.command}: error: {err}', err=True)
        return exit_code_for(err)
    except KeyboardInterrupt:
        echo(f'hrn-vo {args.command}: interrupted', err=True)
        return 130


if __name__ == '__main__':
    sys.exit(main())
