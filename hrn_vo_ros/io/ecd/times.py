"""Exact conversions between decimal-seconds text and int64 nanoseconds."""

from __future__ import annotations

NS_PER_S = 1_000_000_000
MAX_SECONDS = 9_000_000_000  # int64 ns overflow guard (~285 years)


def seconds_to_ns(tok: str) -> int:
    """Exact int ns from a decimal seconds string (``12.000001234``, ``3``, ``0.5``).

    The one seconds-text parser of the I/O layer (dataset, estimate and trajectory files).

    Raises:
        ValueError: for anything but digits with at most 9 decimals, or an int64 overflow.
    """
    sec, dot, frac = tok.partition('.')
    if not (sec.isascii() and sec.isdigit()) or (frac and not (frac.isascii()
                                                                and frac.isdigit())):
        raise ValueError(f'time {tok!r} is not a non-negative decimal number of seconds')
    if len(frac) > 9:
        raise ValueError(f'time {tok!r} has more than 9 decimals (finer than 1 ns)')
    if int(sec) > MAX_SECONDS:
        raise ValueError(f'time {tok!r} is too large')
    return int(sec) * NS_PER_S + (int(frac.ljust(9, '0')) if frac else 0)


def format_ns(t: int) -> str:
    """Int ns as decimal seconds with 9 decimals (exact; the inverse of :func:`seconds_to_ns`)."""
    return f'{t // NS_PER_S}.{t % NS_PER_S:09d}' if t >= 0 else f'-{format_ns(-t)}'
