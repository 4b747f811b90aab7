"""The background rate of an event stream, measured on its first full window.

An event camera's background activity (thermal and junction-leak events, 0.01 to about 1 Hz
per pixel) fires everywhere, all the time; the scene's events come with motion. Sequences start
with the camera at rest or slow (the Event Camera Dataset's and the simulator family's motions
ramp up from rest), so the event rate of the stream's first full window, per sensor pixel, is
the background rate (an upper bound of it when the camera already moves fast).
:class:`BackgroundRate` measures it once: the first window that starts after the first event
(windows fixed in absolute sensor time, ``t // window_ns``, so that the same events give the
same rate however they are split into pushes), decided as soon as an event after that window
arrives. The packetizer freezes its pixel threshold on it (``noise_floor_hz``): frames whose
threshold changed under a running map would no longer match it.

Public API: ``BackgroundRate(pixels, window_ns)`` with ``push(t) -> rate or None``,
``reset()`` and the attribute ``rate_hz`` (None until measured).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.errors import ConfigError


class BackgroundRate:
    """Events per second per pixel of a ``pixels``-pixel sensor over its first full window.

    Args:
        pixels: Sensor pixels the events come from (width x height).
        window_ns: Window length (ns, > 0).

    Raises:
        ConfigError: for a non-positive window or pixel count.
    """

    def __init__(self, pixels: int, window_ns: int) -> None:
        if pixels <= 0 or window_ns <= 0:
            raise ConfigError(f'BackgroundRate needs positive pixels and window, got {pixels} '
                              f'pixels, window {window_ns} ns')
        self.pixels, self.window_ns = int(pixels), int(window_ns)
        self.reset()

    def reset(self) -> None:
        """Measure again from the next event on."""
        self.rate_hz: float | None = None     # the measured rate (None: not yet)
        self._window: int | None = None       # index of the measured window
        self._count = 0                       # its events so far

    def push(self, t: NDArray[np.int64]) -> float | None:
        """Count the events at times ``t`` (ns, in time order); the rate once an event after
        the measured window has arrived, else None."""
        if self.rate_hz is not None or len(t) == 0:
            return self.rate_hz
        w = self.window_ns
        if self._window is None:
            self._window = int(t[0]) // w + 1       # the first window after the first event
        start, end = self._window * w, (self._window + 1) * w
        lo, hi = np.searchsorted(t, [start, end], side='left')
        self._count += int(hi - lo)
        if hi < len(t):                             # an event after the window: complete
            self.rate_hz = self._count * 1e9 / (w * self.pixels)
        return self.rate_hz
