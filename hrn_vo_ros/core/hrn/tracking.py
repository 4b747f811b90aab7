"""Tracking quality and state of the HRN (``docs/model.md``, section 9): numbers only.

The network measures, on each frame, the frame-map overlap at its estimate, the factors' peak
similarities and the distinctiveness of the match (peak-to-sidelobe ratio); :class:`Tracker`
turns them into a quality in [0, 1] and the state ``tracking`` / ``degraded`` / ``lost`` with
hysteresis, and keeps the running references (overlap, on-pixel density) they are judged
against. What the network does with them (hold a poor frame, gate the map and the velocity,
re-localise while lost) stays in :mod:`.network`, which owns the engine.

Public API: ``Tracker(cfg: TrackingConfig)`` with ``reset()``, ``overlap_quality(o)``,
``sharpness(peak)``, ``distinct_term(r)``, ``psr_term(r)``, ``update(q)``, ``search_due()``,
``bootstrap_due()``, ``remap_due(t_ns)``, ``restart()``, ``relocked(q)``, ``psr_on``, ``poor``,
``sparse(n_on)``, ``unusual(n_on)``, ``after_gap(dt_s)``, ``gap_search``,
``note_tracked(n_on, dt_s)``, ``reported`` and the attributes ``state``, ``quality``,
``overlap``, ``distinct``, ``relocalisations``, ``held_frames``, ``jumps``, ``established``,
``restarts``, ``lost_since``, ``interval``, ``gaps``, ``poor_run``.
"""

from __future__ import annotations

import math

from hrn_vo_ros.core.hrn.config import TrackingConfig

#: Dense poor frames are held only among the first this many poor frames in a row.
DENSE_RUN = 3


class Tracker:
    """Quality terms, the running references and the state machine with hysteresis.

    Args:
        cfg: The ``tracking`` section of the resonator configuration.
    """

    def __init__(self, cfg: TrackingConfig) -> None:
        self.cfg = cfg
        self.reset()

    def reset(self) -> None:
        """Back to a fresh track: state tracking, no references yet, counters at zero."""
        self.quality = 1.0              # quality of the last valid frame
        self.relocalisations = 0        # accepted re-localisations
        self.held_frames = 0            # poor sparse frames whose update was undone
        self.jumps = 0                  # frames whose roll readout jumped (jump_deg)
        self.established = False        # a frame after the map's first one reached tracking
        self.restarts = 0               # maps started afresh (bootstrap_due)
        self.interval: float | None = None  # running mean interval (s) of tracked frames
        self.gaps = 0                   # frames that followed a gap (after_gap)
        self.poor_run = 0               # frames of quality < degrade in a row, across new maps
        self._new_map('tracking')

    def restart(self) -> None:
        """A new map (the network's bootstrap): its references start again and the track is
        degraded until it establishes itself on the new map."""
        self._new_map('degraded')
        self.restarts += 1

    def _new_map(self, state: str) -> None:
        """What a map's references and runs start from, in ``state``."""
        self.state = state              # tracking / degraded / lost
        self.overlap = 1.0              # the last frame's frame-map overlap at the estimate
        self.distinct = math.nan        # smoothed distinctiveness (NaN: not computed yet)
        self.density: float | None = None   # running mean on-pixel count of tracked frames
        self.ref: float | None = None   # running reference overlap o_ref
        self._good_run = 0              # consecutive frames of quality >= recover
        self.bad_run = 0                # consecutive frames of quality < degrade
        self.lost_run = 0               # consecutive lost frames (the search's schedule)
        self.lost_since: int | None = None  # frame time (ns) at which the track was lost
        self._gap = False               # a gap armed the search of poor degraded frames
        self.settling = False           # degraded since an accepted re-localisation

    # -- quality terms ----------------------------------------------------------------------

    def overlap_quality(self, overlap: float) -> float:
        """Quality in [0, 1] of a frame-map overlap, relative to the running reference (the
        first overlap after the map's frame sets it); records ``overlap``."""
        tc = self.cfg
        self.overlap = overlap
        ref = self.ref
        if ref is None:
            ref = self.ref = max(overlap, 2.0 * tc.overlap_floor)
        return min(max((overlap - tc.overlap_floor) / (ref - tc.overlap_floor), 0.0), 1.0)

    def sharpness(self, peak: dict[str, float]) -> float:
        """Quality term of the factors' peak similarities (the lowest of h, v, r): a state
        split between two poses (a roll ambiguous by 180 degrees, a shift between two
        matches) has a low peak even where the overlap looks fine."""
        tc = self.cfg
        if tc.sharp_full <= tc.sharp_floor:
            return 1.0
        c = min(peak.get(k, 1.0) for k in ('h', 'v', 'r'))
        return min(max((c - tc.sharp_floor) / (tc.sharp_full - tc.sharp_floor), 0.0), 1.0)

    @property
    def psr_on(self) -> bool:
        """Whether the distinctiveness term is on (``psr_full`` > ``psr_floor``)."""
        return self.cfg.psr_full > self.cfg.psr_floor

    @property
    def poor(self) -> bool:
        """The last frame was poor: lost, or degraded with quality below ``degrade`` (its
        readout is no measurement: the output holds, or follows the gyro)."""
        return self.state == 'lost' or (self.state == 'degraded'
                                        and self.quality < self.cfg.degrade)

    def distinct_term(self, ratio: float) -> float:
        """Quality term of the frame's distinctiveness (its peak-to-sidelobe ratio against the
        map at the estimate), smoothed into :attr:`distinct`: a frame of noise, or a texture
        finer than the frame's pixels, overlaps a map learned at its own (wrong) poses as well
        as ever, but it matches there no better than at any other shift. A NaN ratio (an
        engine without the measure) gives 1."""
        if not self.psr_on or not math.isfinite(ratio):
            return 1.0
        d = self.distinct
        self.distinct = d = ratio if math.isnan(d) else d + self.cfg.psr_rate * (ratio - d)
        return self.psr_term(d)

    def psr_term(self, ratio: float) -> float:
        """A distinctiveness (peak-to-sidelobe ratio) as a quality term in [0, 1], unsmoothed
        (a re-localisation candidate is judged on its own)."""
        tc = self.cfg
        if not self.psr_on or not math.isfinite(ratio):
            return 1.0
        return min(max((ratio - tc.psr_floor) / (tc.psr_full - tc.psr_floor), 0.0), 1.0)

    # -- the state machine ------------------------------------------------------------------

    def update(self, q: float) -> None:
        """One frame of quality ``q``: the state with hysteresis; tracking frames of good
        quality move the reference overlap towards theirs."""
        tc = self.cfg
        self.quality = q
        self._good_run = self._good_run + 1 if q >= tc.recover else 0
        self.bad_run = self.bad_run + 1 if q < tc.degrade else 0
        self.poor_run = self.poor_run + 1 if q < tc.degrade else 0
        if self.state == 'tracking' and q < tc.degrade:
            self.state = 'degraded'
        elif self.state == 'degraded':
            if self._good_run >= tc.recover_frames:
                self.state = 'tracking'
            elif self.bad_run >= tc.lose_frames:
                self.state = 'lost'
        elif self.state == 'lost' and self._good_run >= tc.recover_frames:
            self.state = 'tracking'     # the states found the map again by themselves
        if self.state == 'tracking' and self.ref is not None and q >= tc.recover:
            self.ref += tc.ref_rate * (self.overlap - self.ref)
        self.lost_run = self.lost_run + 1 if self.state == 'lost' else 0
        self.established = self.established or self.state == 'tracking'
        if self.state != 'degraded':    # tracking again, or lost: the lost schedule rules
            self._gap = self.settling = False

    @property
    def reported(self) -> str:
        """The state the outputs report: :attr:`state`, except that a degraded track whose
        last ``lose_frames`` frames were all poor is reported ``lost`` although new maps
        (:meth:`restart`) started its state machine again in between: a track that restarts
        its map on every frame (it never established one) never reaches ``lost`` by itself,
        yet its output holds as a lost one does."""
        if self.state == 'degraded' and self.poor_run >= self.cfg.lose_frames:
            return 'lost'
        return self.state

    def search_due(self) -> bool:
        """Whether this frame runs the global search: the first lost frame and every
        ``search_every``-th after it; after a gap (:meth:`after_gap`) also the first poor
        degraded frame and every ``search_every``-th poor one after it."""
        every = self.cfg.search_every
        if self.state == 'lost':
            return (self.lost_run - 1) % every == 0
        return self._gap and self.poor and (self.bad_run - 1) % every == 0

    @property
    def gap_search(self) -> bool:
        """A search now would be one armed by a gap (the track is not lost): one that is not
        accepted must leave the states alone, they may still hold the pose."""
        return self._gap and self.state != 'lost'

    def after_gap(self, dt_s: float) -> bool:
        """Whether a frame ``dt_s`` seconds after the previous one follows a gap: more than
        ``gap_intervals`` times the running mean interval of tracked frames (never before two
        tracked frames set it). A gap arms the search of poor degraded frames until the
        track is tracking or lost again."""
        n, iv = self.cfg.gap_intervals, self.interval
        if not n or iv is None or not dt_s > n * iv:
            return False
        self._gap = True
        self.gaps += 1
        return True

    def bootstrap_due(self) -> bool:
        """Whether the map should start afresh from the current frame: it has never been
        tracked and the last ``bootstrap_frames`` frames were all poor (a jump the states have
        not caught up with yet converges within fewer frames)."""
        n = self.cfg.bootstrap_frames
        return bool(n) and not self.established and self.poor and self.bad_run >= n

    def remap_due(self, t_ns: int) -> bool:
        """Whether a lost track should start a new map: lost for ``remap_s`` (frame time)
        without a re-localisation. Call once per frame (it keeps the time the loss began)."""
        if self.state != 'lost':
            self.lost_since = None
            return False
        if self.lost_since is None:
            self.lost_since = t_ns
        return self.cfg.remap_s > 0.0 and t_ns - self.lost_since >= self.cfg.remap_s * 1e9

    def relocked(self, q: float) -> None:
        """An accepted re-localisation of quality ``q``: degraded, one good frame counted."""
        self.quality, self.state = q, 'degraded'
        self._good_run, self.bad_run, self.lost_run, self.poor_run = 1, 0, 0, 0
        self.settling = True
        self.relocalisations += 1

    # -- on-pixel density -------------------------------------------------------------------

    def sparse(self, n_on: int) -> bool:
        """Whether a frame of ``n_on`` on pixels is sparse (``hold_density`` of the running
        mean of tracked frames; never before the first tracked frame)."""
        return self.density is not None and n_on < self.cfg.hold_density * self.density

    def unusual(self, n_on: int) -> bool:
        """Whether a frame of ``n_on`` on pixels is sparse (:meth:`sparse`) or dense: more
        than ``hold_dense`` times the running mean of tracked frames (0: never dense), and
        among the first ``DENSE_RUN`` poor frames in a row (faster motion spreads a packet
        over more pixels: a long run of dense frames is the motion, not a pause's noise)."""
        dense = self.cfg.hold_dense
        return self.sparse(n_on) or (dense > 0.0 and self.bad_run < DENSE_RUN
                                     and self.density is not None and n_on > dense * self.density)

    def note_tracked(self, n_on: int, dt_s: float = 0.0) -> None:
        """A tracked frame's on-pixel count, and its interval ``dt_s`` since the previous
        frame (0: unknown), into their running means (rate ``ref_rate``)."""
        a = self.cfg.ref_rate
        self.density = _running(self.density, float(n_on), a)
        if dt_s > 0.0:
            self.interval = _running(self.interval, dt_s, a)


def _running(mean: float | None, x: float, rate: float) -> float:
    """An exponential running mean moved towards ``x`` at ``rate``; ``x`` itself first."""
    return x if mean is None else mean + rate * (x - mean)
