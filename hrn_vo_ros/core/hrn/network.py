"""The hierarchical resonator network (HRN) for event-camera odometry, Model A.

One (or a few) resonator iterations per event frame factorise the frame, encoded as an FHRR
vector, into the camera's shift (h, v), roll (r) and optionally log zoom (z) relative to an
allocentric map that the network learns as it goes. ``docs/model.md`` gives the model, its
equations and every switch beyond the paper; the engines computing the equations are in
:mod:`.fast` and :mod:`.dense` (protocol :class:`~hrn_vo_ros.core.hrn.engine.Engine`); the
prediction step (gyro or velocity, the gyro's gate) in :mod:`.prediction`.

Public API:

* ``ResonatorConfig`` (:mod:`.config`; sections ``codebook``, ``logpolar``, ``cleanup``,
  ``map``, ``readout``, ``scale``, ``imu``, ``sphere``).
* ``HRN(cfg=None, *, rng, dense_dtype=np.complex128, engine=None)``
    - ``step(image (H, W), t_ns, *, gyro_delta (3,) | None = None) -> Estimate``: one event
      frame; ``gyro_delta`` is the integrated gyro (rad, camera axes x right / y down /
      z forward) since the previous frame.
    - ``map_image()``, ``egocentric_map_image()``: the map on the canvas, (H_c, W_c) float64.
    - ``readout_axis(name) -> (K,)``: the physical value of each similarity entry.
    - ``factors`` (``('h', 'v', 'r')``, or with ``'z'``), ``iteration``, ``geometry``,
      ``rejected_frames``, ``innovation_deg``, ``gyro_bias``
      (:class:`~hrn_vo_ros.core.hrn.gyro.GyroBias`), ``reset()``; tracking (``docs/model.md``,
      section 9): ``state``, ``quality``, and ``tracker``
      (:class:`~hrn_vo_ros.core.hrn.tracking.Tracker`: the quality terms, the state machine
      and their counts: ``overlap``, ``distinct``, ``relocalisations``, ``held_frames``,
      ``restarts``; the network keeps what acts on the engine: the hold, the gates and the
      re-localisation), and ``hot_pixels``.

Signs: binding the map with ``h0^a`` moves the image content by +a pixels, and the output
``h = -a`` is the camera's position in the map (x right, y down); a camera roll φ
(right-handed about the optical axis) rotates the content by -φ and gives ``r = φ``; ``z`` is
the log zoom of the content, positive when the camera approaches the scene.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.content import neighbour_ratio
from hrn_vo_ros.core.events.frames import check_event_frame
from hrn_vo_ros.core.hrn import fft as hfft
from hrn_vo_ros.core.hrn.config import geometry, ResonatorConfig
from hrn_vo_ros.core.hrn.dense import DenseEngine
from hrn_vo_ros.core.hrn.engine import Engine, EngineFactory
from hrn_vo_ros.core.hrn.fast import FastEngine
from hrn_vo_ros.core.hrn.gyro import GyroBias
from hrn_vo_ros.core.hrn.hotpixels import HotPixelMask
from hrn_vo_ros.core.hrn.pose import ReportedPose
from hrn_vo_ros.core.hrn.prediction import Prediction
from hrn_vo_ros.core.hrn.shared import (
    centred_mod,
    Complex,
    Floats,
    map_block,
    map_block_ns,
    map_mu1,
    population_readout,
    Real,
    refine_exponent,
    refine_kernel,
)
from hrn_vo_ros.core.hrn.sphere import SphereWarp
from hrn_vo_ros.core.hrn.tracking import Tracker
from hrn_vo_ros.core.odometry.estimate import Estimate
from hrn_vo_ros.errors import ConfigError


class HRN(Prediction):
    """Hierarchical resonator odometry: one (or a few) resonator iterations per event frame.

    Args:
        cfg: Configuration (defaults: 96x72 frames, DFT codebooks, fast path, h/v/r).
        rng: Source of the random initial states (and of random codebooks).
        dense_dtype: Complex type of the dense reference matrices (complex64 halves memory).
        engine: Builds the engine from the configuration and geometry (default: the fast or
            dense engine of ``cfg.path``); the spiking backend passes its own.

    Raises:
        ConfigError: on inconsistent settings.
    """

    def __init__(self, cfg: ResonatorConfig | None = None, *, rng: np.random.Generator,
                 dense_dtype: type[np.complexfloating] = np.complex128,
                 engine: EngineFactory | None = None) -> None:
        self.cfg = cfg if cfg is not None else ResonatorConfig()
        self.rng = rng
        c = self.cfg
        self.geometry = geometry(c)
        self._engine: Engine
        if engine is not None:
            self._engine = engine(c, self.geometry)
        elif c.path == 'fast':
            self._engine = FastEngine(c, self.geometry)
        else:
            self._engine = DenseEngine(c, self.geometry, rng, dense_dtype)
        self.factors: tuple[str, ...] = tuple(self._engine.books)
        self._kernels: dict[str, Complex] = {}      # readout.refine kernels per factor
        # (first entry, entry step) of each factor's codebook, for the readout
        self._steps = {k: (float(b.values[0]), float(b.values[1] - b.values[0])
                           if len(b.values) > 1 else 1.0) for k, b in self._engine.books.items()}
        self._refine_input = set(c.readout.input_factors)
        self._canvas = np.zeros((self.geometry.canvas_height, self.geometry.canvas_width))
        self._sphere = (SphereWarp(c.width, c.height, c.focal_px) if c.sphere.enabled
                        else None)
        if c.imu.enabled and c.focal_px <= 0.0:     # fail at start, not on the first gyro frame
            raise ConfigError('imu.enabled needs focal_px (fx / downsample, in frame pixels) for '
                              'the gyro prediction: set it (hrn-vo run derives it from calib.txt)')
        # ĝ of codebook.kernel_sigma; real and even, so the blur of the real canvas is a real
        # FFT pair: ĝ on the rfft2 half-spectrum
        self._blur: Real | None = None
        if c.codebook.kernel_sigma > 0.0:
            sig = c.codebook.kernel_sigma
            fy = hfft.fftfreq(self.geometry.canvas_height)[:, None]
            fx = hfft.rfftfreq(self.geometry.canvas_width)[None, :]
            self._blur = np.exp(-2.0 * math.pi ** 2 * sig ** 2 * (fx ** 2 + fy ** 2))
        self._blur32 = (self._blur.astype(np.float32) if self._blur is not None
                        and self._engine.blur_dtype is np.float32 else None)
        # the single-precision canvas that blur places the frame on (assigning the frame casts
        # it as astype did), and where the frame goes
        self._canvas32 = self._canvas.astype(np.float32) if self._blur32 is not None else None
        ox, oy = self.geometry.offset
        self._frame_at = np.s_[oy:oy + c.height, ox:ox + c.width]
        self.tracker = Tracker(c.tracking)     # quality and state (core/hrn/tracking.py)
        self.gyro_bias = GyroBias(c.imu.bias_memory_s, c.imu.bias_prior_s,
                                  math.radians(c.imu.max_bias_deg_s))
        # the output (core/hrn/pose.py): on the sphere's chart its origins compose as rotations
        self._pose = ReportedPose(c.focal_px if c.sphere.enabled else 0.0)
        self._hot = HotPixelMask(c.width, c.height, c.hot_pixel_rate, c.hot_pixel_on)
        self.reset()

    def reset(self) -> None:
        """Forget the map and the states; the next non-empty frame starts a new map."""
        self.iteration = 0
        self._started = False
        self._last: Estimate | None = None
        self._pose.reset()              # the reported pose: unwrap, hold, the map's origin
        self._map_iteration = 0         # the iteration at which the map started
        self._map_t_ns = 0              # ... and its frame's time (ns)
        self._t_ns = 0                  # the time of the frame in process (ns)
        self._map_on = 0                # on pixels of the frame the map started from
        self._map_structure = math.nan  # neighbour ratio of the frame the map started from
        self._map_learned = False       # the map has been updated since it started
        self.innovation_deg = 0.0       # last readout vs gyro prediction (imu.gate_deg on)
        self.rejected_frames = 0        # frames rejected by imu.gate_deg
        self.limited_frames = 0         # readouts cut by imu.max_correction_deg_s
        self._t_prev: int | None = None  # time of the previous frame (ns)
        self._new_origin()
        self.tracker.reset()
        self.gyro_bias.reset()
        self._hot.reset()

    def _new_origin(self) -> None:      # a new map: its origin, no velocity
        self._point = dict.fromkeys(self.factors, 0.0)          # index units, wrapped
        self._prev: dict[str, float] | None = None  # readout of the last valid frame
        self._velocity: dict[str, float] | None = None   # smoothed readout change per frame

    # the tracker's figures, as the network's own (docs/model.md, section 9)
    @property
    def state(self) -> str:
        """``tracking``, ``degraded`` or ``lost``, as the outputs report it
        (:attr:`.Tracker.reported`; the network's own logic follows ``tracker.state``)."""
        return self.tracker.reported

    @property
    def hot_pixels(self) -> int:
        """On pixels masked as hot in the last frame (:mod:`.hotpixels`)."""
        return self._hot.masked

    @property
    def quality(self) -> float:
        """Quality in [0, 1] of the last valid frame."""
        return self.tracker.quality

    # -- helpers ---------------------------------------------------------------------------

    def _place(self, image: NDArray[Any]) -> Floats:
        if self._blur32 is not None and self._canvas32 is not None:
            # G * I on the (toroidal) canvas, i.e. s = (Φ I) ⊙ ĝ for DFT codebooks, in single
            # precision where the engine rounds to it
            self._canvas32[self._frame_at] = image
            spec = hfft.rfft2(self._canvas32)
            spec *= self._blur32
            return np.asarray(hfft.irfft2(spec, self._canvas32.shape))
        self._canvas[self._frame_at] = image
        if self._blur is None:
            return self._canvas
        spec = hfft.rfft2(self._canvas)
        spec *= self._blur
        return np.asarray(hfft.irfft2(spec, self._canvas.shape), np.float64)

    def readout_axis(self, name: str) -> Real:
        """Physical value (px, rad, log scale) of each readout entry of factor ``name``."""
        b = self._engine.books[name]
        vals = b.sign * b.unit * b.values
        if b.period is not None:
            vals = centred_mod(vals, b.period * b.unit)
        return vals

    def _readout(self, sims: dict[str, Real]) -> tuple[dict[str, float], dict[str, float],
                                                       dict[str, float]]:
        """Point estimates (index units), spreads and peaks of every factor."""
        hw = self.cfg.readout.half_window
        point, spread, peak = {}, {}, {}
        for name, sim in sims.items():
            b = self._engine.books[name]
            idx, sd, pk = population_readout(sim, hw, b.period is not None)
            first, step = self._steps[name]
            value = first + idx * step
            if self.cfg.readout.refine:
                if name not in self._kernels:
                    self._kernels[name] = refine_kernel(b.phases, step)
                x = (self._engine.input_projection(name) if name in self._refine_input
                     else self._engine.state[name])
                value = refine_exponent(x, b.phases, value, step, self._kernels[name])
            point[name], spread[name], peak[name] = b.wrap(value), sd * step * b.unit, pk
        return point, spread, peak

    # -- public ----------------------------------------------------------------------------

    def step(self, image: NDArray[Any], t_ns: int, *,
             gyro_delta: NDArray[Any] | None = None) -> Estimate:
        """Process one event frame.

        Args:
            image: Binary (or any non-negative) event frame.
            t_ns: Frame time, int64 ns.
            gyro_delta: Integrated gyro since the previous frame (rad, camera axes), applied as
                the prediction step (paper Eq. 10) when given.

        Returns:
            The pose readout; an empty frame, one with more than ``max_fill`` of its pixels
            on (noise), or one the sphere correction warps entirely off the frame repeats the
            previous pose with ``valid=False``.

        Shapes:
            image: (height, width); gyro_delta: (3,).

        Raises:
            TrackingError: for a frame of the wrong shape or with non-finite values.
        """
        c = self.cfg
        prepared = self._prepare(image)
        if prepared is None:
            return self._repeat(t_ns)
        img, n_on, n_in = prepared
        self._t_ns = int(t_ns)
        canvas = self._place(img)
        eng = self._engine
        first = not self._started
        if first:
            self._start_map(canvas, n_in, image)
            self._started = True
        dt_s = 0.0 if self._t_prev is None else max(t_ns - self._t_prev, 0) * 1e-9
        self._t_prev = t_ns
        if gyro_delta is not None:
            gyro_delta = self.gyro_bias.correct(self._check_gyro(gyro_delta), dt_s)
        if c.tracking.enabled and not first:
            self.tracker.after_gap(dt_s)
        predicted, held, shift = self._predict(first, gyro_delta)
        gyro = gyro_delta is not None and not first     # the gyro predicted this frame
        # ... and carries the states: poor frames keep its prediction, the output follows it
        carried = gyro and c.tracking.gyro_poor
        # the predicted states and pose, kept for the quality gate (tracking.hold_gain)
        prior = ({k: x.copy() for k, x in eng.state.items()} if c.tracking.enabled
                 and c.tracking.hold_gain > -1.0 and not first else None)
        prior_point = {k: self._point[k] + shift.get(k, 0.0) for k in self._point}
        S = eng.encode(canvas)
        sims, point, spread, peak = self._resonate(S)
        rejected = False
        if predicted is not None:
            assert gyro_delta is not None       # a prediction is made from the gyro only
            gyro_deg = math.degrees(float(np.linalg.norm(gyro_delta)))
            sims, point, rejected = self._gate_imu(point, predicted, held, sims, dt_s,
                                                   gyro_deg)
        learn = c.map.learn and not self._map_blocked() and not rejected
        target: Any = None
        if c.tracking.enabled and not first:
            point, spread, peak, sims, target = self._assess(
                S, point, spread, peak, sims, prior, prior_point, n_on, rejected, gyro,
                carried)
        self._point = point
        if c.tracking.enabled and not first and (self.tracker.bootstrap_due()
                                                 or self._thin_map(n_in)
                                                 or self._noise_map(image)
                                                 or self._lost_unlearned(carried)
                                                 or (self.tracker.remap_due(t_ns) and gyro)):
            return self._restart(canvas, t_ns, n_in, spread, peak, sims, carried=carried,
                                 frame=image)
        self._follow(point, n_on, dt_s)
        updated = False
        if learn and (not c.tracking.enabled or (self.tracker.state != 'lost'
                                                 and self.quality >= c.tracking.map_quality)):
            eng.update_map(S, point, map_mu1(c), c.map.mu2, target)
            updated = self._map_learned = True
        if self.gyro_bias.enabled and predicted is not None and not rejected \
                and self.tracker.state == 'tracking' and self.quality >= c.imu.bias_min_quality:
            self._learn_bias(point, predicted, dt_s)
        return self._emit(t_ns, point, spread, peak, sims, updated, carried=carried)

    # -- the steps of a frame ---------------------------------------------------------------

    def _prepare(self, image: NDArray[Any]) -> tuple[NDArray[np.float64], int, int] | None:
        """The checked (and sphere-warped) frame, its on-pixel count and that before the warp
        (which spreads each pixel over up to four); None: skip it."""
        c = self.cfg
        img, usable = check_event_frame(image, c.width, c.height, self._max_fill(), 'resonator')
        if not usable:
            return None
        img = self._hot.apply(img)
        n_in = n_on = int(np.count_nonzero(img))
        if not n_in:
            return None
        if self._sphere is not None and self._started:   # the last pose's non-rigid part
            raw = self._pose.raw
            img = self._sphere.warp(img, raw['h'], raw['v'], raw['r'])
            n_on = int(np.count_nonzero(img))
            if not n_on:                  # every event warped off the frame: nothing to use
                return None
        return img, n_on, n_in

    def _max_fill(self) -> float:
        """The fill above which a frame is skipped: ``max_fill``, or once tracked with
        ``tracking.fill_gain``, that many times the running mean fill if larger."""
        c = self.cfg
        density = self.tracker.density if c.tracking.enabled else None
        if c.tracking.fill_gain <= 0.0 or density is None:
            return c.max_fill
        return min(1.0, max(c.max_fill, c.tracking.fill_gain * density / (c.width * c.height)))

    def _resonate(self, S: Any) -> tuple[dict[str, Real], dict[str, float], dict[str, float],
                                         dict[str, float]]:
        """The frame's resonator iterations and their readout: (sims, point, spread, peak)."""
        c, eng = self.cfg, self._engine
        n = c.cleanup.iterations_per_frame
        if c.tracking.enabled and self.tracker.settling:
            n = max(n, c.tracking.relock_iterations)
        for _ in range(n):
            eng.iterate(S)
            self.iteration += 1
        sims = eng.similarities()
        drive = eng.drive
        if c.readout.source == 'drive' and all(k in drive for k in sims):
            sims = {k: drive[k] for k in sims}
        point, spread, peak = self._readout(sims)
        return sims, point, spread, peak

    def _assess(self, S: Any, point: dict[str, float], spread: dict[str, float],
                peak: dict[str, float], sims: dict[str, Real], prior: dict[str, Any] | None,
                prior_point: dict[str, float], n_on: int, rejected: bool, gyro: bool,
                carried: bool) -> tuple[dict[str, float], dict[str, float], dict[str, float],
                           dict[str, Real], Any]:
        """Quality, the hold of poor sparse or dense frames, the state, and re-localisation
        when lost (``gyro``: the gyro predicted this frame; ``carried``: and carries the
        states, ``tracking.gyro_poor``). Returns (point, spread, peak, sims, map target)."""
        c, eng, tr = self.cfg, self._engine, self.tracker
        target = eng.map_target(S, point)
        o1 = eng.overlap(target)
        q = tr.overlap_quality(o1)
        books = eng.books
        # (the roll may jump only away from a tracked pose: a degraded track's prediction
        # is no reference)
        if prior is not None and not rejected and (
                (tr.state == 'tracking' and self._jumped(point, prior_point))
                or (tr.unusual(n_on) and min(q, tr.sharpness(peak)) < c.tracking.degrade)):
            # a poor frame, sparse or dense, or one whose roll jumps (a half turn), moves the
            # states only if that clearly improves the match over the prediction: else they
            # keep it (hot pixels, noise, a pause, the log-polar spectrum's symmetry)
            pp = {k: books[k].wrap(v) for k, v in prior_point.items()}
            t0 = eng.map_target(S, pp)
            o0 = eng.overlap(t0)
            q0 = tr.overlap_quality(o0)
            if q - q0 < c.tracking.hold_gain:
                point, peak, sims, target, q = *self._keep_prior(prior, pp), t0, q0
                tr.held_frames += 1
            else:
                tr.overlap = o1
        # (the distinctiveness's correlation only where its term is on)
        tr.update(min(q, tr.sharpness(peak), tr.distinct_term(
            eng.distinctiveness(target) if tr.psr_on else math.nan)))
        if c.tracking.relocalise and tr.search_due():
            # a search that is not accepted leaves the states alone when the gyro carries them
            # or when a gap, not a loss, armed it (the states may still hold the pose)
            gap, q_frame = tr.gap_search, tr.quality
            kept = {k: x.copy() for k, x in eng.state.items()} if carried or gap else None
            near = prior_point if gyro and c.imu.gate_deg > 0.0 else None
            found = self._relocalise(S, point, near)
            if found is not None:
                point, spread, peak, sims, target = found
            elif kept is not None:      # no unaccepted restart: the states as they were
                eng.state.update(kept)
                if gap:                 # (and the frame's own quality, not the restart's)
                    tr.quality = q_frame
        if carried and prior is not None and tr.poor:
            # a poor frame's readout is no measurement: the states keep the gyro's prediction
            point, peak, sims = self._keep_prior(
                prior, {k: books[k].wrap(v) for k, v in prior_point.items()})
            target = eng.map_target(S, point)
        return point, spread, peak, sims, target

    def _jumped(self, point: dict[str, float], prior_point: dict[str, float]) -> bool:
        """Whether the roll readout ``point`` is more than ``tracking.jump_deg`` from the
        predicted roll ``prior_point`` (index units, wrapped)."""
        bound = self.cfg.tracking.jump_deg
        if bound <= 0.0 or 'r' not in point:
            return False
        b = self._engine.books['r']
        if abs(b.wrap(point['r'] - prior_point['r'])) * b.unit > math.radians(bound):
            self.tracker.jumps += 1
            return True
        return False

    def _thin_map(self, n_in: int) -> bool:
        """Whether the map is still its first frame (learning blocked) and this frame has more
        than ``tracking.bootstrap_fill`` times its on pixels (both counted before the sphere
        warp)."""
        fill = self.cfg.tracking.bootstrap_fill
        return fill > 0.0 and self._map_blocked() and n_in > fill * self._map_on

    def _noise_map(self, frame: NDArray[Any]) -> bool:
        """Whether the map is still its first frame (learning blocked), that frame was as
        scattered as noise (neighbour ratio below ``tracking.bootstrap_structure``) and this
        frame is not."""
        least = self.cfg.tracking.bootstrap_structure
        return (least > 0.0 and self._map_blocked() and self._map_structure < least
                and neighbour_ratio(frame) >= least)

    def _map_blocked(self) -> bool:
        """Whether the map is still the frame it started from: its updates are blocked for
        ``map_block`` iterations from its start or, if that comes first, until a frame comes
        more than ``map_block_ns`` after the map's own frame (``imu.block_s``)."""
        if self.iteration - self._map_iteration > map_block(self.cfg):
            return False
        most = map_block_ns(self.cfg)
        return most <= 0 or self._t_ns - self._map_t_ns <= most

    def _lost_unlearned(self, carried: bool) -> bool:
        """Whether the track is lost while its map never learned (``tracking.bootstrap_lost``):
        the map is the one frame it started from, and the global search can only find that.
        Not while the gyro carries the states (``carried``): ``remap_s`` rules that case."""
        c = self.cfg
        return (c.tracking.bootstrap_lost and c.map.learn and not carried
                and not self._map_learned and self.tracker.state == 'lost')

    def _restart(self, canvas: Floats, t_ns: int, n_in: int, spread: dict[str, float],
                 peak: dict[str, float], sims: dict[str, Real], *, carried: bool,
                 frame: NDArray[Any]) -> Estimate:
        """Bootstrap (``tracking.bootstrap_frames``, ``bootstrap_fill``,
        ``bootstrap_structure``, ``bootstrap_lost``):
        poor frames before the map was ever tracked say that the map's frame had nothing to
        track (noise before the camera moved, a blur), a frame with many more pixels than the
        map's says the map is thin, and a loss before the map ever learned leaves nothing to
        search but its first frame: this frame starts a new map, at the pose the output reports
        now, and the track must establish itself on it again (``frame``: this frame as it
        arrived, ``canvas``: as the network placed it)."""
        out = self._emit(t_ns, self._point, spread, peak, sims, False, carried=carried)
        self._pose.restart()
        self._start_map(canvas, n_in, frame)
        self._new_origin()
        self.tracker.restart()
        return out

    def _start_map(self, canvas: Floats, n_in: int, frame: NDArray[Any]) -> None:
        """A map from this frame (``n_in`` on pixels before the sphere warp; ``frame`` as it
        arrived, before the hot-pixel mask and the warp): the engine's start, and what the
        map's update block (``map_block``), ``_thin_map`` and ``_noise_map`` count from."""
        self._engine.start(canvas, self.rng)
        self._map_on = n_in
        self._map_structure = (neighbour_ratio(frame)
                               if self.cfg.tracking.bootstrap_structure > 0.0 else math.nan)
        self._map_learned = False
        self._map_iteration = self.iteration
        self._map_t_ns = self._t_ns

    def _keep_prior(self, prior: dict[str, Any], point: dict[str, float]
                    ) -> tuple[dict[str, float], dict[str, float], dict[str, Real]]:
        """Undo the frame's iterations: the states back to the prediction ``prior``, whose
        pose is ``point`` (wrapped). Returns (point, peak, sims)."""
        self._engine.state.update(prior)
        sims = self._engine.similarities()
        return point, {k: float(np.max(x)) for k, x in sims.items()}, sims

    def _follow(self, point: dict[str, float], n_on: int, dt_s: float) -> None:
        """Book-keeping of tracked frames: the on-pixel density and frame interval, and the
        velocity (gated)."""
        c = self.cfg
        tracking = self.tracker.state == 'tracking'
        if tracking:        # running means of the tracked frames' on-pixel counts, intervals
            self.tracker.note_tracked(n_on, dt_s)
        if c.cleanup.predict_velocity > 0.0:
            if tracking:
                self._track_velocity(point)
            else:       # gate the prediction: no velocity from frames of low quality
                self._prev = self._velocity = None

    # -- re-localisation -------------------------------------------------------------------

    def _relocalise(self, S: Any, point: dict[str, float],
                    near: dict[str, float] | None = None
                    ) -> tuple[dict[str, float], dict[str, float], dict[str, float],
                               dict[str, Real], Any] | None:
        """Global search and restarts while lost; the accepted restart's readout, or None
        (the states then continue from the best restart); with ``near`` (the gyro's
        prediction) only within ``imu.gate_deg`` of it, as any readout: the gyro rules out
        the rest."""
        eng, tc, tr = self._engine, self.cfg.tracking, self.tracker
        search = getattr(eng, 'relocalise', None)
        if search is None:
            return None
        best: tuple[float, dict[str, Any], tuple[Any, ...]] | None = None
        for _, start in search(S, tc.rolls, point.get('z', 0.0), tc.restarts):
            eng.set_point({k: start[k] for k in self.factors})
            for _ in range(tc.restart_iterations):
                eng.iterate(S)
            sims = eng.similarities()
            pt, spread, peak = self._readout(sims)
            target = eng.map_target(S, pt)
            ov = eng.overlap(target)
            if tr.sharpness(peak) < tc.relock or (      # a split state is no re-localisation
                    near is not None
                    and self._innovation_deg(pt, near) > self.cfg.imu.gate_deg):
                continue
            if best is None or ov > best[0]:
                best = (ov, {k: x.copy() for k, x in eng.state.items()},
                        (pt, spread, peak, sims, target))
        if best is None:
            return None
        eng.state.update(best[1])
        # a restart must also match the map at its pose distinctly (not noise, not a texture
        # that matches anywhere)
        q = min(tr.overlap_quality(best[0]), tr.psr_term(eng.distinctiveness(best[2][4])))
        if q < tc.relock:
            tr.quality = q
            return None
        tr.relocked(q)
        pt, spread, peak, sims, target = best[2]
        return pt, spread, peak, sims, target

    def _emit(self, t_ns: int, point: dict[str, float], spread: dict[str, float],
              peak: dict[str, float], sims: dict[str, Real], updated: bool, *,
              carried: bool = False) -> Estimate:
        # the output: the last tracked pose while lost or on a poor degraded frame, unless
        # the gyro carried the states (its prediction is a measurement of the motion)
        out = self._pose.update(point, self._engine.books, hold=not carried and self.tracker.poor,
                                tracking=self.tracker.state == 'tracking')
        est = Estimate(t_ns=int(t_ns), h=out['h'], v=out['v'], r=out['r'],
                       z=out['z'], confidence=peak, spread=spread,
                       iteration=self.iteration, map_updated=updated, similarity=sims,
                       quality=self.quality, state=self.state)
        self._last = est
        return est

    def _repeat(self, t_ns: int) -> Estimate:
        self._prev = self._velocity = None   # a skipped frame breaks the velocity
        last = self._last
        zeros = dict.fromkeys(self.factors, 0.0)
        if last is None:
            return Estimate(t_ns=int(t_ns), h=0.0, v=0.0, r=0.0, z=0.0, confidence=zeros,
                            spread=zeros, iteration=self.iteration, valid=False)
        return Estimate(t_ns=int(t_ns), h=last.h, v=last.v, r=last.r, z=last.z,
                        confidence=zeros, spread=last.spread, iteration=self.iteration,
                        map_updated=False, similarity=last.similarity, valid=False,
                        quality=last.quality, state=last.state)

    def map_image(self) -> Real:
        """The map as an intensity image on the canvas (allocentric, first frame's frame).

        Shapes:
            returns (canvas_height, canvas_width) float64.
        """
        return self._engine.map_image(None)

    def egocentric_map_image(self) -> Real:
        """The map moved by the current estimate into the camera's view (for overlays).

        Shapes:
            returns (canvas_height, canvas_width) float64; the frame sits at ``geometry.offset``.
        """
        return self._engine.map_image(dict(self._point))
