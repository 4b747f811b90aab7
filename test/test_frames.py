"""Event frames: downsampling formula, binary thresholds, packet times, streaming = batch."""

from __future__ import annotations

import time

import numpy as np
import pytest

from hrn_vo_ros.core.events import EventArray
from hrn_vo_ros.core.frames import downsample_lut, frames_from_events, Packetizer, PacketizerConfig
from hrn_vo_ros.errors import ConfigError, DatasetError


def random_events(rng: np.random.Generator, n: int, w: int = 240, h: int = 180) -> EventArray:
    t = np.cumsum(rng.integers(0, 5000, n)).astype(np.int64) + 10**9
    return EventArray.from_arrays(t, rng.integers(0, w, n), rng.integers(0, h, n),
                                  rng.integers(0, 2, n))


@pytest.mark.parametrize(('sensor', 'f', 'out'), [((240, 180), 2.5, (96, 72)),
                                                  ((640, 480), 10.0, (64, 48)),
                                                  ((346, 260), 2.5, (139, 104))])
def test_output_size_and_every_pixel_lands_inside(sensor: tuple[int, int], f: float,
                                                  out: tuple[int, int]) -> None:
    cfg = PacketizerConfig(sensor_width=sensor[0], sensor_height=sensor[1], downsample=f)
    assert (cfg.width, cfg.height) == out
    lx = downsample_lut(sensor[0], f)
    assert lx.min() == 0 and lx.max() == out[0] - 1
    assert np.all(np.diff(lx) >= 0)


def test_downsampling_is_centre_aligned_division_and_rounding() -> None:
    lx = downsample_lut(240, 2.5)
    x = np.arange(240)
    np.testing.assert_array_equal(lx, np.floor((x + 0.5) / 2.5).astype(int))
    # 2.5 sensor pixels per bin: bins alternately take 2 and 3 pixels (or 3 and 2).
    counts = np.bincount(lx)
    assert set(counts.tolist()) == {2, 3} and counts.sum() == 240
    assert downsample_lut(640, 10.0).tolist() == (np.arange(640) // 10).tolist()


def test_frame_content_time_and_thresholds() -> None:
    cfg = PacketizerConfig(events_per_frame=4, sensor_width=20, sensor_height=10, downsample=2.0)
    ev = EventArray.from_arrays(np.array([100, 200, 300, 401]), np.array([0, 1, 5, 19]),
                                np.array([0, 0, 3, 9]), np.array([1, 0, 1, 1]))
    t, img = frames_from_events(ev, cfg)
    assert t.tolist() == [250] and img.shape == (1, 5, 10) and img.dtype == np.uint8
    expect = np.zeros((5, 10), np.uint8)
    expect[0, 0] = expect[1, 2] = expect[4, 9] = 1
    np.testing.assert_array_equal(img[0], expect)
    cfg2 = PacketizerConfig(events_per_frame=4, sensor_width=20, sensor_height=10,
                            downsample=2.0, min_events_per_pixel=2)
    _, img2 = frames_from_events(ev, cfg2)
    only = np.zeros((5, 10), np.uint8)
    only[0, 0] = 1            # (0,0) and (1,0) both fall into pixel (0, 0): 2 events
    np.testing.assert_array_equal(img2[0], only)


def test_streaming_equals_batch_for_any_split(rng: np.random.Generator) -> None:
    cfg = PacketizerConfig(events_per_frame=1000)
    ev = random_events(rng, 25_500)
    t_ref, img_ref = frames_from_events(ev, cfg)
    assert len(t_ref) == 25
    pk = Packetizer(cfg)
    cuts = np.sort(rng.choice(np.arange(1, len(ev)), 60, replace=False))
    cuts = np.concatenate([[0], cuts[:20], [cuts[20]] * 3, cuts[21:], [len(ev)]])  # empty pushes
    frames = []
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        frames += pk.push(ev[a:b])
    assert [f.t_ns for f in frames] == t_ref.tolist()
    np.testing.assert_array_equal(np.stack([f.image for f in frames]), img_ref)
    assert pk.pending == 500
    f0 = frames[0]
    assert (f0.t_first_ns, f0.t_last_ns, f0.n_events) == (int(ev.t[0]), int(ev.t[999]), 1000)
    # One push spanning many frames gives the same result.
    assert [f.t_ns for f in Packetizer(cfg).push(ev)] == t_ref.tolist()


def test_bad_inputs_raise_with_actionable_messages(rng: np.random.Generator) -> None:
    pk = Packetizer(PacketizerConfig(sensor_width=240, sensor_height=180))
    bad = EventArray.from_arrays(np.array([1, 2]), np.array([3, 240]), np.array([0, 0]),
                                 np.array([0, 0]))
    with pytest.raises(DatasetError, match='outside the 240x180 sensor'):
        pk.push(bad)
    pk.push(EventArray.from_arrays(np.array([50]), np.array([1]), np.array([1]), np.array([0])))
    with pytest.raises(DatasetError, match='back in time'):
        pk.push(EventArray.from_arrays(np.array([40]), np.array([1]), np.array([1]),
                                       np.array([0])))
    with pytest.raises(ConfigError, match='events_per_frame'):
        PacketizerConfig(events_per_frame=0)
    with pytest.raises(ConfigError, match='downsample'):
        PacketizerConfig(downsample=0.5)


def test_packetizing_rate_is_far_above_real_time(rng: np.random.Generator) -> None:
    """A loose in-suite bound (the benchmark measures the 20 M events/s target)."""
    ev = random_events(rng, 2_000_000)
    pk = Packetizer(PacketizerConfig())
    t0 = time.perf_counter()
    for i in range(0, len(ev), 100_000):
        pk.push(ev[i:i + 100_000])
    rate = len(ev) / (time.perf_counter() - t0)
    assert rate > 3e6
