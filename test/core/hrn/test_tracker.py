"""The tracker alone (core/hrn/tracking.py): quality terms and the state machine on
hand-made quality sequences, against hand-computed values."""

from __future__ import annotations

import math

import pytest

from hrn_vo_ros.core.hrn.config import TrackingConfig
from hrn_vo_ros.core.hrn.tracking import DENSE_RUN, Tracker


def states(tr: Tracker, qualities: list[float]) -> list[str]:
    out = []
    for q in qualities:
        tr.update(q)
        out.append(tr.state)
    return out


def test_hysteresis_degrade_lose_recover() -> None:
    """One bad frame degrades; lose_frames bad frames in a row lose; recover_frames good
    frames (>= recover, not merely >= degrade) bring it back."""
    tr = Tracker(TrackingConfig(degrade=0.45, recover=0.6, recover_frames=3, lose_frames=4))
    assert states(tr, [0.9, 0.4]) == ['tracking', 'degraded']
    # 0.5 is between degrade and recover: neither a good nor a bad frame; it breaks the run
    assert states(tr, [0.4, 0.4, 0.5, 0.4, 0.4]) == ['degraded'] * 5
    assert states(tr, [0.4]) == ['degraded']          # the 3rd bad frame in a row
    assert states(tr, [0.3]) == ['lost']              # the 4th
    assert states(tr, [0.7, 0.7, 0.5, 0.7, 0.7]) == ['lost'] * 5
    assert states(tr, [0.7]) == ['tracking']


def test_lost_counts_from_the_first_bad_frame() -> None:
    """The bad run that loses the track includes the frame that degraded it."""
    tr = Tracker(TrackingConfig(lose_frames=3, recover_frames=2))
    assert states(tr, [0.1, 0.1, 0.1]) == ['degraded', 'degraded', 'lost']
    tr.relocked(0.8)
    assert (tr.state, tr.relocalisations, tr.quality) == ('degraded', 1, 0.8)
    assert states(tr, [0.8]) == ['tracking']          # the re-lock counted as one good frame


def test_overlap_quality_against_the_running_reference() -> None:
    """q = (o - floor) / (ref - floor) clipped to [0, 1]; the first overlap sets ref (at
    least 2 floor); good tracking frames move ref by ref_rate."""
    tr = Tracker(TrackingConfig(overlap_floor=0.1, ref_rate=0.5, recover=0.6))
    assert tr.overlap_quality(0.5) == 1.0 and tr.ref == 0.5
    assert tr.overlap_quality(0.3) == pytest.approx(0.5)        # (0.3 - 0.1) / 0.4
    assert tr.overlap_quality(0.05) == 0.0
    tr.overlap_quality(0.7)
    tr.update(1.0)                                              # ref += 0.5 (0.7 - 0.5)
    assert tr.ref == pytest.approx(0.6)
    tr.overlap_quality(0.2)
    tr.update(0.2)                                              # degraded: ref stays
    assert tr.ref == pytest.approx(0.6)
    assert Tracker(TrackingConfig(overlap_floor=0.1)).overlap_quality(0.05) == 0.0  # ref 0.2


def test_distinctiveness_is_smoothed_and_mapped() -> None:
    """The PSR term: linear between psr_floor and psr_full on the exponential average."""
    tr = Tracker(TrackingConfig(psr_floor=6.0, psr_full=10.0, psr_rate=0.25))
    assert math.isnan(tr.distinct)
    assert tr.distinct_term(12.0) == 1.0 and tr.distinct == 12.0
    assert tr.distinct_term(4.0) == pytest.approx(1.0)          # 12 + 0.25 (4 - 12) = 10
    assert tr.distinct_term(4.0) == pytest.approx(0.625)        # 8.5 -> (8.5 - 6) / 4
    assert tr.distinct_term(float('nan')) == 1.0 and tr.distinct == pytest.approx(8.5)
    assert tr.psr_term(7.0) == pytest.approx(0.25)              # unsmoothed
    assert Tracker(TrackingConfig(psr_full=0.0)).distinct_term(1.0) == 1.0


def test_density_and_sparse_frames() -> None:
    tr = Tracker(TrackingConfig(hold_density=0.5, hold_dense=0.0, ref_rate=0.1))
    assert not tr.sparse(0)                       # no tracked frame yet: nothing is sparse
    tr.note_tracked(1000)
    tr.note_tracked(0)                            # 1000 + 0.1 (0 - 1000) = 900
    assert tr.density == pytest.approx(900.0)
    assert tr.sparse(449) and not tr.sparse(450)
    assert tr.unusual(449) and not tr.unusual(5000)             # hold_dense 0: never dense
    tr = Tracker(TrackingConfig(hold_density=0.5, hold_dense=1.5))
    assert not tr.unusual(10_000)                 # no tracked frame yet: nothing is dense
    tr.note_tracked(1000)
    assert tr.unusual(1501) and not tr.unusual(1500) and tr.unusual(499)
    for _ in range(DENSE_RUN):    # a long run of poor frames: dense ones are the motion now
        tr.update(0.0)
    assert not tr.unusual(1501) and tr.unusual(499)


def test_the_search_runs_on_the_first_lost_frame_and_every_nth() -> None:
    tr = Tracker(TrackingConfig(lose_frames=2, search_every=4))
    due = []
    for _ in range(11):
        tr.update(0.0)
        due.append(tr.search_due())
    # frame 1 degrades, frame 2 is the first lost one: searches on lost frames 1, 5, 9
    assert due == [False, True, False, False, False, True, False, False, False, True, False]
    tr.relocked(0.7)
    assert not tr.search_due() and tr.lost_run == 0
    tr.update(0.0)                                 # degraded again (one bad frame) ...
    tr.update(0.0)                                 # ... and lost: a fresh schedule
    assert tr.search_due()
    every = Tracker(TrackingConfig(lose_frames=1, search_every=1))
    flags = []
    for _ in range(4):
        every.update(0.1)
        flags.append(every.search_due())
    assert flags == [False, True, True, True]      # degraded first, then lost: every frame


@pytest.mark.parametrize('gap_intervals', [0.0, 10.0])
def test_a_gap_arms_the_search_of_poor_degraded_frames(gap_intervals: float) -> None:
    """The running interval of tracked frames (rate 0.5: 1/64 s, then 1/64 + 0.5 (3/64 -
    1/64) = 1/32 s, exact in binary); a frame more than 10 x 1/32 s later follows a gap, and
    from it poor degraded frames search on the lost schedule (the first, then every 4th)
    until the track is tracking again; off at 0."""
    tr = Tracker(TrackingConfig(ref_rate=0.5, lose_frames=25, search_every=4,
                                recover_frames=1, gap_intervals=gap_intervals))
    assert not tr.after_gap(5.0)                   # no interval yet: no gap
    tr.note_tracked(100, 1 / 64)
    tr.note_tracked(100, 3 / 64)
    tr.note_tracked(100, 0.0)                      # unknown interval: not counted
    assert tr.interval == 1 / 32
    assert not tr.after_gap(0.3125)                # exactly 10 intervals: no gap
    assert tr.after_gap(0.3126) == bool(gap_intervals)
    assert tr.gaps == (1 if gap_intervals else 0)
    due = []
    for _ in range(6):
        tr.update(0.1)                             # poor: degraded, not lost (25 frames)
        due.append(tr.search_due())
    on = bool(gap_intervals)
    assert tr.state == 'degraded' and tr.gap_search == on
    assert due == [on, False, False, False, on, False]
    tr.update(0.9)                                 # tracking again: disarmed
    tr.update(0.1)
    assert tr.state == 'degraded' and not tr.search_due() and not tr.gap_search


def test_a_gap_while_tracking_well_searches_nothing() -> None:
    tr = Tracker(TrackingConfig(ref_rate=0.5, gap_intervals=10.0))
    tr.note_tracked(100, 0.01)
    assert tr.after_gap(1.0)
    tr.update(0.8)                                 # the track holds across the gap
    assert tr.state == 'tracking' and not tr.search_due() and not tr.gap_search


@pytest.mark.parametrize('remap_s', [0.0, 0.5])
def test_a_new_map_is_due_after_remap_s_lost(remap_s: float) -> None:
    """remap_due counts frame time from the first lost frame: due on the first frame at or
    after remap_s, never while degraded, again from scratch after a recovery; off at 0."""
    tr = Tracker(TrackingConfig(lose_frames=2, recover_frames=1, remap_s=remap_s))
    due = []
    for i, q in enumerate([0.1, 0.1, 0.1, 0.1, 0.1, 0.1]):     # frames 0.2 s apart
        tr.update(q)
        due.append(tr.remap_due(i * 200_000_000))
    # degraded at 0.0 s, lost from 0.2 s: 0.5 s lost at 0.7 s, so the 0.8 s frame is due
    assert tr.lost_since == 200_000_000
    assert due == [False] * 4 + [bool(remap_s)] * 2
    tr.update(0.9)                                              # recovered: no loss to time
    assert tr.state == 'tracking' and not tr.remap_due(1_200_000_000)
    assert tr.lost_since is None
    tr.update(0.1)
    tr.update(0.1)                                              # lost again at 1.6 s
    assert not tr.remap_due(1_600_000_000)
    assert tr.remap_due(2_100_000_000) == bool(remap_s)        # exactly remap_s later
    tr.restart()
    assert tr.lost_since is None and tr.state == 'degraded'


def test_settling_lasts_from_a_relocalisation_until_tracking_or_lost() -> None:
    tr = Tracker(TrackingConfig(lose_frames=2, recover_frames=2))
    assert not tr.settling
    tr.relocked(0.7)                               # degraded, one good frame counted
    assert tr.settling and tr.state == 'degraded'
    tr.update(0.3)                                 # a poor frame: still settling
    assert tr.settling
    tr.update(0.9)
    tr.update(0.9)                                 # two good frames: tracking
    assert tr.state == 'tracking' and not tr.settling
    tr.relocked(0.7)
    tr.update(0.1)
    tr.update(0.1)                                 # lost again: not settling
    assert tr.state == 'lost' and not tr.settling


def test_quality_exactly_at_the_thresholds() -> None:
    """The documented comparisons at their bounds: a quality equal to ``degrade`` is not a bad
    frame (``< degrade``), one equal to ``recover`` is a good one (``>= recover``): it counts
    towards tracking and, while tracking, moves the reference overlap."""
    tr = Tracker(TrackingConfig(degrade=0.45, recover=0.6, recover_frames=2, lose_frames=2,
                                ref_rate=0.5, overlap_floor=0.1))
    assert states(tr, [0.45, 0.45]) == ['tracking', 'tracking']
    assert (tr.bad_run, tr.poor_run) == (0, 0)
    tr.overlap_quality(0.5)                                     # sets ref 0.5
    tr.overlap_quality(0.3)                                     # this frame's overlap
    tr.update(0.6)                                              # ref += 0.5 (0.3 - 0.5)
    assert tr.ref == pytest.approx(0.4)
    assert states(tr, [0.4, 0.6, 0.6]) == ['degraded', 'degraded', 'tracking']


def test_which_frames_are_poor() -> None:
    """Poor: lost, or degraded with a quality below ``degrade`` (not merely degraded)."""
    tr = Tracker(TrackingConfig(degrade=0.45, recover=0.6, recover_frames=5, lose_frames=3))
    assert not tr.poor                                          # tracking
    tr.update(0.3)
    assert (tr.state, tr.poor) == ('degraded', True)
    tr.update(0.5)
    assert (tr.state, tr.poor) == ('degraded', False)
    tr.update(0.45)
    assert (tr.state, tr.poor) == ('degraded', False)
    states(tr, [0.1, 0.1, 0.1])
    assert (tr.state, tr.poor) == ('lost', True)
    tr.update(0.9)
    assert (tr.state, tr.poor) == ('lost', True)                # lost frames are poor at any q


def test_terms_switched_off_and_undefined_ratios() -> None:
    """A term whose full value is not above its floor is off (1, no division by zero); an
    undefined distinctiveness ratio gives 1 while the term is on."""
    assert Tracker(TrackingConfig(sharp_floor=0.3, sharp_full=0.3)).sharpness({'h': 0.0}) == 1.0
    off = Tracker(TrackingConfig(psr_floor=6.0, psr_full=6.0))
    assert not off.psr_on and off.psr_term(7.0) == 1.0 and off.psr_term(1.0) == 1.0
    assert Tracker(TrackingConfig(psr_full=0.0)).psr_term(1.0) == 1.0
    on = Tracker(TrackingConfig(psr_floor=6.0, psr_full=10.0))
    assert on.psr_on and on.psr_term(float('nan')) == 1.0 and on.psr_term(8.0) == 0.5
