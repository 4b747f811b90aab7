"""The event-rate cap (core/events/ratecap.py) by hand, under any split, and in the packetizer."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

from hrn_vo_ros.core.events.arrays import EventArray, runs
from hrn_vo_ros.core.events.frames import frames_from_events, Packetizer
from hrn_vo_ros.core.events.packet_config import PacketizerConfig, paper_framing
from hrn_vo_ros.core.events.ratecap import RateCap
from hrn_vo_ros.errors import ConfigError

MS = 1_000_000


def events(t: list[int] | np.ndarray) -> EventArray:
    """Events at times ``t`` (ns), pixel (index mod 7, 0), polarity 1."""
    tt = np.asarray(t, np.int64)
    return EventArray.from_arrays(tt, np.arange(len(tt)) % 7, np.zeros(len(tt)),
                                  np.ones(len(tt)))


def kept_times(cap: RateCap, ev: EventArray, cuts: tuple[int, ...] = ()) -> list[int]:
    bounds = [0, *sorted(cuts), len(ev)]
    out = EventArray.concatenate([cap.push(ev[a:b])
                                  for a, b in zip(bounds[:-1], bounds[1:], strict=True)])
    assert cap.kept == len(out) and cap.kept + cap.dropped == len(ev)
    return [int(v) for v in out.t]


def test_runs_of_equal_keys_by_hand() -> None:
    """The index ranges the cap (and the background probe) walk window by window."""
    assert runs(np.array([3, 3, 5, 7, 7, 7])) == [(0, 2), (2, 3), (3, 6)]
    assert runs(np.array([-1])) == [(0, 1)] and runs(np.array([], np.int64)) == []


def test_windows_by_hand() -> None:
    """10 ms windows, at most 5 events each. Window 0 (20 events, nothing before): all kept.
    Window 1 (20 events after 20): share 1/4, indices 3, 7, 11, 15, 19. Window 2 (10 events
    after 20): share 1/4, indices 3 and 7. Window 4 (after an empty window 3): all kept.
    Window 5 (3 after 2): all kept (under the cap)."""
    w0 = [i * MS // 2 for i in range(20)]                  # 0 .. 9.5 ms
    w1 = [10 * MS + i * MS // 2 for i in range(20)]
    w2 = [20 * MS + i * MS for i in range(10)]
    w4 = [40 * MS, 41 * MS]
    w5 = [50 * MS, 50 * MS, 59 * MS]                        # equal times
    ev = events(w0 + w1 + w2 + w4 + w5)
    want = w0 + [w1[i] for i in (3, 7, 11, 15, 19)] + [w2[3], w2[7]] + w4 + w5
    assert kept_times(RateCap(5, 10 * MS), ev) == want
    cap = RateCap(5, 10 * MS)
    kept_times(cap, ev[:45])                   # windows 0, 1 and 5 events of window 2
    assert cap.share == 0.25 and cap.dropped == 15 + 4


def test_fractional_share_keeps_an_even_count() -> None:
    """Share 3/7 over 14 events: floor((i+1) 3/7) > floor(i 3/7) at i = 2, 4, 6, 9, 11, 13."""
    ev = events([0] * 7 + [10 * MS + i for i in range(14)])
    out = kept_times(RateCap(3, 10 * MS), ev)
    assert out == [0] * 7 + [10 * MS + i for i in (2, 4, 6, 9, 11, 13)]


@settings(max_examples=150, deadline=None)
@given(gaps=st.lists(st.sampled_from([0, 0, 1, 500, 2 * MS, 7 * MS, 30 * MS]), min_size=1,
                     max_size=400),
       cap=st.sampled_from([1.0, 2.5, 7.0, 40.0]),
       cuts=st.lists(st.integers(0, 400), max_size=15))
def test_any_split_gives_the_same_events(gaps: list[int], cap: float, cuts: list[int]) -> None:
    ev = events(np.cumsum(gaps) - 5 * MS)         # negative times too: floor division
    ref = kept_times(RateCap(cap, 10 * MS), ev)
    assert kept_times(RateCap(cap, 10 * MS), ev, tuple(c for c in cuts if c <= len(ev))) == ref
    # kept per window: n events at share r keep floor(n r) (telescoping sum), r = cap / the
    # previous window's count (1 when that is at most the cap, or the window was empty)
    win = ev.t // (10 * MS)
    kept = np.asarray(ref, np.int64) // (10 * MS)
    for w in np.unique(win):
        n, before = int(np.sum(win == w)), int(np.sum(win == w - 1))
        r = min(1.0, cap / before) if before else 1.0
        assert int(np.sum(kept == w)) == int(np.floor(n * r))


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ConfigError, match='positive cap'):
        RateCap(0, 10 * MS)
    with pytest.raises(ConfigError, match='positive cap'):
        RateCap(5, 0)
    with pytest.raises(ConfigError):
        PacketizerConfig(max_frame_hz=-1.0)


def test_packetizer_caps_the_frame_rate_streaming_equals_batch(
        rng: np.random.Generator) -> None:
    """4 M events/s for 200 ms with 1000-event packets and max_frame_hz 500: the cap is 0.5 M
    events/s (5000 per 10 ms window), so after the first window about 8 of 9 events go and the
    frames come at about 500/s (measured: 118 frames; without the cap 800)."""
    n = 800_000
    t = np.sort(rng.integers(0, 200 * MS, n)).astype(np.int64) + 10**9
    ev = EventArray.from_arrays(t, rng.integers(0, 240, n), rng.integers(0, 180, n),
                                np.ones(n, np.uint8))
    cfg = paper_framing(events_per_frame=1000, max_frame_hz=500.0)
    assert cfg.max_per_window == pytest.approx(5000.0)
    t_ref, img_ref = frames_from_events(ev, cfg)
    assert len(frames_from_events(ev, paper_framing(events_per_frame=1000))[0]) == 800
    # window 0 keeps its ~40 000 events (40 frames), the 19 others 5000 each (95 frames)
    assert 130 <= len(t_ref) <= 137
    pk = Packetizer(cfg)
    cuts = np.sort(rng.choice(np.arange(1, n), 50, replace=False))
    frames = []
    for a, b in zip(np.concatenate([[0], cuts]), np.concatenate([cuts, [n]]), strict=True):
        frames += pk.push(ev[a:b])
    assert [f.t_ns for f in frames] == t_ref.tolist()
    np.testing.assert_array_equal(np.stack([f.image for f in frames]), img_ref)
    assert pk.capped + len(frames) * 1000 + pk.pending == n
    # a rate under the cap changes nothing
    slow = ev[::10]                                   # 0.4 M events/s
    t_slow, _ = frames_from_events(slow, paper_framing(events_per_frame=1000,
                                                       max_frame_hz=500.0))
    assert len(t_slow) == 80
