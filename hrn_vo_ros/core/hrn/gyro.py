"""The gyro's prediction in the HRN's coordinates, and the online estimate of the gyro's bias.

Mapping (Model A, small angles; ``docs/model.md``, IMU prediction): a camera rotation
``theta`` (rad, camera axes x right, y down, z forward) moves the image content by
``d = (-f theta_y, +f theta_x)`` pixels and turns it by ``-theta_z``; the map-frame shift
binds ``Rot(-alpha) d`` into ``h, v`` (``alpha`` the current content angle) and
``-theta_z / unit_r`` into ``r``. :func:`rotation_of_shift` is the inverse: the rotation a
difference of readouts stands for.

That is the first order. With the sphere correction the map is the sphere's chart (:mod:`.sphere`)
and :func:`chart_shift_of_rotation` binds exactly: the pose's camera rotation (swing-twist)
times the gyro's, read on the chart again.

Bias ([design]; ``imu.bias_memory_s``, 30 s in the rotation config, off elsewhere): while vision
tracks, the readout minus the gyro's prediction (the innovation) measures the gyro's error over
the frame, ``-(bias - b) dt``, plus the readout's error; :class:`GyroBias` averages it over the
tracked time with a prior of zero bias, and the predictions subtract the estimate, so that the
gyro alone drifts less while vision is lost. It is only as good as vision's motion over the
tracked stretch (docs/model.md, section 6, and docs/results.md for what that costs).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.hrn.shared import centred_mod
from hrn_vo_ros.core.odometry.geometry import turn_swing_twist

F64 = NDArray[np.float64]


def shift_of_rotation(theta: F64, focal_px: float, alpha: float, unit_r: float
                      ) -> dict[str, float]:
    """The map-frame binding (h, v in pixels, r in index units) of a camera rotation.

    Shapes:
        theta: (3,) rad.
    """
    dx, dy = -focal_px * float(theta[1]), focal_px * float(theta[0])
    ca, sa = math.cos(alpha), math.sin(alpha)
    return {'h': ca * dx + sa * dy, 'v': -sa * dx + ca * dy, 'r': -float(theta[2]) / unit_r}


def chart_shift_of_rotation(theta: F64, focal_px: float, h: float, v: float, alpha: float,
                            unit_r: float) -> dict[str, float]:
    """:func:`shift_of_rotation` on the sphere's chart, exactly: the pose ``(h, v, alpha)``
    turned by ``theta`` (camera axes, rad) and read on the chart again; ``r`` in index units
    (``unit_r`` rad each), the change of ``alpha`` taken within half a turn.

    The chart pose is the swing-twist rotation (:mod:`hrn_vo_ros.core.odometry.geometry`) of
    pan ``-h / f``, tilt ``v / f`` and roll ``-alpha``: the signs for which
    :func:`shift_of_rotation` is its first order. That first order is the same everywhere on
    the chart; the chart is not flat (a loop of pans and tilts also turns the camera about its
    axis), so far from its centre it errs by degrees: the ideal gyro alone, bound at first
    order, drifted 1-11° on fast draws of the family (``docs/results.md``).

    Shapes:
        theta: (3,).
    """
    f = focal_px
    pan, tilt, roll = turn_swing_twist((-h / f, v / f, -alpha), theta)
    return {'h': -f * pan - h, 'v': f * tilt - v,
            'r': float(centred_mod(-roll - alpha, 2.0 * math.pi)) / unit_r}


def rotation_of_shift(d: dict[str, float], focal_px: float, alpha: float, unit_r: float
                      ) -> F64:
    """The camera rotation (rad, camera axes) whose binding is ``d``: inverse of
    :func:`shift_of_rotation`.

    Shapes:
        returns (3,).
    """
    ca, sa = math.cos(alpha), math.sin(alpha)
    dx = ca * d['h'] - sa * d['v']
    dy = sa * d['h'] + ca * d['v']
    return np.array([dy / focal_px, -dx / focal_px, -d['r'] * unit_r])


def rotation_deg(d: dict[str, float], focal_px: float, unit_r: float) -> float:
    """The largest angle of a binding: roll ``|r| unit_r``, pan/tilt ``atan(|h|, |v| / f)``
    (degrees)."""
    return math.degrees(max(abs(d['r']) * unit_r, math.atan(abs(d['h']) / focal_px),
                            math.atan(abs(d['v']) / focal_px)))


class GyroBias:
    """Running estimate of the gyro's bias from the innovations of tracked frames.

    Each tracked frame's gyro error ``u = b dt - innovation`` (the innovation, readout minus
    the prediction made with the bias ``b`` then applied, as a camera rotation) is summed,
    ``U``, with its time ``T``, both forgotten with time constant ``memory_s``; the estimate is
    ``U / (T + prior_s)``: a prior of zero bias weighted as ``prior_s`` seconds of tracking, so
    a few frames cannot set a large bias. Consecutive readout errors cancel in ``U`` (a readout
    is absolute against the map), so its noise is about twice one readout's over ``T +
    prior_s``.

    Args:
        memory_s: Forgetting time constant (s); 0 turns the estimate off (``b`` stays 0).
        prior_s: Weight of the zero-bias prior (s of tracking).
        max_rad_s: Bound on each component of ``b`` (rad/s).
    """

    def __init__(self, memory_s: float, prior_s: float, max_rad_s: float) -> None:
        self.memory_s = memory_s
        self.prior_s = prior_s
        self.max_rad_s = max_rad_s
        self.reset()

    @property
    def enabled(self) -> bool:
        """Whether the estimate runs (``memory_s > 0``)."""
        return self.memory_s > 0.0

    def reset(self) -> None:
        self.b = np.zeros(3)
        self._u = np.zeros(3)
        self._t = 0.0
        self.updates = 0

    def correct(self, gyro_delta: F64, dt_s: float) -> F64:
        """The integrated gyro over ``dt_s`` without the estimated bias.

        Shapes:
            gyro_delta: (3,) rad; returns (3,).
        """
        return np.asarray(gyro_delta, np.float64) - self.b * dt_s

    def update(self, innovation: F64, dt_s: float) -> None:
        """Add one tracked frame: its innovation (readout minus prediction as a camera
        rotation in rad, :func:`rotation_of_shift`) over its ``dt_s`` seconds.

        Shapes:
            innovation: (3,).
        """
        if not self.enabled or dt_s <= 0.0:
            return
        keep = math.exp(-dt_s / self.memory_s)
        self._u = keep * self._u + (self.b * dt_s - np.asarray(innovation, np.float64))
        self._t = keep * self._t + dt_s
        self.b = np.clip(self._u / (self._t + self.prior_s), -self.max_rad_s, self.max_rad_s)
        self.updates += 1
