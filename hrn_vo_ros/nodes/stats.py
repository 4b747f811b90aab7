"""Book-keeping of a running node: message counts, sequence gaps, rates, processing times.

Pure Python, so node callbacks only call methods here and the numbers are unit-testable.
"""

from __future__ import annotations

from collections import Counter, deque
import math
import time

import numpy as np

from hrn_vo_ros.core.events.stream import packet_problem

__all__ = ['NodeStats', 'packet_problem']


class NodeStats:
    """Counters, a sequence-gap detector, a rate meter and a processing-time window.

    Args:
        window: How many recent processing times the percentiles use.
    """

    def __init__(self, window: int = 500) -> None:
        self.counts: Counter[str] = Counter()
        self.bad: Counter[str] = Counter()
        self.seq_gaps = 0
        self.seq_resets = 0
        self._last_seq: int | None = None
        self._proc: deque[float] = deque(maxlen=window)
        self._rate_mark = (time.monotonic(), 0)
        self.last_reject_wall = -math.inf

    def count(self, key: str, n: int = 1) -> None:
        """Add ``n`` to counter ``key`` (messages in, frames out, ...)."""
        self.counts[key] += n

    def reject(self, kind: str) -> None:
        """Count one malformed message of ``kind`` (``decode``, ``empty``, ...)."""
        self.bad[kind] += 1
        self.last_reject_wall = time.monotonic()

    def rejected_within(self, seconds: float) -> int:
        """Whether a message was rejected in the last ``seconds`` of wall time (1) or not (0)."""
        return int(time.monotonic() - self.last_reject_wall <= seconds)

    def sequence(self, seq: int) -> int:
        """Record a message sequence number; returns how many messages were missed before it.

        A number that does not increase counts as a reset (a restarted publisher), not a gap.
        """
        missed = 0
        if self._last_seq is not None:
            if seq > self._last_seq:
                missed = seq - self._last_seq - 1
                self.seq_gaps += missed
            else:
                self.seq_resets += 1
        self._last_seq = seq
        return missed

    def processing(self, seconds: float) -> None:
        """Record the processing time of one message."""
        self._proc.append(seconds)

    def processing_ms(self) -> tuple[float, float]:
        """Median and 99th percentile of the recent processing times in milliseconds."""
        if not self._proc:
            return math.nan, math.nan
        a = np.fromiter(self._proc, float) * 1e3
        return float(np.median(a)), float(np.percentile(a, 99))

    def rate(self, key: str) -> float:
        """Rate of counter ``key`` per wall-clock second since the previous call."""
        now, n = time.monotonic(), self.counts[key]
        t0, n0 = self._rate_mark
        self._rate_mark = (now, n)
        return (n - n0) / (now - t0) if now > t0 else 0.0

    def values(self) -> list[tuple[str, object]]:
        """All counters as (key, value) pairs for a diagnostics message."""
        out: list[tuple[str, object]] = sorted(self.counts.items())
        out += [('bad_' + k, v) for k, v in sorted(self.bad.items())]
        out += [('bad_total', sum(self.bad.values())), ('seq_gaps', self.seq_gaps),
                ('seq_resets', self.seq_resets)]
        med, p99 = self.processing_ms()
        out += [('processing_ms_median', f'{med:.3f}'), ('processing_ms_p99', f'{p99:.3f}')]
        return out
