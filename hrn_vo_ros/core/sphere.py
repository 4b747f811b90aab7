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
the previous frame, readout conventions of :mod:`hrn_vo_ros.core.hrn`), ``P`` the equidistant
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

    def positions(self, flat: NDArray[np.intp], h: float, v: float, r: float
                  ) -> tuple[F64, F64]:
        """Warped (x, y) frame coordinates of the pixels ``flat`` (``y * width + x``).

        Args:
            flat: Flat indices of the pixels to move.
            h, v: Camera position on the chart (frame pixels), r: roll (rad), as read out.

        Shapes:
            flat: (n,); returns two (n,) arrays.
        """
        d = self.rays[:, flat]
        cr, sr = math.cos(r), math.sin(r)
        x = cr * d[0] - sr * d[1]                  # Rz(r): roll about the optical axis
        y = sr * d[0] + cr * d[1]
        z = d[2]
        dist = math.hypot(h, v)
        if dist > 1e-12:                           # swing: Rodrigues about k = e_z × dir(c)
            a = dist / self.f
            kx, ky = -v / dist, h / dist
            ca, sa = math.cos(a), math.sin(a)
            kd = kx * x + ky * y                   # k · d (k_z = 0)
            x, y, z = (x * ca + ky * z * sa + kx * kd * (1 - ca),
                       y * ca - kx * z * sa + ky * kd * (1 - ca),
                       z * ca + (kx * y - ky * x) * sa)
        # P: equidistant projection, radius f·θ along the ray's image direction
        s = np.hypot(x, y)
        off_axis = s > 1e-12                       # on the axis f·θ/s -> f
        k = np.where(off_axis, self.f * np.arctan2(s, z) / np.where(off_axis, s, 1.0), self.f)
        mx, my = k * x - h, k * y - v
        return cr * mx + sr * my + self.cx, -sr * mx + cr * my + self.cy

    def warp(self, image: NDArray[np.generic], h: float, v: float, r: float) -> F64:
        """The frame with every on-pixel moved (bilinear splat, weight = pixel value).

        Shapes:
            image: (height, width); returns (height, width) float64.
        """
        flat = np.flatnonzero(image)
        vals = np.asarray(image, dtype=np.float64).ravel()[flat]
        px, py = self.positions(flat, h, v, r)
        w, hgt = self.width, self.height
        # splat on a frame padded by one pixel (no per-corner bounds checks), then crop; a
        # pixel moved further out than the padding is dropped
        px = np.clip(px + 1.0, 0.0, w + 1.0 - 1e-9)
        py = np.clip(py + 1.0, 0.0, hgt + 1.0 - 1e-9)
        x0, y0 = np.floor(px), np.floor(py)
        fx, fy = px - x0, py - y0
        wp = w + 2
        base = (y0 * wp + x0).astype(np.intp)
        gx, gy = 1.0 - fx, 1.0 - fy
        idx = np.concatenate((base, base + 1, base + wp, base + wp + 1))
        wts = np.concatenate((gx * gy, fx * gy, gx * fy, fx * fy))
        wts *= np.tile(vals, 4)
        out = np.bincount(idx, weights=wts, minlength=wp * (hgt + 2)).reshape(hgt + 2, wp)
        return np.asarray(out[1:-1, 1:-1], dtype=np.float64)
