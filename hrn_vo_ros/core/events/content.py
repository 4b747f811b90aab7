"""How much scene an event frame carries, from the frame alone: numbers only.

A frame of moving edges lights pixels in lines and blobs; a frame of background noise and hot
pixels lights them scattered. :func:`neighbour_ratio` counts the pairs of on pixels that are
4-neighbours and divides by the count expected of the same number of on pixels placed
uniformly at random (sampling without replacement)::

    E[pairs] = (H (W - 1) + W (H - 1)) n (n - 1) / (N (N - 1)),    N = H W

so scattered noise gives about 1, thin edges at a density rho about 1 / (2 rho) and solid
blobs about 1 / rho. It needs no simulator: the robustness benchmark reports it per draw
(:func:`frame_structure`, the median over a draw's frames) next to the simulator's own figures,
and it reads the same on recordings.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: Below this :func:`neighbour_ratio` frames are about as scattered as noise: a blank view, a
#: pause on a noisy sensor or hot pixels alone (fresh rotation draws 10240-10359: the float
#: network tracked 1 of the 13 draws whose median frame lies below it, 78 of the 107 above).
NOISE_LIKE = 1.5


def neighbour_ratio(frame: NDArray[Any]) -> float:
    """Pairs of 4-neighbouring on pixels over their count under uniform random placement.

    Args:
        frame: A 2-D event frame; a pixel is on where it is non-zero.

    Returns:
        The ratio (1: as scattered as noise; larger: lines and blobs), NaN for a frame with
        fewer than two on pixels or no neighbouring pixel positions.
    """
    on = np.asarray(frame) != 0
    if on.ndim != 2:
        raise ValueError(f'neighbour_ratio needs a 2-D frame, got shape {on.shape}')
    h, w = on.shape
    n = int(on.sum())
    slots = h * (w - 1) + w * (h - 1)
    cells = h * w
    if n < 2 or slots == 0:
        return math.nan
    pairs = int(np.count_nonzero(on[:, 1:] & on[:, :-1]) + np.count_nonzero(on[1:] & on[:-1]))
    expected = slots * n * (n - 1) / (cells * (cells - 1))
    return float(pairs / expected)


def frame_structure(frames: NDArray[Any]) -> float:
    """Median :func:`neighbour_ratio` over a stack of frames (NaN frames left out; NaN when
    none is left). Shapes: frames (n, H, W)."""
    r = np.array([neighbour_ratio(f) for f in frames], np.float64)
    r = r[np.isfinite(r)]
    return float(np.median(r)) if r.size else math.nan
