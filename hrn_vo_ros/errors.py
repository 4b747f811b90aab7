"""The package's error hierarchy.

Every error the package raises on purpose derives from :class:`HrnVoError`. Messages say what
to change. Nodes catch :class:`HrnVoError` at the callback boundary, log it (throttled) and keep
running; CLIs map each class to an exit code with :func:`exit_code_for`.
"""

from __future__ import annotations

from pathlib import Path


class HrnVoError(Exception):
    """Base class of all errors raised on purpose by hrn_vo_ros."""

    exit_code = 1


class ConfigError(HrnVoError, ValueError):
    """An invalid configuration value, parameter or YAML file."""

    exit_code = 2


class DatasetError(HrnVoError):
    """Bad input data: a missing file, a malformed line, unsorted times, out-of-sensor events.

    Args:
        message: What is wrong and what to change.
        path: The offending file, if any.
        line: 1-based line number in ``path``, if known.
    """

    exit_code = 3

    def __init__(self, message: str, *, path: Path | str | None = None,
                 line: int | None = None) -> None:
        where = ''
        if path is not None:
            where = f'{path}'
            if line is not None:
                where += f':{line}'
            where += ': '
        super().__init__(where + message)
        self.path = None if path is None else Path(path)
        self.line = line


class DecodeError(HrnVoError):
    """An event message that cannot be decoded (unknown encoding, corrupt payload)."""

    exit_code = 3


class BagError(HrnVoError):
    """A ROS bag that cannot be read, is incomplete, or would be overwritten."""

    exit_code = 4


class TrackingError(HrnVoError):
    """The estimator cannot produce an estimate (e.g. an empty or degenerate frame)."""

    exit_code = 5


class DatasetWarning(UserWarning):
    """Usable input with something missing that the user should know about (e.g. no
    ``calib.txt``, so a converted bag has no camera_info)."""


class IntegrityError(BagError):
    """A bag whose bytes do not match its CRCs, counts or stored event checksum."""


def exit_code_for(err: BaseException) -> int:
    """The process exit code a CLI returns for ``err`` (1 for unknown package errors)."""
    return err.exit_code if isinstance(err, HrnVoError) else 1
