"""Event-rate cap: above a rate, keep an even share of the events (``max_frame_hz``).

The network's time constants count frames (the map's memory, the velocity prediction), and a
frame costs the CPU 1-1.7 ms. A packet of a fixed event count spans less time the
more events the sensor makes: a 640x480 sensor in a fast rotation makes 5-30 M events/s,
2500-15000 frames/s of 2000 events, each showing a sub-pixel motion of the 96x72 frame, and
errors that add up over tens of thousands of frames (docs/results.md). A DAVIS240C seeing the
same motion makes about 7x fewer events, and the network tracks it.

The cap keeps about ``max_per_window`` events of each window of ``window_ns`` (bins fixed in
absolute sensor time, ``t // window_ns``), decided from the previous window's count ``n``:
with ``r = min(1, max_per_window / n)`` the event of index ``i`` in its window (from 0) is
kept iff ``floor((i + 1) r) > floor(i r)``, so the kept events are spread evenly over the
window, one in ``1 / r``, ``floor(m r)`` of a window of ``m`` (more than the cap while the
rate rises). A window whose previous window had no event keeps everything.
The decision depends only on the events, in order: the same events give the same output
however they are split into pushes (a stream and a batch agree).

Public API: ``RateCap(max_per_window, window_ns)`` with ``push(ev) -> EventArray``,
``mask(t)`` (which events it keeps), ``reset()``, ``kept``, ``dropped`` and ``share`` (the
share kept in the current window).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.arrays import EventArray, runs
from hrn_vo_ros.errors import ConfigError


class RateCap:
    """Keeps at most about ``max_per_window`` events per window of ``window_ns``.

    Args:
        max_per_window: Events a window keeps at most (> 0; a rate times the window).
        window_ns: Window length (ns, > 0).

    Raises:
        ConfigError: for a non-positive cap or window.
    """

    def __init__(self, max_per_window: float, window_ns: int) -> None:
        if not max_per_window > 0 or window_ns <= 0:
            raise ConfigError(f'RateCap needs a positive cap and window, got {max_per_window} '
                              f'events per {window_ns} ns')
        self.max_per_window = float(max_per_window)
        self.window_ns = int(window_ns)
        self.kept = 0                   # events passed so far
        self.dropped = 0                # events dropped so far
        self.reset()

    def reset(self) -> None:
        """Forget the windows seen (the counters stay)."""
        self._window: int | None = None     # the current window's index
        self._count = 0                     # events of the current window so far
        self._share = 1.0                   # kept share in the current window

    @property
    def share(self) -> float:
        """The share of the current window's events that is kept (1: no cap in force)."""
        return self._share

    def _enter(self, window: int) -> None:
        """Start ``window``: its share from the previous window's count."""
        previous = self._count if self._window is not None and window == self._window + 1 \
            else 0
        self._share = min(1.0, self.max_per_window / previous) if previous else 1.0
        self._window, self._count = window, 0

    def push(self, ev: EventArray) -> EventArray:
        """The kept events of ``ev`` (in time order, after the previous push's)."""
        keep = self.mask(ev.t)
        return ev if keep.all() else ev[keep]

    def mask(self, t: NDArray[np.int64]) -> NDArray[np.bool_]:
        """Which of the events at times ``t`` (after the previous call's) are kept."""
        n = len(t)
        keep = np.ones(n, dtype=bool)
        if n == 0:
            return keep
        win = t // self.window_ns
        for a, b in runs(win):
            w = int(win[a])
            if w != self._window:
                self._enter(w)
            if self._share < 1.0:
                i = np.arange(self._count, self._count + (b - a), dtype=np.float64)
                keep[a:b] = np.floor((i + 1.0) * self._share) > np.floor(i * self._share)
            self._count += b - a
        n_kept = int(np.count_nonzero(keep))
        self.kept += n_kept
        self.dropped += n - n_kept
        return keep
