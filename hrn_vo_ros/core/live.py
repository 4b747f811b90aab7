"""Frames and IMU samples of a running graph → estimates to publish: ``resonator_node``'s logic.

:class:`LiveOdometry` holds what the node keeps between messages: the odometry pipeline
(:class:`~hrn_vo_ros.core.pipeline.OdometryPipeline`), the frames waiting for gyro samples
(:class:`~hrn_vo_ros.core.odometry.publish.GyroGate`), the pose/twist composer, the stamp checks
of both streams, the frame size and the diagnostics windows. Frames of another size are
rejected, or, while the settings say ``adopt_size`` (``frame_size: frames``), given a resonator
of their size (tracking restarts). A frame or IMU stamp going back by more than the
tolerance restarts that stream's time state (waiting frames processed, a new gyro integrator,
no twist across; counted as ``clock_resets_<stream>``). A frame-stamp reset also restarts
tracking (``estimator.reset()``, counted as ``tracking_restarts``): after a looped bag or a
driver restart the scene seen next need not match the map, and a network kept across the jump
locked onto a wrong roll (the soak's looped bag: 19 of 29 later loops about 30 deg off); the
next frame starts a new map and the pose starts again from the identity, as at start-up.

The diagnostics also say how much scene the frames carry (``frame_structure``: the running mean
of :func:`~hrn_vo_ros.core.events.content.neighbour_ratio`, rate :data:`STRUCTURE_RATE` per
frame); while the track is degraded or lost on frames as scattered as noise (below
:data:`~hrn_vo_ros.core.events.content.NOISE_LIKE`), the status says so: no odometry can follow
a blank view or a stream of noise, and the fix is in the scene or the sensor, not the network.

Each call yields, lazily and in order, :class:`~hrn_vo_ros.core.events.stream.Note` entries
(rejects and warnings for the caller to count and log) and :class:`Step` results (one
processed frame for the caller to publish); a frame is processed only when the caller asks for
the next item, so the caller publishes each before the next one is computed.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
import math
import time

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.clock import Recent, StampChecker, Verdict
from hrn_vo_ros.core.events.content import neighbour_ratio, NOISE_LIKE
from hrn_vo_ros.core.events.packet_config import VALIDATED_FRAME
from hrn_vo_ros.core.events.sequence import CameraFocal
from hrn_vo_ros.core.events.stream import Note
from hrn_vo_ros.core.hrn.backends import BackendConfig, make_backend, ResonatorBackend
from hrn_vo_ros.core.hrn.config import needs_focal, ResonatorConfig, without_unset_focal
from hrn_vo_ros.core.odometry.estimate import Estimate
from hrn_vo_ros.core.odometry.odometry import OdometryConfig
from hrn_vo_ros.core.odometry.publish import (
    Composed,
    GyroGate,
    imu_frame_warning,
    OdometryComposer,
    size_mismatch_text,
    static_frames,
    StaticFrame,
)
from hrn_vo_ros.core.pipeline import OdometryPipeline
from hrn_vo_ros.errors import HrnVoError

#: Weight of the newest frame in the running mean of the frames' structure (about 10 frames).
STRUCTURE_RATE = 0.1


@dataclass(frozen=True, slots=True)
class LiveSettings:
    """The run-time settings a call reads (they may change between messages)."""

    adopt_size: bool               # frames of another size get a resonator of their size
    imu: bool                      # frames wait for the gyro (``imu.enabled``)
    with_z: bool                   # the resonator reads out the log scale z
    odometry: OdometryConfig
    focal_px: float
    lost_variance: float
    min_quality: float
    imu_timeout_s: float
    camera_from_imu: tuple[float, ...]   # 9 values, row-major (``imu.camera_from_imu``)


@dataclass(frozen=True, slots=True, eq=False)
class Step:
    """One processed frame: its estimate, the odometry settings used, what to publish."""

    t_ns: int
    estimate: Estimate
    odometry: OdometryConfig
    out: Composed
    seconds: float                 # processing time so far (the pipeline step)


Item = Note | Step

#: Builds the resonator for frames of (width, height): the resonator, or None and why not,
#: and the text to log (``frame_size: frames``; :func:`sized_config` and :func:`make_resonator`).
Resizer = Callable[[int, int], tuple[ResonatorBackend | None, str]]


def make_resonator(cfg: ResonatorConfig, seed: int, backend: BackendConfig
                   ) -> tuple[ResonatorBackend, str | None]:
    """The resonator of a node for ``cfg`` (seeded) and a warning text or None.

    Without a focal length it has no sphere correction and no gyro prediction (a node may have
    no calibration, or not yet; a live camera should still give odometry): the warning says so.
    """
    cfg, why = without_unset_focal(cfg)
    return make_backend(cfg, rng=np.random.default_rng(seed), backend=backend), why


def camera_focal_px(camera: CameraFocal, frame: tuple[int, int]) -> float:
    """The focal length in pixels of frames of size ``frame`` binned from ``camera``'s events:
    fx / D with D = max(W / w, H / h).

    The packetizer's frame is ceil(sensor / D): for its auto factor (``downsample`` 0,
    D = max(W / 96, H / 72, 1)) this D is the factor exactly (640x480 into 96x72: 6.667;
    1280x720 into 96x54: 13.33); for a fixed factor the frame's rounding up makes it at most
    1 / w smaller (346x260 at 2.5 into 139x104: 2.5 from the height, 2.489 from the width).
    """
    fx, (sw, sh) = camera
    w, h = frame
    return fx / max(sw / w, sh / h)


def sized_config(cfg: ResonatorConfig, width: int, height: int
                 ) -> tuple[ResonatorConfig | None, str]:
    """``cfg`` for frames of ``width`` x ``height`` (``frame_size: frames``; a canvas given by
    ``canvas_scale`` follows) and the text to log; ``(None, why)`` when the config cannot take
    that size (a fixed canvas smaller than the frame)."""
    try:
        sized = replace(cfg, width=width, height=height)
    except HrnVoError as err:
        return None, f'frames are {width}x{height}; the resonator cannot take that size: {err}'
    vw, vh = VALIDATED_FRAME
    ratio = width * height / (vw * vh)
    return sized, (f'frames are {width}x{height}: the resonator takes that size (frame_size: '
                   'frames); tracking starts from a new map' + (
                       f'; {ratio:.1f}x the pixels of the validated {vw}x{vh} frame: more '
                       'time per frame (packetizer downsample 0 gives at most that size)'
                       if ratio > 1.5 else ''))


def sized_resonator(cfg: ResonatorConfig, width: int, height: int,
                    make: Callable[[ResonatorConfig], ResonatorBackend]
                    ) -> tuple[ResonatorBackend | None, str]:
    """A :data:`Resizer` step: the resonator ``make`` builds for ``cfg`` at ``width`` x
    ``height``, or None when the config cannot take that size, and the text of
    :func:`sized_config`."""
    sized, text = sized_config(cfg, width, height)
    return (None if sized is None else make(sized)), text


@dataclass(slots=True)
class FocalLength:
    """Where a node's focal length (frame pixels) comes from: ``focal_px`` when set, else the
    camera_info's ``camera`` for the frames in use (:func:`camera_focal_px`), else none (the
    odometry keeps its own ``focal_length_px``)."""

    camera: CameraFocal | None = None
    _memo: tuple[OdometryConfig, float, OdometryConfig] | None = None

    def value(self, focal_px: float, frame: tuple[int, int]) -> tuple[float, str]:
        """The focal length (0 when none) and its source: ``focal_px``, ``camera_info`` or
        ``odometry.focal_length_px``."""
        if focal_px > 0.0:
            return focal_px, 'focal_px'
        if self.camera is not None:
            return camera_focal_px(self.camera, frame), 'camera_info'
        return 0.0, 'odometry.focal_length_px'

    def odometry(self, odo: OdometryConfig, focal_px: float,
                 frame: tuple[int, int]) -> OdometryConfig:
        """``odo`` with the camera_info's focal length when that is the source (the one focal
        length of the node; built once per change, not per frame)."""
        focal, source = self.value(focal_px, frame)
        if source != 'camera_info':
            return odo
        if self._memo is None or self._memo[:2] != (odo, focal):
            self._memo = (odo, focal, replace(odo, focal_length_px=focal))
        return self._memo[2]

    def config(self, cfg: ResonatorConfig, frame: tuple[int, int]) -> ResonatorConfig:
        """``cfg`` with the camera's focal length for frames of size ``frame`` when its own
        ``focal_px`` is unset (a set ``focal_px`` wins; no camera, no change)."""
        if cfg.focal_px > 0.0 or self.camera is None:
            return cfg
        return replace(cfg, focal_px=camera_focal_px(self.camera, frame))

    def adopt(self, camera: CameraFocal, cfg: ResonatorConfig,
              frame: tuple[int, int]) -> tuple[bool, str]:
        """Take ``camera`` (the first usable camera_info): whether a resonator of ``cfg`` must
        be rebuilt with its focal length (a gyro or sphere correction waited for it), and the
        text to log."""
        self.camera = camera
        rebuild = needs_focal(cfg)
        fx, (sw, sh) = camera
        return rebuild, (f'focal length {camera_focal_px(camera, frame):.4g} frame px from '
                         f'camera_info (fx {fx:g} on {sw}x{sh}, frames {frame[0]}x{frame[1]}), '
                         'for the odometry too' + (
                             '; the resonator restarts with it' if rebuild else ''))

    def diagnostic_values(self, focal_px: float, frame: tuple[int, int],
                          odo: OdometryConfig) -> list[tuple[str, object]]:
        """``focal_px`` (the one in use; without one the odometry's) and ``focal_source``."""
        focal, source = self.value(focal_px, frame)
        return [('focal_px', f'{focal or odo.focal_length_px:.6g}'), ('focal_source', source)]

    def missing(self, cfg: ResonatorConfig, topic: str) -> str | None:
        """Why the gyro or sphere correction of ``cfg`` is off for want of a focal length, and
        what to do (the text of a WARN), or None."""
        why = without_unset_focal(cfg)[1] if self.camera is None else None
        return None if why is None else (f'no focal length: {why}; set focal_px or publish a '
                                         f'camera_info on {topic}')


class LiveOdometry:
    """The odometry of a live frame and IMU stream (see the module docstring).

    Args:
        estimator: The resonator (the pipeline's estimator; replaced by ``reconfigured``).
        gate: The frames waiting for gyro samples (its gyro is the pipeline's).
        size: The (width, height) of the frames ``estimator`` takes.
        tolerance_ns: Stamps going back by more than this restart the time state.
        resize: Builds a resonator for frames of another size (used while the settings'
            ``adopt_size`` holds; without it such frames are rejected).
        counts: Where counters go (a new Counter when None).
        now: The wall clock (``time.monotonic``; injectable for tests).
    """

    def __init__(self, estimator: ResonatorBackend, gate: GyroGate, size: tuple[int, int], *,
                 tolerance_ns: int, resize: Resizer | None = None,
                 counts: Counter[str] | None = None,
                 now: Callable[[], float] = time.monotonic) -> None:
        self.pipeline = OdometryPipeline(estimator, gyro=gate.gyro, record=False)
        self.size = size
        self.resize = resize
        self.gate = gate
        self.composer = OdometryComposer()
        self.counts: Counter[str] = Counter() if counts is None else counts
        self.frame_clock = StampChecker(tolerance_ns)
        self.imu_clock = StampChecker(tolerance_ns, strict=True)
        self.last_reset = Recent(now)
        self.size_mismatch = Recent(now)
        self.queue_dropped = Recent(now)     # frames the node's subscription queue dropped
        self.focal = FocalLength()           # focal_px, or a camera_info's
        self.structure = math.nan            # running mean neighbour_ratio of the frames
        self._now = now

    def frame(self, t_ns: int, image: NDArray[np.uint8], s: LiveSettings) -> Iterator[Item]:
        """One decoded frame: checked (of another size: a resonator of its size when the
        settings adopt sizes), then processed now or when the gyro covers it."""
        size = (image.shape[1], image.shape[0])
        if size != self.size and s.adopt_size and self.resize is not None:
            estimator, text = self.resize(*size)
            if estimator is not None:
                self.reconfigured(estimator, size)
                yield Note('warn', 'frame_size', text)
            else:                                   # the frame is then rejected (ERROR)
                yield Note('warn', 'frame_size_refused', text, throttled=True)
        if size != self.size:
            text = size_mismatch_text(*size, *self.size)
            self.size_mismatch.mark(text)
            yield Note('reject', 'size', text)
            return
        verdict = self.frame_clock.observe(t_ns)
        if verdict is Verdict.BACKWARDS:
            yield Note('reject', 'time_backwards', f'frame at {t_ns} ns is older than the '
                       'previous')
            return
        if verdict is Verdict.RESET:
            yield from self._restart_time('frames', s)
        if not s.imu:
            yield from self._process(t_ns, image, s, imu=False)
            return
        self.gate.add(t_ns, image, self._now())
        yield from self._drain(s, force=False)

    def imu(self, t_ns: int, gyro: NDArray[np.float64], s: LiveSettings) -> Iterator[Item]:
        """One gyro sample (rad/s, IMU frame): stored, then the frames it completes."""
        verdict = self.imu_clock.observe(t_ns)
        if verdict is Verdict.BACKWARDS:
            yield Note('reject', 'imu_time', f'IMU sample at {t_ns} ns does not increase')
            return
        if verdict is Verdict.RESET:
            yield from self._restart_time('imu', s)
        try:
            self.gate.add_gyro(t_ns, gyro, self._now())
        except (HrnVoError, ValueError, TypeError) as err:
            yield Note('reject', 'imu', str(err))
            return
        yield from self._drain(s, force=False)

    def imu_frame(self, frame_id: str, imu_frame_id: str) -> Iterator[Item]:
        """Check an IMU message's frame against ``imu_frame_id`` (counted, throttled note)."""
        warning = imu_frame_warning(frame_id, imu_frame_id)
        if warning is not None:
            self.counts['imu_frame_mismatch'] += 1
            yield Note('warn', 'imu_frame', warning, throttled=True)

    def static_frames(self, s: LiveSettings, *, base: str, camera: str,
                      imu: str) -> tuple[list[StaticFrame], list[Note]]:
        """The static transforms (``publish.static_frames``) with the odometry of ``s``, and
        the focal-length note when its focal length is not the resonator's."""
        odo, warning = self.composer.odometry(s.odometry, s.focal_px)
        notes = [] if warning is None else [Note('warn', 'focal', warning)]
        return static_frames(odo, s.camera_from_imu, base=base, camera=camera, imu=imu), notes

    def tick(self, s: LiveSettings) -> Iterator[Item]:
        """Periodic: when the IMU stopped (end of a bag), the waiting frames go anyway."""
        if self.gate.stalled(self._now(), s.imu_timeout_s):
            yield from self._drain(s, force=True)

    def rebuild(self, cfg: ResonatorConfig,
                make: Callable[[ResonatorConfig], ResonatorBackend]) -> None:
        """A changed config: a new resonator from ``make`` (with the camera_info's focal
        length while ``cfg`` has none), at the frame size in use when ``cfg`` can take it (an
        adopted size is kept), else at ``cfg``'s own size."""
        cfg = self.focal.config(cfg, self.size)
        sized, _ = sized_config(cfg, *self.size)
        self.reconfigured(make(sized or cfg), self.size if sized else (cfg.width, cfg.height))

    def sized(self, cfg: ResonatorConfig, width: int, height: int,
              make: Callable[[ResonatorConfig], ResonatorBackend]
              ) -> tuple[ResonatorBackend | None, str]:
        """A :data:`Resizer`'s work: :func:`sized_resonator` for ``cfg`` with the camera_info's
        focal length for frames of that size (while ``cfg`` has none)."""
        return sized_resonator(self.focal.config(cfg, (width, height)), width, height, make)

    def adopt_camera(self, camera: CameraFocal, cfg: ResonatorConfig,
                     make: Callable[[ResonatorConfig], ResonatorBackend]) -> str:
        """The first usable camera_info (``FocalLength.adopt``): a resonator that waited for
        its focal length (gyro, sphere correction) is rebuilt with it; the text to log."""
        rebuild, text = self.focal.adopt(camera, cfg, self.size)
        if rebuild:
            self.rebuild(cfg, make)
        return text

    def focal_for(self, cfg: ResonatorConfig, odo: OdometryConfig
                  ) -> tuple[float, OdometryConfig]:
        """The focal length in use (0: none; ``FocalLength.value``) and the odometry config
        with it (a camera_info's focal length is the odometry's too)."""
        return (self.focal.value(cfg.focal_px, self.size)[0],
                self.focal.odometry(odo, cfg.focal_px, self.size))

    def reconfigured(self, estimator: ResonatorBackend, size: tuple[int, int]) -> None:
        """A new resonator, for frames of ``size`` (tracking restarts: no twist across)."""
        self.pipeline.estimator = estimator
        self.size = size
        self.composer.restart()

    def _restart_time(self, what: str, s: LiveSettings) -> Iterator[Item]:
        """A stream's stamps went back (restart, looped bag): clear the time state."""
        self.counts[f'clock_resets_{what}'] += 1
        self.last_reset.mark(what)
        self.composer.restart()
        yield from self._drain(s, force=True)
        self.pipeline.gyro = self.gate.new_gyro(s.camera_from_imu)
        if what == 'frames':
            self.pipeline.estimator.reset()
            self.counts['tracking_restarts'] += 1
        yield Note('warn', 'time_reset', f'{what} stamps went back by more than '
                   'clock_tolerance_s: time state restarted (a driver restart or a looped bag)'
                   + ('; tracking restarts from the next frame' if what == 'frames' else ''),
                   throttled=True)

    def _drain(self, s: LiveSettings, *, force: bool) -> Iterator[Item]:
        """Process waiting frames whose gyro increment is final (or all, when forced)."""
        for t_ns, image in self.gate.drain(force=force):
            yield from self._process(t_ns, image, s, imu=True)

    def _process(self, t_ns: int, image: NDArray[np.uint8], s: LiveSettings, *,
                 imu: bool) -> Iterator[Item]:
        """One frame through the pipeline (with the gyro increment when ``imu``), composed."""
        t0 = time.perf_counter()
        r = neighbour_ratio(image)
        if math.isfinite(r):
            self.structure = (r if not math.isfinite(self.structure) else
                              self.structure + STRUCTURE_RATE * (r - self.structure))
        try:
            est = self.pipeline.step(image, t_ns, use_gyro=imu)
        except HrnVoError as err:
            yield Note('reject', 'tracking', str(err))
            return
        odo, warning = self.composer.odometry(s.odometry, s.focal_px)
        if warning is not None:
            yield Note('warn', 'focal', warning)
        out = self.composer.compose(t_ns, est, odo, with_z=s.with_z,
                                    lost_variance=s.lost_variance, min_quality=s.min_quality)
        self.counts['estimates_out'] += 1
        self.counts['invalid_frames'] += 0 if est.valid else 1
        yield Step(t_ns, est, odo, out, time.perf_counter() - t0)

    def describe(self, cfg: ResonatorConfig, *, adopt_size: bool,
                 camera_info_topic: str | None) -> str:
        """The node's start-up line: frame size (or that frames give it), the resonator's
        factors, the gyro, and where the focal length comes from when a camera_info gives it
        (``camera_info_topic``; None: ``focal_px`` is set)."""
        return (f'{cfg.width}x{cfg.height} frames'
                + (' (or the size of the frames)' if adopt_size else '')
                + f', factors {"/".join(self.pipeline.estimator.factors)}, IMU {cfg.imu.enabled}'
                + ('' if camera_info_topic is None else ', focal length from the first '
                   f'camera_info on {camera_info_topic} (focal_px 0)'))

    def diagnostics(self, window_s: float, measured: tuple[str, int, int], cfg: ResonatorConfig,
                    odo: OdometryConfig, camera_info_topic: str
                    ) -> tuple[list[tuple[str, object]], list[tuple[str, str]]]:
        """What ``/diagnostics`` reports: the key/values (:meth:`diagnostic_values` with the
        three the caller ``measured``, and the focal length's) and the ``(level, message)``
        pairs of :meth:`states`, with a WARN while the gyro or sphere correction of ``cfg``
        waits for a focal length (a camera_info on ``camera_info_topic``)."""
        values = (self.diagnostic_values(*measured)
                  + self.focal.diagnostic_values(cfg.focal_px, self.size, odo))
        missing = self.focal.missing(cfg, camera_info_topic)
        return values, self.states(window_s, *([('warn', missing)] if missing else []))

    def diagnostic_values(self, frame_rate_hz: str, output_subscribers: int,
                          odom_subscribers: int) -> list[tuple[str, object]]:
        """The diagnostics key/values (with the three the caller measures)."""
        return ([('frame_rate_hz', frame_rate_hz), ('pending_frames', len(self.gate)),
                 ('gyro_samples', len(self.gate.gyro)),
                 ('output_subscribers', output_subscribers),
                 ('odom_subscribers', odom_subscribers),
                 ('imu_rejected_frames', self.pipeline.estimator.rejected_frames),
                 ('imu_limited_frames', self.pipeline.estimator.limited_frames),
                 ('hot_pixels', self.pipeline.estimator.hot_pixels),
                 ('distinctiveness', f'{self.pipeline.estimator.tracker.distinct:.1f}'),
                 ('relocalisations', self.pipeline.estimator.tracker.relocalisations),
                 ('gaps', self.pipeline.estimator.tracker.gaps),
                 ('gyro_bias_deg_s', ' '.join(
                     f'{b:+.3f}' for b in np.degrees(self.pipeline.estimator.gyro_bias.b)))]
                + self.composer.diagnostic_values()
                + [('frame_structure', f'{self.structure:.2f}'),
                   ('clock_resets', self.frame_clock.resets + self.imu_clock.resets)])

    def queue_drops(self, gaps: int, depth: int) -> Iterator[Item]:
        """Frames the node's subscription queue dropped (``gaps`` in all, queue ``depth``):
        WARN in :meth:`states` for a window, and a throttled warning."""
        text = (f'{gaps} frames dropped before the resonator: it falls behind the frames '
                f'(queue frames_depth {depth}, oldest dropped first)')
        self.queue_dropped.mark(text)
        yield Note('warn', 'frames_dropped', text, throttled=True)

    def states(self, window_s: float, *more: tuple[str, str]) -> list[tuple[str, str]]:
        """``(level, message)`` pairs: ERROR while frames of another size arrive (within
        ``window_s``), the tracking state, WARN after a time reset, the caller's ``more``, WARN
        after frames dropped by the node's queue (within ``window_s``)."""
        states = []
        if self.size_mismatch.within(window_s):
            states.append(('error', f'every frame dropped: {self.size_mismatch.detail}'))
        level, text = self.composer.status()
        if level != 'ok' and self.structure < NOISE_LIKE:
            text += (f'; the frames are as scattered as noise (structure {self.structure:.2f} '
                     f'< {NOISE_LIKE:g}): a blank view, or a noisy sensor')
        states.append((level, text))
        if self.last_reset.within(window_s):
            states.append(('warn', 'stamps went back: time state restarted'))
        states += more
        if self.queue_dropped.within(window_s):
            states.append(('warn', self.queue_dropped.detail))
        return states
