"""Synthetic event frames from a known camera motion over a random 'shapes' scene (test helper).

Model: the camera looks at a planar scene image; at pose (x, y, roll, log_zoom) the frame pixel p
shows the scene at ``R(roll) (p - c) e^{-log_zoom} + c + (x, y) + origin`` (camera position
(x, y) in scene pixels, roll right-handed about the optical axis, so content turns by -roll).
Event frames are the pixels whose rendered view changes between two nearby poses (edges that
moved), like the events of a real sensor.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage


def random_scene(rng: np.random.Generator, size: int = 320, n_shapes: int = 60
                 ) -> NDArray[np.float64]:
    """A binary scene of random filled rectangles and discs (the 'shapes' texture)."""
    img = np.zeros((size, size))
    yy, xx = np.mgrid[0:size, 0:size]
    for _ in range(n_shapes):
        cx, cy = rng.uniform(0, size, 2)
        r = rng.uniform(4, 16)
        if rng.random() < 0.5:
            m = (xx - cx) ** 2 + (yy - cy) ** 2 < r * r
        else:
            a = rng.uniform(0, np.pi)
            u = (xx - cx) * np.cos(a) + (yy - cy) * np.sin(a)
            w = -(xx - cx) * np.sin(a) + (yy - cy) * np.cos(a)
            m = (np.abs(u) < r) & (np.abs(w) < r * rng.uniform(0.4, 1.0))
        img[m] = 1.0 - img[m]
    return img


def render(scene: NDArray[np.float64], pose: tuple[float, float, float, float],
           width: int = 96, height: int = 72) -> NDArray[np.float64]:
    """Frame intensity at pose (x, y, roll, log_zoom); the scene centre is the origin."""
    x, y, roll, lz = pose
    c = np.array([(width - 1) / 2, (height - 1) / 2])
    yy, xx = np.mgrid[0:height, 0:width]
    px, py = xx - c[0], yy - c[1]
    k = np.exp(-lz)
    cr, sr = np.cos(roll), np.sin(roll)
    sx = k * (cr * px - sr * py) + scene.shape[1] / 2 + x
    sy = k * (sr * px + cr * py) + scene.shape[0] / 2 + y
    return ndimage.map_coordinates(scene, [sy, sx], order=1, mode='constant')


def event_frame(scene: NDArray[np.float64], pose: tuple[float, float, float, float],
                rng: np.random.Generator, *, width: int = 96, height: int = 72,
                noise: float = 0.002) -> NDArray[np.uint8]:
    """Binary event frame: edges of the view at ``pose`` (gradient), plus sparse noise."""
    img = render(scene, pose, width, height)
    gx = np.abs(np.diff(img, axis=1, prepend=img[:, :1]))
    gy = np.abs(np.diff(img, axis=0, prepend=img[:1, :]))
    ev = (gx + gy) > 0.3
    ev &= rng.random(ev.shape) < 0.8
    ev |= rng.random(ev.shape) < noise
    return ev.astype(np.uint8)


def trajectory(n: int, *, amp_xy: float = 0.0, amp_roll: float = 0.0, amp_zoom: float = 0.0,
               period: float = 200.0) -> NDArray[np.float64]:
    """Smooth poses (n, 4): sines with different phases, starting at 0."""
    t = np.arange(n)
    w = 2 * np.pi / period
    return np.stack([amp_xy * np.sin(w * t), amp_xy * np.sin(1.3 * w * t) * 0.7,
                     amp_roll * np.sin(0.8 * w * t), amp_zoom * np.sin(1.1 * w * t)], axis=1)
