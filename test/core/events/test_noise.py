"""The background rate (core/events/noise.py) and the packetizer's noisy-sensor threshold
(PacketizerConfig.noise_floor_hz), on hand-built events."""

from __future__ import annotations

import numpy as np
import pytest

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.frames import frames_from_events, Packetizer, PacketizerConfig
from hrn_vo_ros.core.events.noise import BackgroundRate
from hrn_vo_ros.errors import ConfigError

S = 1_000_000_000


def test_rate_of_the_first_full_window_by_hand() -> None:
    """100 pixels, 1 s windows; the stream starts 0.5 s into window 0 (partial: not
    measured). Window 1 holds 50 events, one of them exactly at its start (1.0 s): 50 events
    / (1 s x 100 px) = 0.5 Hz, known once an event at or after 2.0 s arrives."""
    probe = BackgroundRate(100, S)
    t0 = np.array([S // 2, S // 2 + 1, S - 1], np.int64)      # window 0: 3 events, ignored
    t1 = np.linspace(S, 2 * S - 1, 50).astype(np.int64)        # window 1: 50 events
    assert probe.push(t0) is None
    assert probe.push(t1) is None              # no event after window 1 yet
    assert probe.push(np.array([2 * S], np.int64)) == pytest.approx(0.5)
    assert probe.rate_hz == pytest.approx(0.5)
    assert probe.push(np.arange(3 * S, 3 * S + 1000, dtype=np.int64)) == pytest.approx(0.5)
    probe.reset()
    assert probe.rate_hz is None


@pytest.mark.parametrize('split', [0, 1, 2, 3, 25, 52, 53, 54])
def test_any_batching_gives_the_same_rate(split: int) -> None:
    """Equal timestamps on the window's edges and any cut give the same measurement."""
    t = np.array([10, 10] + [S] * 3 + [S + 5] * 47 + [2 * S, 2 * S], np.int64)  # 47+3 in win 1
    probe = BackgroundRate(50, S)
    out = [probe.push(t[:split]), probe.push(t[split:])]
    assert out[-1] == pytest.approx(50 / 50)
    assert out[0] is None or split >= 53


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ConfigError, match='positive'):
        BackgroundRate(0, S)
    with pytest.raises(ConfigError, match='positive'):
        BackgroundRate(10, 0)
    with pytest.raises(ConfigError):
        PacketizerConfig(noise_floor_hz=-1.0)


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


def cfg(floor: float) -> PacketizerConfig:
    return PacketizerConfig(events_per_frame=400, sensor_width=40, sensor_height=20,
                            downsample=1.0, noise_floor_hz=floor, noise_window_ms=250.0)


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
            assert pk.noisy and pk.background_hz == pytest.approx(20.0, rel=0.15)
        out += frames
    assert [f.t_ns for f in out] == list(t_b)
    np.testing.assert_array_equal(np.stack([f.image for f in out]), img_b)
    pk.reset()
    assert pk.background_hz is None and not pk.noisy


def test_a_stream_too_short_to_measure_gives_no_frames(rng: np.random.Generator) -> None:
    """Events that end inside the measured window: no frame (the threshold is unknown)."""
    ev = scene(20.0, rng)
    ev = ev[: int(np.searchsorted(ev.t, S // 2 - 1))]
    t, img = frames_from_events(ev, cfg(10.0))
    assert len(t) == 0 and img.shape == (0, 20, 40)
    assert Packetizer(cfg(10.0)).push(ev) == []
