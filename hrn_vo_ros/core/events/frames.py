"""Fixed-count (or time-capped) event packets → binary downsampled event frames (paper Methods).

The settings are :class:`~hrn_vo_ros.core.events.packet_config.PacketizerConfig`. Polarity is
dropped. Coordinates are downsampled by a (possibly fractional) factor ``f``:

    x_out = floor((x + 0.5) / f)          # = round((x + 0.5) / f - 0.5): pixel centres map to bins
    W_out = ceil(W / f)

so 240x180 → 96x72 with f = 2.5 and 640x480 → 64x48 with f = 10, and every sensor pixel lands in
exactly one output pixel. (The paper's "divide by the factor and round" taken literally sends
x = 239 to round(95.6) = 96, one past the 96-pixel image; the centre-aligned form above is the
same division-and-rounding with pixel centres at x + 0.5.) A pixel is 1 when it received more
than ``min_events_per_pixel - 1`` events (``min_events_per_pixel = 1`` for shapes, 2 for the
arm), else 0. The frame time is the midpoint of the first and last event of the packet (int64
ns, rounded down).

**Auto factor** (``downsample: 0``, the default and the live configs): f = max(W / 96, H / 72,
1), so every sensor gives frames of at most 96x72 (:data:`.packet_config.VALIDATED_FRAME`, the
size the network was validated at): 2.5 on a DAVIS240C, 3.61 on 346x260, 6.67 on 640x480, 13.3
on 1280x720 (96x54).
Packets of the same event count then make about the same frames whatever the sensor's
resolution (docs/results.md: the rotation family on a 640x480 sensor).

**Time-capped packets** (``max_frame_ms`` > 0): a packet also closes once it spans
``max_frame_ms`` and holds at least ``min_frame_events`` events (:func:`packet_ends`), so a slow
camera or a sparse scene still gives frames at a steady rate (fixed 2000-event packets give a
scene of 3 k events/s 1.5 frames/s, too few to follow a rotation). Fast, busy scenes fill their
``events_per_frame`` first and are binned as before. With a fused gyro (``imu.enabled``, set by
the launch file's ``use_imu:=true`` and ``hrn-vo run --imu``) ``imu.max_frame_ms`` replaces
``max_frame_ms``: the gyro carries the motion between frames, so there the frame rate counts
more than what each frame holds; without it short sparse frames cost more than they give
(docs/results.md).

**Refilled packets** (``refill``, with ``max_frame_ms``): a packet that closes by time with fewer
than ``events_per_frame`` events is binned together with the events just before it, up to
``events_per_frame``, so each frame holds the newest ``events_per_frame`` events (a sliding
window) and its time is the midpoint of that window. A slow scene then gives frames at a steady
rate (one per ``max_frame_ms``) that hold as much as a full packet, where a thin packet alone
held too little to match against the map; busy streams fill their packets first and are binned
as before. The stateful form keeps the last ``events_per_frame`` binned events for this, so
streaming still equals batch. Not with the gyro's own limit (``imu.max_frame_ms``): the gyro
carries the motion between thin frames, and refilled ones, which span the motion of a whole
packet, cost accuracy there (docs/results.md).

**Event-rate cap** (``max_frame_hz`` > 0, 1500 by default; :mod:`.ratecap`): above
``events_per_frame * max_frame_hz`` events per second, counted over the previous window of
``rate_window_ms`` (windows fixed in sensor time), only an even share of the events goes on to
the packets (one in ``1 / share``, share = cap / that count). The network's time constants
count frames: a 640x480 sensor in a fast rotation makes 5-30 M events/s, thousands of frames a
second that each show a fraction of a frame pixel of motion, and errors add up over them (and a
core runs 600-1000 frames a second). A DAVIS240C rarely reaches the cap. The decision
depends only on the events, so streaming equals batch; :attr:`Packetizer.capped` counts the
events left out. It comes after denoising and the background measurement, before
rectification.

**Rectification** (``rectify``: ``none``, ``pinhole`` or ``equidistant``; :mod:`.camera`) moves
each sensor pixel to its rectified continuous position before the same division and rounding, so
the rounding happens once, at frame resolution. It is a per-sensor-pixel lookup table built from
the calibration (``calib.*``: from the dataset's ``calib.txt`` in ``hrn-vo run``, from
``camera_info`` in the packetizer node). Events whose rectified position falls outside the frame
are not counted into packets; :attr:`Packetizer.outside` counts them.

**Denoising** (``denoise_ms`` > 0; :mod:`.denoise`) drops, before rectification and binning,
the events that none of their 8 neighbouring sensor pixels supports within the same or the
previous bin of ``denoise_ms`` (background activity, hot pixels). It holds back the newest bin,
so frames come out up to ``denoise_ms`` later; :attr:`Packetizer.denoised` counts the drops.

**Noisy sensors** (``noise_floor_hz`` > 0; :mod:`.noise`): the stream's background is measured
on its first full window of ``noise_window_ms``: the rate of isolated events (no other event in
their 3x3 sensor pixels within ``noise_isolation_ms``; per second and sensor pixel) and their
share of all events. No frame comes out before it is, or before :meth:`Packetizer.finish` ends
a stream too short to measure (which keeps the normal threshold, as the batch form does). When
the rate is at least ``noise_floor_hz`` and the share at least ``noise_share``, every frame
pixel needs one event more than ``min_events_per_pixel`` for the whole stream: a lone
background event no longer lights a pixel, an edge's several events still do (a textured scene
in motion makes isolated events too, but among many others: the share keeps it out). The
decision is frozen: frames whose threshold changed under a running map would no longer match
it. :attr:`Packetizer.background_hz`, :attr:`Packetizer.background_share` and
:attr:`Packetizer.noisy` report it.

Packetizing is vectorised: one ``bincount`` (or one scatter when any event lights a pixel) over
``packet * H * W + pixel`` for all complete packets of a batch; no per-event Python.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.camera import rectified_pixels
from hrn_vo_ros.core.events.denoise import NeighbourFilter
from hrn_vo_ros.core.events.noise import BackgroundRate
from hrn_vo_ros.core.events.packet_config import out_size, PacketizerConfig
from hrn_vo_ros.core.events.ratecap import RateCap
from hrn_vo_ros.errors import ConfigError, DatasetError, TrackingError


def downsample_lut(n: int, f: float) -> NDArray[np.intp]:
    """Output index of every sensor coordinate 0..n-1: floor((x + 0.5) / f), clipped.

    Shapes:
        returns (n,) intp.
    """
    out = np.floor((np.arange(n, dtype=np.float64) + 0.5) / f).astype(np.intp)
    return np.minimum(out, out_size(n, f) - 1)


@dataclass(frozen=True, slots=True, eq=False)
class EventFrame:
    """One binary event frame.

    Shapes:
        image: (H, W) uint8, values 0 or 1.
    """

    t_ns: int
    image: NDArray[np.uint8]
    n_events: int
    t_first_ns: int
    t_last_ns: int


def packet_ends(t: NDArray[np.int64], cfg: PacketizerConfig) -> NDArray[np.intp]:
    """End indices (exclusive) of the complete packets of the event times ``t``.

    A packet starting at event ``s`` (time ``t[s]``) closes after ``events_per_frame`` events,
    or, with a time limit (``max_frame_ms`` > 0, or ``imu.max_frame_ms`` with ``imu.enabled``:
    :attr:`PacketizerConfig.frame_ms`), at the first event at or after ``t[s] + limit`` when
    it holds at least ``min_frame_events`` by then (else once it holds them; at most
    ``events_per_frame``, :attr:`PacketizerConfig.min_events`). A packet is
    complete only when later events cannot change it: its count is reached, or an event at or
    after its window's end has arrived. So the same events give the same packets however they
    are split into batches.

    Shapes:
        t: (n,) int64, non-decreasing; returns (n_packets,) intp, increasing.
    """
    n, k = len(t), cfg.events_per_frame
    span = cfg.max_frame_ns
    if span <= 0:
        return np.arange(k, n + 1, k, dtype=np.intp)
    m = cfg.min_events
    ends: list[int] = []
    s = 0
    while s < n:
        e_time = int(np.searchsorted(t, t[s] + span, 'left'))   # first event past the window
        e = min(s + k, max(s + m, e_time)) if e_time < n else s + k
        if e > n:
            break
        ends.append(e)
        s = e
    return np.asarray(ends, dtype=np.intp)


def frame_starts(ends: NDArray[np.intp], cfg: PacketizerConfig) -> NDArray[np.intp]:
    """Start indices of the frames of the packets ending at ``ends`` (the first packet starts
    at 0): each packet's own first event, or when packets are refilled
    (:attr:`PacketizerConfig.refills`) the ``events_per_frame``-th event before its end (at
    least 0), so that a packet closed early by time is binned with the events before it.

    Shapes:
        ends: (n,) intp; returns (n,) intp.
    """
    if cfg.refills:
        return np.maximum(ends - cfg.events_per_frame, 0).astype(np.intp)
    return np.concatenate([[0], ends[:-1]]).astype(np.intp)


def _packet_times(t: NDArray[np.int64], starts: NDArray[np.intp], ends: NDArray[np.intp]
                  ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """First, last and midpoint (rounded down) event time of the frames ``[starts, ends)``."""
    first, last = t[starts], t[ends - 1]
    return first, last, first + (last - first) // 2


class _Binner:
    """Flat pixel index lookup and packet binning shared by the stateful and batch forms."""

    def __init__(self, cfg: PacketizerConfig) -> None:
        self.cfg = cfg
        self.h, self.w = cfg.height, cfg.width
        self.lut_x = downsample_lut(cfg.sensor_width, cfg.factor).astype(np.int32)
        self.lut_y = (downsample_lut(cfg.sensor_height, cfg.factor) * cfg.width).astype(
            np.int32)
        self.lut: NDArray[np.int32] | None = None
        if cfg.rectify != 'none':
            self.lut = rectify_lut(cfg)

    def check(self, ev: EventArray) -> None:
        if len(ev) == 0:
            return
        xmax, ymax = int(ev.x.max()), int(ev.y.max())
        if xmax >= self.cfg.sensor_width or ymax >= self.cfg.sensor_height:
            msg = (f'event coordinate (x={xmax}, y={ymax}) max is outside the '
                   f'{self.cfg.sensor_width}x{self.cfg.sensor_height} sensor: set '
                   'sensor_width/sensor_height to the camera resolution')
            raise DatasetError(msg)

    def pixels(self, ev: EventArray) -> tuple[NDArray[np.int32], NDArray[np.int64]]:
        """Flat frame pixel and time of every event that lands in the frame."""
        if self.lut is None:
            out: NDArray[np.int32] = self.lut_x[ev.x]
            out += self.lut_y[ev.y]
            return out, ev.t
        flat = ev.y.astype(np.intp)
        flat *= self.cfg.sensor_width
        flat += ev.x
        pix = self.lut[flat]
        inside = pix >= 0
        if inside.all():
            return pix, ev.t
        return pix[inside], ev.t[inside]

    def images(self, pix: NDArray[np.int32], starts: NDArray[np.intp], ends: NDArray[np.intp],
               noisy: bool = False) -> NDArray[np.uint8]:
        """Binary frames of the events ``[starts[i], ends[i])`` of the flat pixel indices
        ``pix`` (consecutive packets, or overlapping windows with ``refill``; ``noisy``: a pixel
        needs one event more than ``min_events_per_pixel``)."""
        npx = self.h * self.w
        n_packets = len(ends)
        sizes = ends - starts
        if n_packets and np.array_equal(starts[1:], ends[:-1]):    # consecutive: no gather
            flat = pix[int(starts[0]):int(ends[-1])].astype(np.intp)
        else:                       # overlapping windows: gather each window's events
            idx = np.arange(int(sizes.sum()), dtype=np.intp)
            idx += np.repeat(starts - (np.cumsum(sizes) - sizes), sizes)
            flat = pix[idx].astype(np.intp)
        flat += np.repeat(np.arange(n_packets, dtype=np.intp) * npx, sizes)
        need = self.cfg.min_events_per_pixel + int(noisy)
        if need <= 1:
            out = np.zeros(n_packets * npx, np.uint8)
            out[flat] = 1
        else:
            counts = np.bincount(flat, minlength=n_packets * npx)
            out = (counts >= need).astype(np.uint8)
        return out.reshape(n_packets, self.h, self.w)


def check_event_frame(image: NDArray[Any], width: int, height: int, max_fill: float,
                      section: str) -> tuple[NDArray[np.float64], bool]:
    """An estimator's check of one event frame: the frame as float64 and whether it is usable.

    A frame is unusable when it has no pixel on, or more than ``max_fill`` of its pixels on (the
    noise a still camera fills fixed-count packets with); estimators repeat the previous pose
    for such frames.

    Args:
        image: The event frame (binary, or any non-negative values).
        width: The frame width the estimator is configured for.
        height: Its frame height.
        max_fill: The largest usable fraction of pixels on.
        section: The configuration section naming width/height (for the error message).

    Returns:
        ``(frame, usable)``.

    Shapes:
        image: (height, width); frame: (height, width).

    Raises:
        TrackingError: for a frame of the wrong shape or with non-finite values.
    """
    if image.shape != (height, width):
        raise TrackingError(f'event frame has shape {image.shape}, expected ({height}, {width}): '
                            f'match the packetizer size to {section} width/height')
    img = np.asarray(image, dtype=np.float64)
    if image.dtype.kind not in 'biu' and not np.all(np.isfinite(img)):   # ints are finite
        raise TrackingError('event frame contains non-finite values')
    on = int(np.count_nonzero(img))
    return img, not (on == 0 or on > max_fill * img.size)


def rectify_lut(cfg: PacketizerConfig) -> NDArray[np.int32]:
    """Flat frame pixel of every sensor pixel (``y * sensor_width + x``) under ``cfg.rectify``.

    -1 marks sensor pixels whose rectified position lies outside the frame.

    Raises:
        ConfigError: if rectification is on and the calibration is unknown.
    """
    c = cfg.calib
    if cfg.rectify != 'none' and not c.known:
        raise ConfigError(f'rectify = {cfg.rectify} needs the camera calibration: set '
                          'calib.fx/fy/cx/cy/dist (hrn-vo run reads calib.txt; the packetizer '
                          'node reads camera_info)')
    xr, yr = rectified_pixels(cfg.rectify, cfg.sensor_width, cfg.sensor_height, c.fx, c.fy,
                              c.cx, c.cy, c.dist)
    u = np.floor((xr + 0.5) / cfg.factor)
    v = np.floor((yr + 0.5) / cfg.factor)
    inside = (u >= 0) & (u < cfg.width) & (v >= 0) & (v < cfg.height)
    flat = np.where(inside, v * cfg.width + u, -1)
    return flat.astype(np.int32).ravel()


def denoiser(cfg: PacketizerConfig) -> NeighbourFilter | None:
    """The background-activity filter of ``cfg`` (None when ``denoise_ms`` is 0)."""
    if cfg.denoise_ms <= 0.0:
        return None
    return NeighbourFilter(cfg.sensor_width, cfg.sensor_height,
                           max(1, round(cfg.denoise_ms * 1e6)))


def background(cfg: PacketizerConfig) -> BackgroundRate | None:
    """The background-rate measurement of ``cfg`` (None when ``noise_floor_hz`` is 0)."""
    if cfg.noise_floor_hz <= 0.0:
        return None
    window = max(1, round(cfg.noise_window_ms * 1e6))
    return BackgroundRate(cfg.sensor_width, cfg.sensor_height, window,
                          min(window, max(1, round(cfg.noise_isolation_ms * 1e6))))


def rate_cap(cfg: PacketizerConfig) -> RateCap | None:
    """The event-rate cap of ``cfg`` (None when ``max_frame_hz`` is 0)."""
    if cfg.max_frame_hz <= 0.0:
        return None
    return RateCap(cfg.max_per_window, max(1, round(cfg.rate_window_ms * 1e6)))


def _noisy(cfg: PacketizerConfig, probe: BackgroundRate | None) -> bool:
    """Whether a stream whose background ``probe`` measured (None, or not measured yet: no)
    needs one event more per frame pixel: isolated rate and share at or above the floors."""
    return probe is not None and probe.rate_hz is not None and probe.share is not None \
        and probe.rate_hz >= cfg.noise_floor_hz and probe.share >= cfg.noise_share


def frames_from_events(ev: EventArray, cfg: PacketizerConfig
                       ) -> tuple[NDArray[np.int64], NDArray[np.uint8]]:
    """All complete packets of ``ev`` as frames (a trailing partial packet is dropped).

    Args:
        ev: Events in time order.
        cfg: Packetizer settings.

    Returns:
        ``(t_ns, images)``: packet midpoints and binary frames.

    Shapes:
        t_ns: (n,) int64; images: (n, H, W) uint8.

    Raises:
        DatasetError: if an event lies outside the sensor.
    """
    b = _Binner(cfg)
    b.check(ev)
    probe = background(cfg)
    if probe is not None:       # not measured (too short): the normal threshold, as finish()
        probe.push(ev.t, ev.x, ev.y)
    f = denoiser(cfg)
    if f is not None:
        ev = EventArray.concatenate([f.push(ev), f.flush()])
    cap = rate_cap(cfg)
    if cap is not None:
        ev = cap.push(ev)
    pix, t = b.pixels(ev)
    ends = packet_ends(t, cfg)
    starts = frame_starts(ends, cfg)
    images = b.images(pix, starts, ends, _noisy(cfg, probe))
    return _packet_times(t, starts, ends)[2], images


class Packetizer:
    """Stateful packetizer: feed event batches of any size, get every completed frame.

    Partial packets carry over between calls, so a frame may span many pushes and one push may
    complete many frames.

    Args:
        cfg: Packetizer settings.
    """

    def __init__(self, cfg: PacketizerConfig | None = None) -> None:
        self.cfg = cfg if cfg is not None else PacketizerConfig()
        self._b = _Binner(self.cfg)
        self._pend_pix: list[NDArray[np.int32]] = []
        self._pend_t: list[NDArray[np.int64]] = []
        self._pending = 0
        # (with refill: the newest binned events, which a packet closed by time is filled
        # up with)
        self._hist_pix: NDArray[np.int32] = np.empty(0, np.int32)
        self._hist_t: NDArray[np.int64] = np.empty(0, np.int64)
        self._last_t: int | None = None
        self._outside = 0
        self._by_time = 0
        self._filter = denoiser(self.cfg)
        self._probe = background(self.cfg)
        self._cap = rate_cap(self.cfg)
        self._ended = False             # finish() was called: no more waiting for the probe

    @property
    def pending(self) -> int:
        """Events waiting for their packet to fill up."""
        return self._pending

    @property
    def outside(self) -> int:
        """Events so far whose rectified position fell outside the frame (not binned)."""
        return self._outside

    @property
    def by_time(self) -> int:
        """Frames so far whose packet closed by its time limit with fewer than
        ``events_per_frame`` events (refilled when :attr:`PacketizerConfig.refills`): a slow or
        sparse scene."""
        return self._by_time

    @property
    def denoised(self) -> int:
        """Events so far dropped by the background-activity filter (``denoise_ms``)."""
        return 0 if self._filter is None else self._filter.dropped

    @property
    def capped(self) -> int:
        """Events so far left out by the event-rate cap (``max_frame_hz``)."""
        return 0 if self._cap is None else self._cap.dropped

    @property
    def cap_share(self) -> float:
        """The share of the events the rate cap bins now (1: not capping, or no cap)."""
        return 1.0 if self._cap is None else self._cap.share

    @property
    def denoise_pending(self) -> int:
        """Events the background-activity filter holds back (its newest, open bin)."""
        return 0 if self._filter is None else self._filter.pending

    @property
    def background_hz(self) -> float | None:
        """The measured background rate, Hz per sensor pixel (None: ``noise_floor_hz`` off,
        or not measured yet)."""
        return None if self._probe is None else self._probe.rate_hz

    @property
    def background_share(self) -> float | None:
        """Isolated events per event of the measured window (None: off, or not measured
        yet)."""
        return None if self._probe is None else self._probe.share

    @property
    def noisy(self) -> bool:
        """Whether frame pixels need one event more (``noise_floor_hz``)."""
        return _noisy(self.cfg, self._probe)

    def reset(self) -> None:
        """Drop pending events, the time-order memory and the background measurement."""
        self._pend_pix, self._pend_t, self._pending, self._last_t = [], [], 0, None
        self._hist_pix, self._hist_t = np.empty(0, np.int32), np.empty(0, np.int64)
        self._ended = False
        if self._filter is not None:
            self._filter.reset()
        if self._probe is not None:
            self._probe.reset()
        if self._cap is not None:
            self._cap.reset()

    def push(self, ev: EventArray) -> list[EventFrame]:
        """Add events (in time order) and return the frames they complete.

        Raises:
            DatasetError: if an event lies outside the sensor, or the batch starts before the
                end of the previous one.
        """
        if len(ev) == 0:
            return []
        self._b.check(ev)
        if self._last_t is not None and int(ev.t[0]) < self._last_t:
            msg = (f'events go back in time: batch starts at {int(ev.t[0])} ns after an event '
                   f'at {self._last_t} ns; feed batches in time order (or reset())')
            raise DatasetError(msg)
        self._last_t = int(ev.t[-1])
        # (after finish() the probe stops: a threshold decided at the end stays)
        waiting = not self._ended and self._probe is not None \
            and self._probe.push(ev.t, ev.x, ev.y) is None
        if self._filter is not None:
            ev = self._filter.push(ev)
        if self._cap is not None:
            ev = self._cap.push(ev)
        pix, t = self._b.pixels(ev)
        self._outside += len(ev) - len(t)
        total = self._pending + len(t)
        # frames also wait for the background rate's measurement
        if total < self._fewest or waiting:
            self._pend_pix.append(pix)
            self._pend_t.append(t)
            self._pending = total
            return []
        if self._pending:
            pix = np.concatenate([*self._pend_pix, pix])
            t = np.concatenate([*self._pend_t, t])
        return self._close(pix, t, total)

    def finish(self) -> list[EventFrame]:
        """End of the stream: the complete packets held back for the background measurement
        (``noise_floor_hz``) come out, with the normal threshold when the stream ended before
        its window was measured (too short to tell: counted as quiet). The partial packet
        stays pending; later pushes no longer wait. Nothing when nothing is held."""
        self._ended = True
        if self._pending < self._fewest:
            return []
        return self._close(np.concatenate(self._pend_pix), np.concatenate(self._pend_t),
                           self._pending)

    @property
    def _fewest(self) -> int:
        """The fewest events that can close a packet."""
        return self.cfg.min_events if self.cfg.max_frame_ns > 0 else \
            self.cfg.events_per_frame

    def _close(self, pix: NDArray[np.int32], t: NDArray[np.int64],
               total: int) -> list[EventFrame]:
        """The frames of every complete packet of the pending events ``pix``, ``t``
        (``total`` of them); the rest stays pending."""
        ends = packet_ends(t, self.cfg)
        used = int(ends[-1]) if len(ends) else 0
        rest = total - used
        self._pend_pix = [pix[used:].copy()] if rest else []
        self._pend_t = [t[used:].copy()] if rest else []
        self._pending = rest
        if not len(ends):
            return []
        self._by_time += int(np.count_nonzero(np.diff(ends, prepend=0)
                                              < self.cfg.events_per_frame))
        if self.cfg.refills:
            k, h = self.cfg.events_per_frame, len(self._hist_t)
            if h and int(ends[0]) < k:        # the first window reaches into the binned events
                pix = np.concatenate([self._hist_pix, pix[:used]])
                t = np.concatenate([self._hist_t, t[:used]])
                ends = ends + h
            e = int(ends[-1])                 # the newest k binned events, for the next call
            self._hist_pix, self._hist_t = pix[max(e - k, 0):e].copy(), t[max(e - k, 0):e].copy()
        starts = frame_starts(ends, self.cfg)
        first, last, mid = _packet_times(t, starts, ends)
        images = self._b.images(pix, starts, ends, self.noisy)
        sizes = ends - starts
        return [EventFrame(t_ns=int(mid[i]), image=images[i], n_events=int(sizes[i]),
                           t_first_ns=int(first[i]), t_last_ns=int(last[i]))
                for i in range(len(ends))]
