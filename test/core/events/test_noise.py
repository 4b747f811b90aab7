"""The background rate (core/events/noise.py) and the packetizer's noisy-sensor threshold
(PacketizerConfig.noise_floor_hz), on hand-built events."""

from __future__ import annotations

from dataclasses import replace

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.frames import frames_from_events, Packetizer
from hrn_vo_ros.core.events.noise import BackgroundRate
from hrn_vo_ros.core.events.packet_config import PacketizerConfig
from hrn_vo_ros.errors import ConfigError

S = 1_000_000_000


MS = 1_000_000


def ev_of(rows: list[tuple[int, int, int]]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, x, y) arrays of ``(t_ns, x, y)`` rows, sorted by time (stable)."""
    a = np.array(sorted(rows, key=lambda r: r[0]), np.int64).reshape(-1, 3)
    return a[:, 0], a[:, 1], a[:, 2]


def test_isolated_events_by_hand() -> None:
    """10x10 pixels, 1 s windows, 100 ms bins; window 0 (partial) is ignored. Window 1:
    a lone event (isolated); two diagonal neighbours in adjacent bins, the second exactly on a
    bin's start (neither); one pixel twice, three bins apart (both); two events two pixels
    apart in one bin (both); two neighbours two bins apart, one on a bin start (both); an
    event in the window's last ns (isolated). 10 events, 8 isolated, on 100 px in 1 s."""
    rows = [(S // 2, 5, 5), (S - 1, 5, 5), (S - 1, 6, 5),        # window 0: ignored
            (S + 50 * MS, 5, 5),                                     # lone
            (S + 250 * MS, 1, 1), (S + 300 * MS, 2, 2),              # bins 2, 3: neighbours
            (S + 450 * MS, 8, 8), (S + 720 * MS, 8, 8),              # bins 4, 7: both alone
            (S + 910 * MS, 0, 0), (S + 910 * MS, 2, 0),              # two px apart: alone
            (S + 400 * MS, 4, 1), (S + 600 * MS, 4, 2),              # bins 4, 6: alone
            (2 * S - 1, 9, 9)]                                       # last bin: alone
    t, x, y = ev_of(rows)
    probe = BackgroundRate(10, 10, S, 100 * MS)
    assert probe.push(t, x, y) is None                 # no event after window 1 yet
    assert probe.push(*ev_of([(2 * S, 9, 9)])) == pytest.approx(0.08)
    assert probe.total_hz == pytest.approx(0.10) and probe.share == pytest.approx(0.8)
    assert probe.push(*ev_of([(3 * S, 0, 0)])) == pytest.approx(0.08)      # frozen
    probe.reset()
    assert probe.rate_hz is None and probe.total_hz is None and probe.share is None


def brute_isolated(t: np.ndarray, x: np.ndarray, y: np.ndarray, start: int, w: int,
                   b: int) -> int:
    """Isolated events of the window [start, start + w), event against event (reference)."""
    m = (t >= start) & (t < start + w)
    k, xs, ys = (t[m] - start) // b, x[m], y[m]
    near = ((np.abs(k[:, None] - k[None, :]) <= 1) & (np.abs(xs[:, None] - xs[None, :]) <= 1)
            & (np.abs(ys[:, None] - ys[None, :]) <= 1))
    return int(np.count_nonzero(near.sum(axis=1) == 1))


@pytest.mark.parametrize('pieces', [1, 2, 5, 40, 300])
def test_any_batching_gives_the_brute_force_count(rng: np.random.Generator,
                                                  pieces: int) -> None:
    """Random events on 12x9 px with many equal timestamps (1 ms resolution, 4 ms bins):
    every way of cutting the stream gives the pairwise reference count."""
    n = 600
    t = np.sort(rng.integers(0, 300, n)) * MS
    x, y = rng.integers(0, 12, n), rng.integers(0, 9, n)
    w = 100 * MS                                         # window 1: [100, 200) ms
    want = brute_isolated(t, x, y, w, w, 4 * MS)
    count = int(np.count_nonzero((t >= w) & (t < 2 * w)))
    assert 0 < want < count
    probe = BackgroundRate(12, 9, w, 4 * MS)
    cuts = np.unique(np.concatenate([[0, n], rng.integers(0, n, pieces - 1)]))
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        probe.push(t[a:b], x[a:b], y[a:b])
    assert probe.rate_hz == pytest.approx(want * 1e9 / (w * 108))
    assert probe.share == pytest.approx(want / count)


def test_poisson_background_is_isolated_at_the_predicted_share(
        rng: np.random.Generator) -> None:
    """Background alone at 2 Hz per pixel, 100x100 px, 10 ms bins: another event in an
    event's 3x3 x 3 cells is Poisson with mean 2 Hz x 10 ms x (cells there), so the expected
    share is the mean over the window's cells of exp(-0.02 cells) (27 inside: 0.5827; fewer on the
    border and in the first and last bin): 0.5896; 20 k events give it within about 0.4 %."""
    r, n_px, w, b = 2.0, 100, S, 10 * MS
    n = rng.poisson(r * n_px * n_px * 2.2)
    t = np.sort(rng.integers(0, 2.2 * S, n))
    x, y = rng.integers(0, n_px, n), rng.integers(0, n_px, n)
    probe = BackgroundRate(n_px, n_px, w, b)
    probe.push(t, x, y)
    side = np.array([2] + [3] * (n_px - 2) + [2], float)             # neighbours per axis
    bins = np.array([2] + [3] * 98 + [2], float)
    cells = bins[:, None, None] * side[None, :, None] * side[None, None, :]
    expect = float(np.mean(np.exp(-r * b * 1e-9 * cells)))
    assert expect == pytest.approx(0.5896, abs=1e-4)
    assert probe.share == pytest.approx(expect, abs=0.012)
    assert probe.total_hz == pytest.approx(r, rel=0.03)


def test_bad_settings_are_refused() -> None:
    for args in [(0, 5, S, MS), (5, 0, S, MS), (5, 5, 0, MS), (5, 5, S, 0), (5, 5, MS, S)]:
        with pytest.raises(ConfigError, match='positive'):
            BackgroundRate(*args)
    with pytest.raises(ConfigError):
        PacketizerConfig(noise_floor_hz=-1.0)
    with pytest.raises(ConfigError):
        PacketizerConfig(noise_share=1.5)


def scene(rate_hz: float, rng: np.random.Generator) -> EventArray:
    """A 40x20 sensor: background events at ``rate_hz`` per pixel for 2 s (uniform pixels,
    Poisson times), and from 0.5 s on an 'edge' that fires every sensor pixel of column 7
    four times per 10 ms."""
    w, h = 40, 20
    n = rng.poisson(rate_hz * w * h * 2.0)
    t_bg = np.sort(rng.integers(0, 2 * S, n))
    x_bg, y_bg = rng.integers(0, w, n), rng.integers(0, h, n)
    t_e = np.repeat(np.arange(S // 2, 2 * S, 2_500_000), h)
    y_e = np.tile(np.arange(h), len(t_e) // h)
    t = np.concatenate([t_bg, t_e])
    x = np.concatenate([x_bg, np.full(len(t_e), 7)])
    y = np.concatenate([y_bg, y_e])
    o = np.argsort(t, kind='stable')
    return EventArray.from_arrays(t[o].astype(np.int64), x[o], y[o],
                                  np.ones(len(t), np.uint8))


def busy_scene(rng: np.random.Generator) -> EventArray:
    """The background of :func:`scene` at 20 Hz, and from 0 s on column 7 firing all its
    20 pixels together every 0.5 ms (40 k events/s, none of them isolated)."""
    w, h = 40, 20
    n = rng.poisson(20.0 * w * h * 2.0)
    t_bg = np.sort(rng.integers(0, 2 * S, n))
    t_e = np.repeat(np.arange(0, 2 * S, 500_000), h)
    t = np.concatenate([t_bg, t_e])
    x = np.concatenate([rng.integers(0, w, n), np.full(len(t_e), 7)])
    y = np.concatenate([rng.integers(0, h, n), np.tile(np.arange(h), len(t_e) // h)])
    o = np.argsort(t, kind='stable')
    return EventArray.from_arrays(t[o].astype(np.int64), x[o], y[o],
                                  np.ones(len(t), np.uint8))


def test_a_busy_scene_is_no_noisy_sensor_below_the_share(rng: np.random.Generator) -> None:
    """The same 20 Hz background under a busy scene: its isolated rate is still about
    19.5 Hz (above the floor of 10), but only 19.5 / (20 + 50) = 28 % of the events are
    isolated: with noise_share 0.5 the frames are those of the switch off, with 0.2 they need
    two events per pixel."""
    ev = busy_scene(rng)
    pk = Packetizer(cfg(10.0, share=0.5))
    pk.push(ev)
    assert pk.background_hz == pytest.approx(19.5, rel=0.05)
    assert pk.background_share == pytest.approx(0.28, abs=0.02)
    assert not pk.noisy
    _, off = frames_from_events(ev, cfg(0.0))
    _, high = frames_from_events(ev, cfg(10.0, share=0.5))
    _, low = frames_from_events(ev, cfg(10.0, share=0.2))
    np.testing.assert_array_equal(high, off)
    assert low.sum() < 0.5 * off.sum()


def cfg(floor: float, share: float = 0.0) -> PacketizerConfig:
    """40x20 px, 400 events per frame; isolation bins of 50 us, so that of 20 Hz background
    a share exp(-27 x 20 Hz x 50 us) = 97 % is isolated."""
    return PacketizerConfig(events_per_frame=400, sensor_width=40, sensor_height=20,
                            downsample=1.0, noise_floor_hz=floor, noise_window_ms=250.0,
                            noise_isolation_ms=0.05, noise_share=share)


def test_a_noisy_stream_needs_two_events_per_pixel(rng: np.random.Generator) -> None:
    """Background 20 Hz per pixel (16 k events/s on 800 px): measured on [0.25, 0.5) s, at
    or above noise_floor_hz 10 every pixel needs 2 events: the edge column stays, most lone
    background events go. Below it (floor 30) the frames equal those of the switch off."""
    ev = scene(20.0, rng)
    t_on, on = frames_from_events(ev, cfg(10.0))
    t_off, off = frames_from_events(ev, cfg(0.0))
    _, high = frames_from_events(ev, cfg(30.0))
    np.testing.assert_array_equal(high, off)
    assert len(t_on) == len(t_off) and np.array_equal(t_on, t_off)
    late = t_on > S                                  # frames with the edge in them
    assert late.sum() >= 10
    assert np.all(on[late][:, :, 7] == 1)            # the edge column: 4+ events per pixel
    # background pixels: a frame of 400 events spans 1/60 s here (8 k edge + 16 k background
    # events/s), so about 267 background events on 800 px, lam = 1/3 per pixel: with one event
    # 1 - exp(-lam) = 28 % of the pixels are on, with two 1 - exp(-lam) (1 + lam) = 4.2 %
    bg_on = np.median(on[late].sum(axis=(1, 2)) - 20) / 780
    bg_off = np.median(off[late].sum(axis=(1, 2)) - 20) / 780
    assert bg_off == pytest.approx(0.28, abs=0.02) and bg_on == pytest.approx(0.042, abs=0.01)
    # exact: a pixel is on in a noisy frame iff its packet gave it >= 2 events
    k = 400
    flat = (ev.y.astype(np.int64) * 40 + ev.x)[:len(t_on) * k].reshape(-1, k)
    counts = np.stack([np.bincount(f, minlength=800) for f in flat]).reshape(-1, 20, 40)
    np.testing.assert_array_equal(on, (counts >= 2).astype(np.uint8))


@pytest.mark.parametrize('pieces', [1, 7, 97])
def test_streaming_waits_for_the_measurement_then_equals_batch(
        rng: np.random.Generator, pieces: int) -> None:
    """No frame comes out before an event after the measured window (0.5 s here); then the
    held packets come out with the decided threshold, and the whole stream equals the batch
    form whatever the batching."""
    ev = scene(20.0, rng)
    t_b, img_b = frames_from_events(ev, cfg(10.0))
    pk = Packetizer(cfg(10.0))
    cuts = np.unique(np.concatenate([[0, len(ev)], rng.integers(0, len(ev), pieces - 1)]))
    out = []
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        frames = pk.push(ev[a:b])
        if frames:
            assert int(ev.t[b - 1]) >= S // 2        # only once the window [0.25, 0.5) s closed
            assert pk.noisy and pk.background_hz == pytest.approx(19.5, rel=0.15)
        out += frames
    assert [f.t_ns for f in out] == list(t_b)
    np.testing.assert_array_equal(np.stack([f.image for f in out]), img_b)
    pk.reset()
    assert pk.background_hz is None and not pk.noisy


def test_a_stream_too_short_to_measure_keeps_the_normal_threshold(
        rng: np.random.Generator) -> None:
    """Events that end inside the measured window [0.25, 0.5) s: streaming holds every frame
    until finish(), which gives the frames of the switch off (the batch form gives them at
    once); pushes after finish() no longer wait."""
    ev = scene(20.0, rng)
    short = ev[: int(np.searchsorted(ev.t, S // 2 - 1))]
    t_off, off = frames_from_events(short, cfg(0.0))
    t_b, img_b = frames_from_events(short, cfg(10.0))
    assert len(t_off) >= 10
    np.testing.assert_array_equal(t_b, t_off)
    np.testing.assert_array_equal(img_b, off)
    pk = Packetizer(cfg(10.0))
    assert pk.push(short) == []
    out = pk.finish()
    assert [f.t_ns for f in out] == list(t_off) and not pk.noisy
    np.testing.assert_array_equal(np.stack([f.image for f in out]), off)
    assert pk.pending < 400 and pk.finish() == []
    assert len(pk.push(ev[len(short):])) >= 10                    # no more waiting,
    assert not pk.noisy and pk.background_hz is None               # nor a later switch


def test_finish_is_idle_on_a_measured_stream(rng: np.random.Generator) -> None:
    """A measured stream holds only its partial packet: finish() adds nothing."""
    ev = scene(20.0, rng)
    pk = Packetizer(cfg(10.0))
    n = len(pk.push(ev))
    assert n > 10 and pk.noisy and pk.finish() == []


@settings(max_examples=150, deadline=None)
@given(st.data())
def test_isolated_count_equals_the_pairwise_reference(data: st.DataObject) -> None:
    """Any small sensor, window, bin, event set (equal timestamps, events on the window's and
    bins' edges) and cut into pushes: the pairwise reference count."""
    w, h = data.draw(st.integers(1, 6)), data.draw(st.integers(1, 6))
    win = data.draw(st.integers(2, 40))
    b = data.draw(st.integers(1, win))
    n = data.draw(st.integers(1, 60))
    t = np.sort(np.array(data.draw(st.lists(st.integers(0, 3 * win), min_size=n, max_size=n)),
                         np.int64))
    x = np.array(data.draw(st.lists(st.integers(0, w - 1), min_size=n, max_size=n)), np.int64)
    y = np.array(data.draw(st.lists(st.integers(0, h - 1), min_size=n, max_size=n)), np.int64)
    cuts = sorted(set(data.draw(st.lists(st.integers(0, n), max_size=6))) | {0, n})
    probe = BackgroundRate(w, h, win, b)
    for a, c in zip(cuts[:-1], cuts[1:], strict=True):
        probe.push(t[a:c], x[a:c], y[a:c])
    start = (int(t[0]) // win + 1) * win
    if int(t[-1]) < start + win:                   # no event after the window: not measured
        assert probe.rate_hz is None
        return
    want = brute_isolated(t, x, y, start, win, b)
    count = int(np.count_nonzero((t >= start) & (t < start + win)))
    assert probe.rate_hz == pytest.approx(want * 1e9 / (win * w * h))
    assert probe.total_hz == pytest.approx(count * 1e9 / (win * w * h))
    assert probe.share == pytest.approx(want / count if count else 0.0)


def test_a_reset_stream_waits_for_its_measurement_again(rng: np.random.Generator) -> None:
    """finish() ends the waiting of its stream only: after reset() a new stream's frames wait
    for their own measurement; a held packet of exactly events_per_frame comes out at
    finish()."""
    ev = scene(20.0, rng)
    short = ev[: int(np.searchsorted(ev.t, S // 2 - 1))]
    pk = Packetizer(cfg(10.0))
    pk.push(short)
    assert len(pk.finish()) >= 10
    pk.reset()
    assert pk.push(short) == []                   # waiting again
    pk = Packetizer(replace(cfg(10.0), max_frame_ms=0.0))   # packets by count only
    assert pk.push(short[:400]) == [] and pk.pending == 400
    assert len(pk.finish()) == 1


def test_the_noisy_threshold_holds_at_the_floors_themselves() -> None:
    """Noisy at an isolated rate and share equal to noise_floor_hz and noise_share."""
    from types import SimpleNamespace

    from hrn_vo_ros.core.events.frames import _noisy
    c = cfg(10.0, share=0.5)
    assert _noisy(c, SimpleNamespace(rate_hz=10.0, share=0.5))     # type: ignore[arg-type]
    assert not _noisy(c, SimpleNamespace(rate_hz=9.99, share=0.5))  # type: ignore[arg-type]
    assert not _noisy(c, SimpleNamespace(rate_hz=10.0, share=0.49))  # type: ignore[arg-type]
