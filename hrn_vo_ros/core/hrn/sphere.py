"""Sphere correction: the non-rigid part of a camera rotation, removed from each event frame.

A rotating camera sees the sphere of view directions; the HRN (and the baseline) model the
frame as a shifted and rolled copy of a flat map. With equidistant-rectified frames (radius =
f · angle from the optical axis, ``packetizer.rectify: equidistant``) the map is, to first
order, the azimuthal equidistant chart of the sphere about the first optical axis, and a pan or
tilt is a shift of the frame on that chart only near its centre: away from it the chart
stretches (by θ / sin θ across the radius) and bends. Fitting a rigid shift and roll to that
field biases the roll by a content-dependent amount (simulated shapes_rotation, swing 17°:
0.5–0.7° for the rigid fit of the exact mapping weighted by the frame's edges).

:class:`SphereWarp` moves every on-pixel ``u`` (frame pixels about the frame centre) to

    ``u' = Rot(-r) (P(S · Rz(r) · P⁻¹(u)) - c)``,

where ``c = (h, v)`` is the camera position on the chart, ``r`` the roll (the pose estimate of
the previous frame, readout conventions of ``docs/model.md``), ``P`` the equidistant
projection with focal length ``f`` (frame pixels), ``Rz(r)`` the roll about the optical axis and
``S`` the swing (the rotation about an axis in the image plane) that turns the optical axis to
``P⁻¹(c)``. For the exact pose, ``c + Rot(r) u'`` is the chart point the pixel sees, so the
warped frame is exactly the rigid transform of the chart that the resonator assumes; with the
previous frame's pose the remaining error is second order in the motion between frames. With
``c = 0`` the warp is the identity. Each pixel is splatted bilinearly (weights sum to its value)
into an image of the frame's size; content warped outside the frame is dropped (a pixel warped
more than one pixel out is clipped to the border ring first, then dropped with it).

Conventions: image x right, y down, optical axis z forward (camera frame of REP-103's optical
frame); ``Rot(a)`` turns from +x towards +y.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.errors import ConfigError

F64 = NDArray[np.float64]

MAX_SWING_RAD = math.pi / 2     # beyond it SphereWarp.warp passes frames through unwarped


class SphereWarp:
    """Per-frame warp of equidistant-rectified event frames (module docstring).

    Args:
        width, height: Frame size in pixels.
        focal_px: Focal length of the equidistant frames in frame pixels (fx / downsample).

    Raises:
        ConfigError: if ``focal_px`` is not positive.
    """

    def __init__(self, width: int, height: int, focal_px: float) -> None:
        if not focal_px > 0.0:
            raise ConfigError('the sphere correction needs the focal length: set focal_px to '
                              'fx / downsample in frame pixels (hrn-vo run derives it from '
                              'calib.txt)')
        self.width, self.height, self.f = width, height, float(focal_px)
        self.cx, self.cy = (width - 1) / 2.0, (height - 1) / 2.0
        yy, xx = np.mgrid[0:height, 0:width].astype(np.float64)
        ux, uy = (xx - self.cx).ravel(), (yy - self.cy).ravel()
        th = np.hypot(ux, uy) / self.f
        st = np.sinc(th / np.pi) / self.f          # sin(θ) / |u|, finite at the centre
        # unit ray P⁻¹(u) of every frame pixel, (3, H·W)
        self.rays = np.stack([ux * st, uy * st, np.cos(th)])
        self._padded_width = width + 2
        self._padded_size = (width + 2) * (height + 2)
        self._upper = np.array([[width + 1.0 - 1e-9], [height + 1.0 - 1e-9]])
        self._corners = np.array([[0, 1], [width + 2, width + 3]], np.intp)[:, :, None]

    def _transform(self, h: float, v: float, r: float) -> tuple[F64, F64]:
        """``(R, o)`` with ``u' = k(R d) · (R d)_xy + o`` for the ray ``d`` of pixel ``u``.

        The projection P is radially symmetric, so the final ``Rot(-r)`` moves into the ray
        rotation: ``R = Rz(-r) · S · Rz(r)`` and ``o = centre - Rot(-r) c``.
        """
        cr, sr = math.cos(r), math.sin(r)
        rz = np.array([[cr, -sr, 0.0], [sr, cr, 0.0], [0.0, 0.0, 1.0]])
        offset = np.array([[self.cx - (cr * h + sr * v)], [self.cy - (-sr * h + cr * v)]])
        dist = math.hypot(h, v)
        if dist <= 1e-12:
            return np.eye(3), offset
        # swing: Rodrigues about k = e_z × dir(c) by a = |c| / f, as one matrix
        a = dist / self.f
        kx, ky = -v / dist, h / dist
        ca, sa = math.cos(a), math.sin(a)
        t = 1.0 - ca
        swing = np.array([[ca + t * kx * kx, t * kx * ky, sa * ky],
                          [t * kx * ky, ca + t * ky * ky, -sa * kx],
                          [-sa * ky, sa * kx, ca]])
        return rz.T @ swing @ rz, offset

    def _moved(self, flat: NDArray[np.intp], h: float, v: float, r: float) -> F64:
        """Warped (x, y) of the pixels ``flat`` as a (2, n) array (see :meth:`positions`)."""
        rot, offset = self._transform(h, v, r)
        d: F64 = rot @ np.take(self.rays, flat, axis=1)
        x, y = d[0], d[1]
        s = np.sqrt(x * x + y * y)
        np.maximum(s, 1e-12, out=s)                # on the axis f·θ/s -> f / z
        k = np.arctan2(s, d[2])                    # P: equidistant, radius f·θ
        k *= self.f
        k /= s
        xy = d[:2]
        xy *= k
        xy += offset
        return xy

    def positions(self, flat: NDArray[np.intp], h: float, v: float, r: float
                  ) -> tuple[F64, F64]:
        """Warped (x, y) frame coordinates of the pixels ``flat`` (``y * width + x``).

        Args:
            flat: Flat indices of the pixels to move.
            h, v: Camera position on the chart (frame pixels), r: roll (rad), as read out.

        Shapes:
            flat: (n,); returns two (n,) arrays.
        """
        xy = self._moved(flat, h, v, r)
        return xy[0], xy[1]

    def warp(self, image: NDArray[np.generic], h: float, v: float, r: float) -> F64:
        """The frame with every on-pixel moved (bilinear splat, weight = pixel value).

        A pose whose optical axis is more than :data:`MAX_SWING_RAD` (90°) from the chart's
        centre, or not finite, is no pose the correction can model (a lost track reads out
        thousands of pixels): the frame is returned unwarped, so that it still reaches the
        resonator instead of being warped off the frame.

        Shapes:
            image: (height, width); returns (height, width) float64.
        """
        if not (math.hypot(h, v) <= MAX_SWING_RAD * self.f and math.isfinite(r)):
            return np.asarray(image, dtype=np.float64)
        flat = np.flatnonzero(np.asarray(image) != 0)     # (a bool mask: 4x faster than on floats)
        vals = np.take(np.ravel(image), flat).astype(np.float64, copy=False)
        # splat on a frame padded by one pixel (no per-corner bounds checks), then crop; a
        # pixel moved further out than the padding is dropped
        # (weight of the low/high corner, x/y, pixel); p: the high corner's, in place
        g = np.empty((2, 2, flat.shape[0]))
        p = g[1]
        np.add(self._moved(flat, h, v, r), 1.0, out=p)
        np.maximum(p, 0.0, out=p)                  # (as np.clip, which takes longer)
        np.minimum(p, self._upper, out=p)
        p0 = np.floor(p)
        p -= p0                                    # fractional part, (x, y) rows
        base = (p0[1] * self._padded_width + p0[0]).astype(np.intp)
        np.subtract(1.0, p, out=g[0])
        wts = g[:, None, 1, :] * g[None, :, 0, :]  # (dy, dx, pixel)
        wts *= vals
        idx = base + self._corners                 # (dy, dx, pixel)
        out = np.bincount(idx.ravel(), weights=wts.ravel(), minlength=self._padded_size)
        out = out.reshape(self.height + 2, self._padded_width)
        return np.asarray(out[1:-1, 1:-1], dtype=np.float64)
