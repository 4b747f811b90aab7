"""The background rate of an event stream, measured on its first full window.

An event camera's background activity (thermal and junction-leak events, 0.01 to about 1 Hz
per pixel) fires everywhere, all the time, one lone event at a time; the scene's events come
with motion, along edges, several pixels and events together. :class:`BackgroundRate` measures
both on the stream's first full window (windows fixed in absolute sensor time,
``t // window_ns``, so that the same events give the same figures however they are split into
pushes; decided as soon as an event after that window arrives):

* ``total_hz``: all events, per second and sensor pixel;
* ``rate_hz``: the *isolated* events, those with no other event in their 3x3 pixel
  neighbourhood (their own pixel included) within the same or an adjacent time bin of
  ``isolation_ns`` (bins counted from the window's start). Background events are isolated
  unless two fall together (at rate ``r``, a fraction ``exp(-27 r isolation)`` of them is:
  0.87 at 1 Hz and 5 ms); an edge's events have neighbours, a hot pixel's repeat;
* ``share``: isolated events over all events.

A textured scene in motion also makes many isolated events (fine, low-contrast texture: up to
about 1.5 Hz per pixel in the simulator family), but with its many other events the share
stays lower than on a noisy sensor watching a quiet scene, where nearly every event is alone.
The packetizer freezes its pixel threshold on both (``noise_floor_hz``, ``noise_share``):
frames whose threshold changed under a running map would no longer match it.

Memory: three time bins of per-pixel counts at a time (int32, about 11 MB on a 1280x720
sensor), whatever the window and event rate.

Public API: ``BackgroundRate(width, height, window_ns, isolation_ns)`` with
``push(t, x, y) -> rate or None``, ``reset()`` and the attributes ``rate_hz``, ``total_hz``,
``share`` (None until measured).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.arrays import runs
from hrn_vo_ros.errors import ConfigError

I32 = NDArray[np.int32]


class BackgroundRate:
    """Isolated and total events per second per pixel over a stream's first full window.

    Args:
        width, height: Sensor size in pixels.
        window_ns: Window length (ns, > 0).
        isolation_ns: Time bin of the isolation test (ns, > 0; at most the window).

    Raises:
        ConfigError: for a non-positive size, window or bin, or a bin longer than the window.
    """

    def __init__(self, width: int, height: int, window_ns: int, isolation_ns: int) -> None:
        if width <= 0 or height <= 0 or window_ns <= 0 or not 0 < isolation_ns <= window_ns:
            raise ConfigError(f'BackgroundRate needs a positive sensor size, window and '
                              f'isolation bin no longer than the window, got {width}x{height}, '
                              f'window {window_ns} ns, bin {isolation_ns} ns')
        self.width, self.height = int(width), int(height)
        self.window_ns, self.isolation_ns = int(window_ns), int(isolation_ns)
        self.reset()

    def reset(self) -> None:
        """Measure again from the next event on."""
        self.rate_hz: float | None = None     # isolated events, Hz per pixel (None: not yet)
        self.total_hz: float | None = None    # all events, Hz per pixel
        self.share: float | None = None       # isolated / all (0 for an empty window)
        self._window: int | None = None       # index of the measured window
        self._count = 0                       # its events so far
        self._isolated = 0                    # its isolated events in decided bins
        self._bins: dict[int, I32] = {}       # counts of the bins not yet decided (and k-1)
        self._done = -1                       # bins below this are decided

    def push(self, t: NDArray[np.int64], x: NDArray[np.integer],
             y: NDArray[np.integer]) -> float | None:
        """Count the events at times ``t`` (ns, in time order) and pixels ``(x, y)`` (inside
        the sensor); the isolated rate once an event after the measured window has arrived,
        else None."""
        if self.rate_hz is not None or len(t) == 0:
            return self.rate_hz
        w, b = self.window_ns, self.isolation_ns
        if self._window is None:
            self._window = int(t[0]) // w + 1       # the first window after the first event
        start, end = self._window * w, (self._window + 1) * w
        lo, hi = (int(i) for i in np.searchsorted(t, [start, end], side='left'))
        if hi > lo:
            self._count += hi - lo
            k = (t[lo:hi] - start) // b                               # bin of each event
            for a, e in runs(k):
                kb = int(k[a])
                self._decide(kb - 2)        # the bins before kb are complete (time order)
                cell = y[lo + a:lo + e].astype(np.int64) * self.width + x[lo + a:lo + e]
                add = np.bincount(cell, minlength=self.width * self.height)
                self._bins[kb] = self._slab(kb) + add.reshape(self.height, self.width)
        if hi < len(t):                             # an event after the window: complete
            self._decide(-(-w // b))                # every bin of the window (ceil(w / b))
            px = self.width * self.height
            self.rate_hz = self._isolated * 1e9 / (w * px)
            self.total_hz = self._count * 1e9 / (w * px)
            self.share = self._isolated / self._count if self._count else 0.0
            self._bins = {}
        return self.rate_hz

    def _slab(self, k: int) -> I32:
        got = self._bins.get(k)
        return got if got is not None else np.zeros((self.height, self.width), np.int32)

    def _decide(self, last: int) -> None:
        """Count the isolated events of every bin up to ``last`` not yet decided (bin k needs
        bins k-1 and k+1 complete)."""
        for k in range(self._done + 1, last + 1):
            c = self._bins.get(k)
            if c is not None:
                s = np.pad(self._slab(k - 1) + c + self._slab(k + 1), 1)
                h, w = self.height, self.width
                box = sum(s[dy:dy + h, dx:dx + w] for dy in range(3) for dx in range(3))
                self._isolated += int(np.count_nonzero((c == 1) & (box == 1)))
            self._bins.pop(k - 1, None)
        self._done = max(self._done, last)
