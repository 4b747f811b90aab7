"""The hot-pixel mask of the resonator's input frames (``hot_pixel_rate``, ``hot_pixel_on``).

Hot or flickering pixels stay put while the scene moves: left in a frame, they pull the
estimate towards standing still. :class:`HotPixelMask` keeps a running on-fraction of every
frame pixel and zeroes the pixels on in more than ``hot_pixel_on`` of the recent frames; a
frame whose on pixels would be mostly masked is a still view of real edges (frames made
without motion), not hot pixels, and is left whole. Numbers only (numpy).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


class HotPixelMask:
    """Running on-fraction of each frame pixel and the mask it gives.

    Args:
        width, height: Frame size in pixels.
        rate: Rate of the running on-fraction (0: no mask).
        on: Fraction above which a pixel that is on counts as hot.

    Attributes:
        masked: On pixels masked as hot in the last frame.
    """

    def __init__(self, width: int, height: int, rate: float, on: float) -> None:
        self.width, self.height = width, height
        self.rate, self.on = rate, on
        self.reset()

    def reset(self) -> None:
        self._frac = np.zeros((self.height, self.width))
        self.masked = 0

    def apply(self, img: NDArray[np.float64]) -> NDArray[np.float64]:
        """The frame without its hot pixels (the frame itself when none is masked); updates
        the running on-fraction with the frame's on pixels.

        Shapes:
            img: (height, width); returns the same.
        """
        a = self.rate
        if a <= 0.0:
            return img
        f = self._frac
        on = img > 0.0
        hot = (f > self.on) & on
        f *= 1.0 - a
        f += a * on
        n_hot = int(np.count_nonzero(hot))      # (usually none: then no count of on)
        self.masked = n_hot if n_hot and 2 * n_hot <= int(np.count_nonzero(on)) else 0
        return np.where(hot, 0.0, img) if self.masked else img
