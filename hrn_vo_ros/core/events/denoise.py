"""Background-activity filter: drop events that no neighbouring pixel supports.

An event camera's background activity (thermal and junction-leak events, 0.01 to a few Hz per
pixel) and its hot pixels fire alone; an edge moving over the sensor fires neighbouring pixels
within a short time. The filter keeps an event when at least one of the 8 neighbouring sensor
pixels (not the pixel itself: a hot pixel supports only itself) has an event in the same or the
previous time bin of ``window_ns``, bins fixed in absolute sensor time (``t // window_ns``).
Support therefore reaches back between one and two windows, and forward to the end of the
event's own bin. This is the binned form of the classic background-activity filter (support
from the 8 neighbours within a time window), chosen because it is exact under any batching:
the same events give the same output however they are split into pushes.

The filter holds back the events of the newest bin until a later event shows that the bin is
complete (or until :meth:`NeighbourFilter.flush`), so it delays events by at most one window.
Events are in time order; coordinates are checked by the caller (the packetizer).

Public API: ``NeighbourFilter(width, height, window_ns)`` with ``push(ev) -> EventArray``,
``flush() -> EventArray``, ``reset()``, ``pending``, ``kept`` and ``dropped``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.errors import ConfigError

I64 = NDArray[np.int64]

#: The 8 neighbours (dx, dy).
_NEIGHBOURS = tuple((dx, dy) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dx or dy)


class NeighbourFilter:
    """The binned background-activity filter of a ``width`` x ``height`` sensor.

    Each batch is decided with boolean occupancy images, one per time bin that has events
    (padded by one pixel; at most about 16 MB of them at a time): the OR of a bin's and the
    previous bin's image, shifted to each of the 8 neighbours, is looked up at every event.

    Args:
        width: Sensor width in pixels.
        height: Sensor height in pixels.
        window_ns: Bin length (ns, > 0).

    Raises:
        ConfigError: for a non-positive window or size.
    """

    _CHUNK = 1 << 24        # bytes of occupancy images per step

    def __init__(self, width: int, height: int, window_ns: int) -> None:
        if window_ns <= 0 or width <= 0 or height <= 0:
            raise ConfigError(f'NeighbourFilter needs a positive window and sensor size, got '
                              f'window {window_ns} ns, {width}x{height}')
        self.width, self.height, self.window_ns = int(width), int(height), int(window_ns)
        self.kept = 0                   # events passed so far
        self.dropped = 0                # events dropped so far
        self.reset()

    def reset(self) -> None:
        """Forget the held-back bin and the previous bin's pixels (the counters stay)."""
        self._held = EventArray.empty()
        self._prev_bin: int | None = None        # the last decided bin ...
        self._prev_x = np.zeros(0, np.intp)      # ... and its events' padded x, y
        self._prev_y = np.zeros(0, np.intp)

    @property
    def pending(self) -> int:
        """Events held back (the newest bin, not yet complete)."""
        return len(self._held)

    def push(self, ev: EventArray) -> EventArray:
        """Add events (time order) and return the kept events of the bins now complete."""
        if len(ev) == 0:
            return EventArray.empty()
        if len(self._held):
            ev = EventArray.concatenate([self._held, ev])
        bins = ev.t // self.window_ns
        last = int(bins[-1])
        cut = int(np.searchsorted(bins, last, side='left'))   # the newest bin is held back
        self._held = ev[cut:]
        return self._decide(ev[:cut], bins[:cut])

    def flush(self) -> EventArray:
        """The held-back bin, decided now (end of the stream)."""
        ev, self._held = self._held, EventArray.empty()
        return self._decide(ev, ev.t // self.window_ns)

    def _decide(self, ev: EventArray, bins: I64) -> EventArray:
        """Keep the events of complete bins ``bins`` whose neighbours are active."""
        n = len(ev)
        if n == 0:
            return ev
        w, h = self.width, self.height
        x = ev.x.astype(np.intp) + 1            # on a frame padded by one pixel
        y = ev.y.astype(np.intp) + 1
        # compact bin index: only bins with events get an occupancy image
        ub, cb = np.unique(bins, return_inverse=True)
        keep = np.empty(n, bool)
        step = max(1, self._CHUNK // ((w + 2) * (h + 2)))
        starts = np.searchsorted(cb, np.arange(0, len(ub), step))
        ends = np.append(starts[1:], n)
        for lo, hi in zip(starts, ends, strict=True):
            c0 = int(cb[lo])
            c = cb[lo:hi] - c0
            nb = int(c[-1]) + 1
            occ = np.zeros((nb + 1, h + 2, w + 2), bool)     # [0]: the bin before the first
            if self._prev_bin is not None and self._prev_bin == int(ub[c0]) - 1:
                occ[0, self._prev_y, self._prev_x] = True
            occ[c + 1, y[lo:hi], x[lo:hi]] = True
            both = occ[1:].copy()                            # this bin and the one before
            adjacent = np.diff(ub[c0:c0 + nb], prepend=ub[c0] - 1) == 1
            both[adjacent] |= occ[:-1][adjacent]
            nbr = np.zeros((nb, h, w), bool)                 # any of the 8 neighbours
            for dx, dy in _NEIGHBOURS:
                nbr |= both[:, 1 + dy:h + 1 + dy, 1 + dx:w + 1 + dx]
            keep[lo:hi] = nbr[c, y[lo:hi] - 1, x[lo:hi] - 1]
            last = int(ub[c0 + nb - 1])
            sel = slice(int(np.searchsorted(c, nb - 1)), None)
            self._prev_bin = last
            self._prev_x, self._prev_y = x[lo:hi][sel].copy(), y[lo:hi][sel].copy()
        k = int(np.count_nonzero(keep))
        self.kept += k
        self.dropped += n - k
        return ev[keep]
