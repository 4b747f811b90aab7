"""Camera model: radial-tangential (plumb-bob) distortion and rectification of sensor pixels.

The Event Camera Dataset's ``calib.txt`` and ``sensor_msgs/CameraInfo`` (``plumb_bob``) describe
the same model: a pixel ``(u, v)`` sees the ray ``(x, y, 1)`` of normalised undistorted
coordinates with

    r² = x² + y²,  s = 1 + k1 r² + k2 r⁴ + k3 r⁶
    x_d = x s + 2 p1 x y + p2 (r² + 2 x²),  y_d = y s + p1 (r² + 2 y²) + 2 p2 x y
    u = fx x_d + cx,  v = fy y_d + cy.

**Rectification** moves every sensor pixel to where an ideal camera would have seen its ray, in
continuous sensor-pixel coordinates, with the principal point moved to the sensor centre
``((W - 1)/2, (H - 1)/2)`` (the centre of the event frame, about which the HRN's log-polar
partition measures roll):

* ``pinhole``: ``(fx x, fy y)`` — straight lines stay straight, but the image of a camera rotation
  stretches towards the border (a pan by θ moves the centre by f·θ and the border by more);
* ``equidistant``: ``(fx x, fy y) · atan(ρ)/ρ`` with ``ρ = |(x, y)|``, the radius proportional to
  the ray's angle from the optical axis (r = f·θ). A camera rotation about the optical axis is an
  exact image rotation about the centre in every model; pan and tilt are closest to image shifts
  in this one, which is what the Cartesian partition of the HRN assumes.

Only the rays are remapped (a per-pixel lookup table built once): events keep their times.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

RECTIFY_MODES = ('none', 'pinhole', 'equidistant')
_UNDISTORT_ITERATIONS = 30

F64 = NDArray[np.float64]


def undistort_points(fx: float, fy: float, cx: float, cy: float,
                     dist: tuple[float, ...], u: Any, v: Any) -> tuple[F64, F64]:
    """Normalised undistorted coordinates of distorted pixel coordinates (fixed point).

    Args:
        fx, fy, cx, cy: Pinhole intrinsics in pixels.
        dist: ``(k1, k2, p1, p2, k3)``.
        u, v: Pixel coordinates, any matching shapes.

    Returns:
        ``(x, y)``, the same shape as ``u``.
    """
    xd = (np.asarray(u, dtype=np.float64) - cx) / fx
    yd = (np.asarray(v, dtype=np.float64) - cy) / fy
    k1, k2, p1, p2, k3 = dist
    x, y = xd.copy(), yd.copy()
    for _ in range(_UNDISTORT_ITERATIONS):
        r2 = x * x + y * y
        radial = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 ** 3
        dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        x = (xd - dx) / radial
        y = (yd - dy) / radial
    return x, y


def distort_points(fx: float, fy: float, cx: float, cy: float,
                   dist: tuple[float, ...], x: Any, y: Any) -> tuple[F64, F64]:
    """Pixel coordinates of normalised undistorted coordinates (the inverse of the above)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    k1, k2, p1, p2, k3 = dist
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 ** 3
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return fx * xd + cx, fy * yd + cy


def rectified_pixels(mode: str, width: int, height: int, fx: float, fy: float, cx: float,
                     cy: float, dist: tuple[float, ...]) -> tuple[F64, F64]:
    """Rectified continuous coordinates of every sensor pixel (see the module docstring).

    Args:
        mode: ``pinhole`` or ``equidistant`` (``none`` returns the pixel grid itself).
        width, height: Sensor size in pixels.
        fx, fy, cx, cy, dist: Calibration of the sensor.

    Returns:
        ``(xr, yr)``, each (height, width) float64, indexed ``[y, x]`` by sensor pixel.

    Raises:
        ValueError: for an unknown mode (configs validate it before this is called).
    """
    if mode not in RECTIFY_MODES:
        raise ValueError(f'unknown rectification {mode!r}; use one of {", ".join(RECTIFY_MODES)}')
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float64)
    if mode == 'none':
        return xx, yy
    x, y = undistort_points(fx, fy, cx, cy, dist, xx, yy)
    if mode == 'equidistant':
        rho = np.hypot(x, y)
        safe = np.where(rho > 1e-12, rho, 1.0)
        scale = np.where(rho > 1e-12, np.arctan(rho) / safe, 1.0)
        x, y = x * scale, y * scale
    return fx * x + (width - 1) / 2, fy * y + (height - 1) / 2
