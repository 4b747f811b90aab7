"""The pose the HRN reports (``docs/model.md``, sections 5 and 9): numbers only.

The network reads its factors out as codebook indices; :class:`ReportedPose` turns them into
the physical pose it outputs. Three things happen on the way: periodic factors are unwrapped
against the last tracked pose (the wild readouts of poor frames cannot carry the pose a whole
canvas away or turn it around); poor frames output the last tracked pose instead of their
readout (unless the gyro carried the states); and the poses on the current map are composed
with that map's origin in the output's frame (moved by each bootstrap restart): as planar
similarities, or, on the sphere's chart (the sphere correction), as the camera rotations they are.

Public API: ``ReportedPose(chart_focal_px=0.0)`` with ``reset()``, ``update(point, books,
hold=, tracking=)``, ``restart()``, ``compose(pose)`` and the attributes ``raw`` (the
network's own pose on the current map: physical, unwrapped), ``out`` (the output), ``held``
(the last tracked pose on the map, None before one) and ``origin``.
"""

from __future__ import annotations

from collections.abc import Mapping
import math

from hrn_vo_ros.core.hrn.shared import centred_mod, FactorCodebook
from hrn_vo_ros.core.odometry.geometry import compose_swing_twist

POSE_KEYS = ('h', 'v', 'r', 'z')


class ReportedPose:
    """Unwrap, hold and the map's origin: from a readout (index units) to the output pose.

    Args:
        chart_focal_px: The focal length (frame pixels) when the maps are the sphere's chart
            (the sphere correction): a pose is then the camera rotation of swing-twist pan
            ``h / f``, tilt ``-v / f`` and roll ``r`` (as the odometry reads it), and a map's
            origin composes with it as a rotation; 0: as a planar similarity.
    """

    def __init__(self, chart_focal_px: float = 0.0) -> None:
        self.chart_focal_px = chart_focal_px
        self.reset()

    def reset(self) -> None:
        """Zero pose, on the first map, nothing tracked yet."""
        self.raw = dict.fromkeys(POSE_KEYS, 0.0)    # on the map: physical, unwrapped
        self.out = dict(self.raw)                    # the output: raw, or the held pose
        self.origin = dict(self.raw)                 # the map's origin in the output's frame
        self.held: dict[str, float] | None = None    # raw of the last tracking frame

    def update(self, point: Mapping[str, float], books: Mapping[str, FactorCodebook], *,
               hold: bool, tracking: bool) -> dict[str, float]:
        """A frame's readout ``point`` (index units per factor) into :attr:`raw`, unwrapped
        against the last tracked pose; the output is the held pose if ``hold`` (a poor frame
        without the gyro), else the readout, composed with the origin. A ``tracking`` frame
        becomes the held pose. Returns :attr:`out`."""
        ref = self.held if self.held is not None else self.raw
        for name, idx in point.items():
            b = books[name]
            val = b.sign * b.unit * idx
            if b.period is not None:
                prev = ref[name]
                val = prev + centred_mod(val - prev, b.period * b.unit)
            self.raw[name] = val
        self.out.update(self.compose(self.held if hold and self.held is not None
                                     else self.raw))
        if tracking:
            self.held = dict(self.raw)
        return self.out

    def restart(self) -> None:
        """A new map starts at the pose output now: it becomes the origin, and the pose on
        the map (and the held one: a poor frame holds the new origin) is zero."""
        self.origin = dict(self.out)
        self.raw = dict.fromkeys(POSE_KEYS, 0.0)
        self.held = dict(self.raw)

    def compose(self, pose: Mapping[str, float]) -> dict[str, float]:
        """A pose on the map in the output's frame: the map's origin composed with it (roll
        and log zoom add; the shift turns by the origin's roll); on the sphere's chart the
        camera rotations multiply, origin first (the new map's chart is centred on the camera
        of its first frame), with the roll kept continuous and the log zoom added."""
        o = self.origin
        if not any(o.values()):
            return dict(pose)
        f = self.chart_focal_px
        if f > 0.0:
            pan, tilt, roll = compose_swing_twist((o['h'] / f, -o['v'] / f, o['r']),
                                                  (pose['h'] / f, -pose['v'] / f, pose['r']))
            r = o['r'] + pose['r']
            return {'h': f * pan, 'v': -f * tilt,
                    'r': r + float(centred_mod(roll - r, 2.0 * math.pi)), 'z': o['z'] + pose['z']}
        c, s = math.cos(o['r']), math.sin(o['r'])
        return {'h': o['h'] + c * pose['h'] - s * pose['v'],
                'v': o['v'] + s * pose['h'] + c * pose['v'],
                'r': o['r'] + pose['r'], 'z': o['z'] + pose['z']}
