"""A dependency-free progress bar for long CLI work (stderr; redraws on a TTY, lines otherwise)."""

from __future__ import annotations

import sys
import time
from types import TracebackType
from typing import TextIO


class Progress:
    """Progress of ``total`` units of work, e.g. events or bytes.

    Use as a context manager and call :meth:`advance`; the bar redraws at most every
    ``interval`` seconds on a terminal, and prints a line every 10 % otherwise (CI logs).

    Args:
        total: The amount of work, or ``None`` when unknown (then counts and rates only).
        label: What is being done ("converting", "running HRN").
        unit: Name of a unit of work ("ev", "frames", "B").
        stream: Where to draw (stderr by default).
    """

    def __init__(self, total: float | None, label: str, *, unit: str = '',
                 stream: TextIO | None = None, interval: float = 0.25) -> None:
        self.total = total
        self.label = label
        self.unit = unit
        self.stream = stream if stream is not None else sys.stderr
        self.interval = interval
        self.done = 0.0
        self._start = time.monotonic()
        self._last = 0.0
        self._last_decile = -1
        self._tty = bool(getattr(self.stream, 'isatty', lambda: False)())

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    @property
    def elapsed(self) -> float:
        """Seconds since the start."""
        return time.monotonic() - self._start

    def advance(self, amount: float) -> None:
        """Record ``amount`` more units of finished work."""
        self.done += amount
        now = time.monotonic()
        if self._tty:
            if now - self._last >= self.interval:
                self._last = now
                self.stream.write('\r' + self._line())
                self.stream.flush()
        elif self.total:
            decile = int(10 * self.done / self.total)
            if decile > self._last_decile and decile < 10:
                self._last_decile = decile
                self.stream.write(self._line() + '\n')
                self.stream.flush()

    def _line(self) -> str:
        rate = self.done / max(self.elapsed, 1e-9)
        if self.total:
            frac = min(self.done / self.total, 1.0)
            bar = '#' * int(30 * frac) + '-' * (30 - int(30 * frac))
            eta = (self.total - self.done) / rate if rate > 0 else float('inf')
            return (f'{self.label} [{bar}] {100 * frac:5.1f}% {_si(self.done)}{self.unit} '
                    f'{_si(rate)}{self.unit}/s eta {eta:4.0f}s')
        return f'{self.label} {_si(self.done)}{self.unit} {_si(rate)}{self.unit}/s'

    def close(self) -> None:
        """Draw the final state and end the line."""
        if self._tty:
            self.stream.write('\r' + self._line() + '\n')
        else:
            self.stream.write(self._line() + '\n')
        self.stream.flush()


def _si(value: float) -> str:
    for factor, suffix in ((1e9, 'G'), (1e6, 'M'), (1e3, 'k')):
        if abs(value) >= factor:
            return f'{value / factor:.2f}{suffix}'
    return f'{value:.0f}'
