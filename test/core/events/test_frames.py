"""Event frames: downsampling formula, binary thresholds, packet times, streaming = batch."""

from __future__ import annotations

from dataclasses import replace

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.camera import distort_points, rectified_pixels, undistort_points
from hrn_vo_ros.core.events.frames import (
    check_event_frame,
    downsample_lut,
    EventFrame,
    frames_from_events,
    packet_ends,
    Packetizer,
    rectify_lut,
)
from hrn_vo_ros.core.events.packet_config import (
    CalibrationConfig,
    FramingImuConfig,
    PacketizerConfig,
    paper_framing,
    with_calibration,
)
from hrn_vo_ros.core.events.sequence import CameraCalibration
from hrn_vo_ros.errors import ConfigError, DatasetError, TrackingError


def random_events(rng: np.random.Generator, n: int, w: int = 240, h: int = 180) -> EventArray:
    t = np.cumsum(rng.integers(0, 5000, n)).astype(np.int64) + 10**9
    return EventArray.from_arrays(t, rng.integers(0, w, n), rng.integers(0, h, n),
                                  rng.integers(0, 2, n))


@pytest.mark.parametrize(('sensor', 'f', 'out'), [((240, 180), 2.5, (96, 72)),
                                                  ((640, 480), 10.0, (64, 48)),
                                                  ((346, 260), 2.5, (139, 104))])
def test_output_size_and_every_pixel_lands_inside(sensor: tuple[int, int], f: float,
                                                  out: tuple[int, int]) -> None:
    cfg = paper_framing(sensor_width=sensor[0], sensor_height=sensor[1], downsample=f)
    assert (cfg.width, cfg.height) == out
    lx = downsample_lut(sensor[0], f)
    assert lx.min() == 0 and lx.max() == out[0] - 1
    assert np.all(np.diff(lx) >= 0)


@pytest.mark.parametrize(('sensor', 'f', 'out'), [((240, 180), 2.5, (96, 72)),
                                                  ((640, 480), 640 / 96, (96, 72)),
                                                  ((346, 260), 260 / 72, (96, 72)),
                                                  ((1280, 720), 1280 / 96, (96, 54)),
                                                  ((64, 40), 1.0, (64, 40))])
def test_auto_downsample_fits_any_sensor_into_96x72(sensor: tuple[int, int], f: float,
                                                    out: tuple[int, int]) -> None:
    """downsample 0: the smallest factor that fits the sensor into 96x72 (346x260: the
    height binds, 3.611 > 3.604), never below 1 (a sensor smaller than the frame)."""
    cfg = PacketizerConfig(sensor_width=sensor[0], sensor_height=sensor[1], downsample=0.0)
    assert cfg.factor == pytest.approx(f, abs=1e-12)
    assert (cfg.width, cfg.height) == out
    # the sensor size of another camera (sensor_size: messages) gives its own factor
    assert replace(cfg, sensor_width=240, sensor_height=180).factor == 2.5
    ev = EventArray.from_arrays(np.arange(1, 5, dtype=np.int64) * 1000,
                                np.array([0, sensor[0] - 1, 0, sensor[0] - 1]),
                                np.array([0, 0, sensor[1] - 1, sensor[1] - 1]), np.zeros(4))
    _, imgs = frames_from_events(ev, replace(cfg, events_per_frame=4))
    corners = imgs[0][[0, 0, -1, -1], [0, -1, 0, -1]]
    assert imgs[0].shape == (out[1], out[0]) and corners.tolist() == [1, 1, 1, 1]
    assert int(imgs[0].sum()) == 4


def test_downsampling_is_centre_aligned_division_and_rounding() -> None:
    lx = downsample_lut(240, 2.5)
    x = np.arange(240)
    np.testing.assert_array_equal(lx, np.floor((x + 0.5) / 2.5).astype(int))
    # 2.5 sensor pixels per bin: bins alternately take 2 and 3 pixels (or 3 and 2).
    counts = np.bincount(lx)
    assert set(counts.tolist()) == {2, 3} and counts.sum() == 240
    assert downsample_lut(640, 10.0).tolist() == (np.arange(640) // 10).tolist()


def test_frame_content_time_and_thresholds() -> None:
    cfg = paper_framing(events_per_frame=4, sensor_width=20, sensor_height=10, downsample=2.0)
    ev = EventArray.from_arrays(np.array([100, 200, 300, 401]), np.array([0, 1, 5, 19]),
                                np.array([0, 0, 3, 9]), np.array([1, 0, 1, 1]))
    t, img = frames_from_events(ev, cfg)
    assert t.tolist() == [250] and img.shape == (1, 5, 10) and img.dtype == np.uint8
    expect = np.zeros((5, 10), np.uint8)
    expect[0, 0] = expect[1, 2] = expect[4, 9] = 1
    np.testing.assert_array_equal(img[0], expect)
    cfg2 = paper_framing(events_per_frame=4, sensor_width=20, sensor_height=10,
                         downsample=2.0, min_events_per_pixel=2)
    _, img2 = frames_from_events(ev, cfg2)
    only = np.zeros((5, 10), np.uint8)
    only[0, 0] = 1            # (0,0) and (1,0) both fall into pixel (0, 0): 2 events
    np.testing.assert_array_equal(img2[0], only)


def test_streaming_equals_batch_for_any_split(rng: np.random.Generator) -> None:
    cfg = paper_framing(events_per_frame=1000)
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


def test_time_capped_packet_ends_by_hand() -> None:
    cfg = paper_framing(events_per_frame=10, min_frame_events=3, max_frame_ms=1.0)
    ms = 1_000_000
    t = np.array([*range(12), 2 * ms, 2 * ms + 1, 2 * ms + 2, 2 * ms + 3, 5 * ms], np.int64)
    # [0, 10): ten events within 1 ms close by count. [10, 13): the packet from t = 10 ns holds
    # two events in its window, so it waits for its third (at 2 ms). [13, 16): closed by the
    # event at 5 ms, past the window [2 ms + 1, 3 ms + 1). The event at 5 ms is still open.
    assert packet_ends(t, cfg).tolist() == [10, 13, 16]
    # An event exactly at the window's end starts the next packet.
    assert packet_ends(np.array([0, 1, 2, ms, ms], np.int64), cfg).tolist() == [3]
    # Off: fixed counts.
    assert packet_ends(t, paper_framing(events_per_frame=5)).tolist() == [5, 10, 15]
    # min_frame_events above events_per_frame: every packet closes by count
    big = paper_framing(events_per_frame=5, min_frame_events=11, max_frame_ms=1.0)
    assert big.min_events == 5
    assert packet_ends(t, big).tolist() == [5, 10, 15]


def test_imu_packets_close_by_their_own_limit() -> None:
    ms = 1_000_000
    t = np.array([0, 1, 2, 3, 2 * ms, 2 * ms + 1, 2 * ms + 2, 5 * ms, 9 * ms], np.int64)
    # Without the gyro: fixed 5-event packets; with it (imu.enabled) the 1 ms limit: [0, 4)
    # closes at the event at 2 ms, [4, 7) at the one at 5 ms, [7, 8) holds one event (< 3) and
    # waits for its third.
    imu = FramingImuConfig(enabled=True, max_frame_ms=1.0)
    cfg = paper_framing(events_per_frame=5, min_frame_events=3)
    assert packet_ends(t, cfg).tolist() == [5]
    with_gyro = replace(cfg, imu=imu)
    assert with_gyro.frame_ms == 1.0 and with_gyro.max_frame_ns == ms
    assert packet_ends(t, with_gyro).tolist() == [4, 7]
    # The limit only applies with the gyro fused; 0 keeps max_frame_ms.
    assert replace(cfg, imu=replace(imu, enabled=False)).frame_ms == 0.0
    assert replace(cfg, max_frame_ms=2.0, imu=replace(imu, max_frame_ms=0.0)).frame_ms == 2.0
    # min_frame_events above events_per_frame: the gyro's packets close by count as well
    assert packet_ends(t, paper_framing(events_per_frame=3, min_frame_events=6,
                                        imu=imu)).tolist() == [3, 6, 9]
    # the defaults: 100 ms with and without the gyro, refilled only without it
    d = PacketizerConfig(events_per_frame=100)
    assert d.imu.max_frame_ms == d.max_frame_ms == 100.0 and d.refills
    assert not replace(d, imu=replace(d.imu, enabled=True)).refills


def test_time_capped_frames_by_hand() -> None:
    cfg = paper_framing(events_per_frame=4, sensor_width=20, sensor_height=10, downsample=2.0,
                        max_frame_ms=0.001, min_frame_events=2)      # 1 us windows
    ev = EventArray.from_arrays(np.array([100, 200, 1300, 1400, 1500, 3000]),
                                np.array([0, 19, 4, 4, 5, 0]), np.array([0, 9, 2, 2, 2, 0]),
                                np.zeros(6, np.int64))
    t, img = frames_from_events(ev, cfg)
    assert t.tolist() == [150, 1400]        # [100, 200] by time, [1300, 1500] by the 3000 event
    expect = np.zeros((2, 5, 10), np.uint8)
    expect[0, 0, 0] = expect[0, 4, 9] = 1
    expect[1, 1, 2] = 1                     # x 4 and 5 both fall into column 2
    np.testing.assert_array_equal(img, expect)
    frames = Packetizer(cfg).push(ev)
    assert [(f.t_first_ns, f.t_last_ns, f.n_events) for f in frames] == [(100, 200, 2),
                                                                            (1300, 1500, 3)]


def push_split(pk: Packetizer, ev: EventArray, rng: np.random.Generator, n_cuts: int
               ) -> list[EventFrame]:
    """The frames of ``ev`` pushed into ``pk`` in ``n_cuts + 1`` batches split at random."""
    n = len(ev)
    cuts = np.sort(rng.choice(np.arange(1, n), n_cuts, replace=False))
    cuts = np.concatenate([[0], cuts, [n]])
    frames: list[EventFrame] = []
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        frames += pk.push(ev[a:b])
    return frames


def test_refilled_frames_by_hand() -> None:
    # Packets of 3 events or 1 us; with refill a packet closed by time is binned with the
    # events before it, up to 3 events in all.
    cfg = paper_framing(events_per_frame=3, sensor_width=20, sensor_height=10, downsample=2.0,
                        max_frame_ms=0.001, min_frame_events=1, refill=True)
    ev = EventArray.from_arrays(np.array([100, 200, 300, 2000, 4000, 4100, 4200, 4300, 9000]),
                                np.array([0, 2, 4, 6, 8, 10, 12, 14, 16]), np.zeros(9, np.int64),
                                np.zeros(9, np.int64))
    # packets: [0, 3) by count; [3, 4) by time (the event at 4000 is past 2000 + 1000);
    # [4, 7) by count; [7, 8) by time (9000). Frames: [0, 3), [1, 4), [4, 7), [5, 8).
    t, img = frames_from_events(ev, cfg)
    assert t.tolist() == [200, 200 + (2000 - 200) // 2, 4100, 4100 + (4300 - 4100) // 2]
    cols = [np.flatnonzero(im[0]).tolist() for im in img]
    assert cols == [[0, 1, 2], [1, 2, 3], [4, 5, 6], [5, 6, 7]]
    assert img.sum() == 12
    pk = Packetizer(cfg)
    frames = pk.push(ev)
    assert [(f.t_first_ns, f.t_last_ns, f.n_events) for f in frames] == [
        (100, 300, 3), (200, 2000, 3), (4000, 4200, 3), (4100, 4300, 3)]
    assert pk.by_time == 2                      # the packets [3, 4) and [7, 8)
    # without refill the time-closed packets are binned alone; without a time limit refill
    # changes nothing
    plain = frames_from_events(ev, replace(cfg, refill=False))[1]
    assert [np.flatnonzero(im[0]).tolist() for im in plain] == [[0, 1, 2], [3], [4, 5, 6], [7]]
    t0, i0 = frames_from_events(ev, replace(cfg, max_frame_ms=0.0))
    t1, i1 = frames_from_events(ev, replace(cfg, max_frame_ms=0.0, refill=False))
    assert t0.tolist() == t1.tolist() == [200, 3050, 6600] and np.array_equal(i0, i1)
    # under the gyro's own limit packets are binned alone; a gyro that keeps max_frame_ms
    # (imu.max_frame_ms 0) keeps the refill
    gyro = replace(cfg, imu=FramingImuConfig(enabled=True, max_frame_ms=0.001))
    assert not gyro.refills and cfg.refills
    assert [np.flatnonzero(im[0]).tolist() for im in frames_from_events(ev, gyro)[1]] == [
        [0, 1, 2], [3], [4, 5, 6], [7]]
    same = replace(cfg, imu=FramingImuConfig(enabled=True, max_frame_ms=0.0))
    assert same.refills and np.array_equal(frames_from_events(ev, same)[1], img)
    # the first packet of a stream has nothing before it: a short window
    first = frames_from_events(ev[3:], cfg)
    assert [np.flatnonzero(im[0]).tolist() for im in first[1]] == [[3], [4, 5, 6], [5, 6, 7]]


def test_refilled_streaming_equals_batch_for_any_split(rng: np.random.Generator) -> None:
    gaps = np.concatenate([rng.integers(0, 3000, 6000), rng.integers(0, 400_000, 2000),
                           np.zeros(300, np.int64), rng.integers(0, 3000, 5000),
                           rng.integers(0, 200_000, 3000)])
    t = np.cumsum(gaps).astype(np.int64) + 10**9
    n = len(t)
    ev = EventArray.from_arrays(t, rng.integers(0, 240, n), rng.integers(0, 180, n),
                                rng.integers(0, 2, n))
    cfg = paper_framing(events_per_frame=1000, max_frame_ms=50.0, min_frame_events=20,
                        refill=True)
    t_ref, img_ref = frames_from_events(ev, cfg)
    ends = packet_ends(ev.t, cfg)
    sizes = np.diff(ends, prepend=0)
    assert (sizes < 1000).sum() >= 10           # packets closed by time
    # every frame holds the 1000 events before its packet's end (the first ones fewer)
    starts = np.maximum(ends - 1000, 0)
    assert t_ref.tolist() == (t[starts] + (t[ends - 1] - t[starts]) // 2).tolist()
    for i in (0, int(np.argmin(sizes)), len(ends) - 1):
        ref = np.zeros((72, 96), np.uint8)
        e = EventArray.from_arrays(t[starts[i]:ends[i]], ev.x[starts[i]:ends[i]],
                                   ev.y[starts[i]:ends[i]], ev.p[starts[i]:ends[i]])
        ref[(e.y * 2 + 1) // 5, (e.x * 2 + 1) // 5] = 1      # floor((x + 0.5) / 2.5)
        np.testing.assert_array_equal(img_ref[i], ref)
    for _ in range(2):                          # a reset forgets the events before it
        pk = Packetizer(cfg)
        frames = push_split(pk, ev, rng, 150)
        assert [f.t_ns for f in frames] == t_ref.tolist()
        np.testing.assert_array_equal(np.stack([f.image for f in frames]), img_ref)
        assert [f.n_events for f in frames] == (ends - starts).tolist()
        pk.reset()
        again = pk.push(ev[int(ends[5]):])
        t_tail = frames_from_events(ev[int(ends[5]):], cfg)[0]
        assert [f.t_ns for f in again] == t_tail.tolist()


def test_time_capped_streaming_equals_batch_for_any_split(rng: np.random.Generator) -> None:
    # A stream whose rate swings between busy (count-closed) and slow (time-closed) stretches,
    # with runs of equal timestamps.
    gaps = np.concatenate([rng.integers(0, 3000, 8000), rng.integers(0, 400_000, 3000),
                           rng.integers(0, 3000, 8000), np.zeros(500, np.int64),
                           rng.integers(0, 200_000, 4000)])
    t = np.cumsum(gaps).astype(np.int64) + 10**9
    n = len(t)
    ev = EventArray.from_arrays(t, rng.integers(0, 240, n), rng.integers(0, 180, n),
                                rng.integers(0, 2, n))
    cfg = paper_framing(events_per_frame=1000, max_frame_ms=50.0, min_frame_events=200)
    t_ref, img_ref = frames_from_events(ev, cfg)
    sizes = np.diff(packet_ends(ev.t, cfg), prepend=0)
    assert sizes.min() >= 200 and sizes.max() == 1000 and (sizes < 1000).sum() > 10
    pk = Packetizer(cfg)
    frames = push_split(pk, ev, rng, 200)
    assert [f.t_ns for f in frames] == t_ref.tolist()
    np.testing.assert_array_equal(np.stack([f.image for f in frames]), img_ref)
    assert [f.n_events for f in frames] == sizes.tolist()
    assert pk.pending == n - int(sizes.sum())
    assert pk.by_time == int((sizes < 1000).sum())
    # A packet closed by time (fewer than events_per_frame, more than min_frame_events) holds
    # its window's events: its last one inside, the next packet's first one past it.
    short = sizes < 1000
    nxt = t[np.cumsum(sizes)[:-1]]
    first = np.array([f.t_first_ns for f in frames])
    closed_by_time = short[:-1] & (sizes[:-1] > 200)
    assert np.all(nxt[closed_by_time] - first[:-1][closed_by_time] >= 50_000_000)
    assert np.all(t[np.cumsum(sizes)[:-1] - 1][closed_by_time]
                  - first[:-1][closed_by_time] < 50_000_000)


def test_bad_inputs_raise_with_actionable_messages(rng: np.random.Generator) -> None:
    pk = Packetizer(paper_framing(sensor_width=240, sensor_height=180))
    bad = EventArray.from_arrays(np.array([1, 2]), np.array([3, 240]), np.array([0, 0]),
                                 np.array([0, 0]))
    with pytest.raises(DatasetError, match='outside the 240x180 sensor'):
        pk.push(bad)
    pk.push(EventArray.from_arrays(np.array([50]), np.array([1]), np.array([1]), np.array([0])))
    with pytest.raises(DatasetError, match='back in time'):
        pk.push(EventArray.from_arrays(np.array([40]), np.array([1]), np.array([1]),
                                       np.array([0])))
    with pytest.raises(ConfigError, match='events_per_frame'):
        paper_framing(events_per_frame=0)
    with pytest.raises(ConfigError, match='downsample = 0.5: set a factor >= 1, or 0'):
        paper_framing(downsample=0.5)


# ------------------------------------------------------------------------------------------
# Rectification


DAVIS = CameraCalibration(240, 180, 199.1, 198.8, 121.3, 89.6, (-0.12, 0.03, 0.001, -0.002, 0.0))


def _rectified(mode: str, calib: CameraCalibration = DAVIS, **kw: object) -> PacketizerConfig:
    return with_calibration(paper_framing(rectify=mode, **kw), calib)  # type: ignore[arg-type]


def test_undistort_inverts_distort() -> None:
    rng = np.random.default_rng(3)
    x, y = rng.uniform(-0.6, 0.6, 200), rng.uniform(-0.45, 0.45, 200)
    u, v = distort_points(199.1, 198.8, 121.3, 89.6, DAVIS.dist, x, y)
    x2, y2 = undistort_points(199.1, 198.8, 121.3, 89.6, DAVIS.dist, u, v)
    np.testing.assert_allclose(x2, x, atol=1e-9)
    np.testing.assert_allclose(y2, y, atol=1e-9)


def test_plumb_bob_distortion_by_hand() -> None:
    """Each coefficient of (k1, k2, p1, p2, k3) alone at the normalised point (0.5, 0.2)
    (r^2 = 0.29), f = 100 at the origin: x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y +
    p2 (r^2 + 2 x^2), y_d likewise; undistorting gives the point back."""
    r2 = 0.29
    cases = [((0.1, 0, 0, 0, 0), 0.5 * (1 + 0.1 * r2), 0.2 * (1 + 0.1 * r2)),
             ((0, 0.1, 0, 0, 0), 0.5 * (1 + 0.1 * r2 ** 2), 0.2 * (1 + 0.1 * r2 ** 2)),
             ((0, 0, 0.01, 0, 0), 0.5 + 0.02 * 0.1, 0.2 + 0.01 * (r2 + 0.08)),
             ((0, 0, 0, 0.01, 0), 0.5 + 0.01 * (r2 + 0.5), 0.2 + 0.02 * 0.1),
             ((0, 0, 0, 0, 0.1), 0.5 * (1 + 0.1 * r2 ** 3), 0.2 * (1 + 0.1 * r2 ** 3))]
    for dist, xd, yd in cases:
        u, v = distort_points(100.0, 100.0, 0.0, 0.0, dist, 0.5, 0.2)
        assert (float(u), float(v)) == pytest.approx((100 * xd, 100 * yd), abs=1e-12)
        x, y = undistort_points(100.0, 100.0, 0.0, 0.0, dist, u, v)
        assert (float(x), float(y)) == pytest.approx((0.5, 0.2), abs=1e-9)


def test_equidistant_radius_is_focal_times_ray_angle() -> None:
    xr, yr = rectified_pixels('equidistant', *DAVIS_ARGS)
    # the ray of every sensor pixel (undistorted, normalised) and its angle from the axis
    yy, xx = np.mgrid[0:180, 0:240].astype(float)
    x, y = undistort_points(199.1, 198.8, 121.3, 89.6, DAVIS.dist, xx, yy)
    theta = np.arctan(np.hypot(x, y))
    radius = np.hypot((xr - 119.5) / 199.1, (yr - 89.5) / 198.8)
    np.testing.assert_allclose(radius, theta, atol=1e-9)
    # the direction about the centre is the ray's direction (a roll is an image rotation)
    np.testing.assert_allclose(np.arctan2((yr - 89.5) / 198.8, (xr - 119.5) / 199.1),
                               np.arctan2(y, x), atol=1e-9)
    # pinhole keeps the ray's tangent instead
    xp, yp = rectified_pixels('pinhole', *DAVIS_ARGS)
    np.testing.assert_allclose((xp - 119.5) / 199.1, x, atol=1e-9)
    assert np.hypot(xp - 119.5, yp - 89.5).max() > np.hypot(xr - 119.5, yr - 89.5).max() + 5


DAVIS_ARGS = (240, 180, 199.1, 198.8, 121.3, 89.6, DAVIS.dist)


def test_rectify_with_an_ideal_centred_camera_changes_nothing(rng: np.random.Generator) -> None:
    ideal = CameraCalibration(240, 180, 200.0, 200.0, 119.5, 89.5)
    ev = random_events(rng, 20_000)
    t_ref, img_ref = frames_from_events(ev, paper_framing())
    t, img = frames_from_events(ev, _rectified('pinhole', ideal))
    assert t.tolist() == t_ref.tolist()
    np.testing.assert_array_equal(img, img_ref)


def test_rectified_event_lands_where_the_lookup_says() -> None:
    cfg = _rectified('equidistant', events_per_frame=1)
    xr, yr = rectified_pixels('equidistant', *DAVIS_ARGS)
    for x, y in [(0, 0), (239, 179), (121, 90), (17, 150)]:
        ev = EventArray.from_arrays(np.array([5]), np.array([x]), np.array([y]), np.array([1]))
        _, img = frames_from_events(ev, cfg)
        (v,), (u,) = np.nonzero(img[0])
        assert (u, v) == (int((xr[y, x] + 0.5) // 2.5), int((yr[y, x] + 0.5) // 2.5))
    # the barrel-distorted corner moves outwards under pinhole rectification
    xp, _ = rectified_pixels('pinhole', *DAVIS_ARGS)
    assert xp[0, 0] < -5.0 < xr[0, 0]


def test_events_rectified_outside_the_frame_are_counted_not_binned(
        rng: np.random.Generator) -> None:
    cfg = _rectified('pinhole', events_per_frame=1000)
    lut = rectify_lut(cfg)
    outside = np.flatnonzero(lut < 0)
    assert 0.02 < len(outside) / lut.size < 0.2       # the barrel-distorted corners
    ev = random_events(rng, 30_000)
    n_out = int(np.isin(ev.y.astype(int) * 240 + ev.x, outside).sum())
    pk = Packetizer(cfg)
    frames = []
    for i in range(0, len(ev), 7_000):
        frames += pk.push(ev[i:i + 7_000])
    assert pk.outside == n_out
    assert len(frames) * 1000 + pk.pending == len(ev) - n_out
    t_ref, img_ref = frames_from_events(ev, cfg)     # streaming = batch with rectification
    assert [f.t_ns for f in frames] == t_ref.tolist()
    np.testing.assert_array_equal(np.stack([f.image for f in frames]), img_ref)
    # equidistant keeps every DAVIS pixel in the frame
    assert (rectify_lut(_rectified('equidistant')) >= 0).all()


def test_rectification_needs_a_matching_calibration() -> None:
    with pytest.raises(ConfigError, match='needs the camera calibration'):
        Packetizer(paper_framing(rectify='equidistant'))
    with pytest.raises(ConfigError, match='rectify'):
        paper_framing(rectify='fisheye')
    with pytest.raises(DatasetError, match='346x260 sensor'):
        _rectified('pinhole', CameraCalibration(346, 260, 200.0, 200.0, 173.0, 130.0))
    with pytest.raises(ConfigError, match='5 plumb-bob'):
        CalibrationConfig(fx=1.0, fy=1.0, dist=(0.1,))
    with pytest.raises(ConfigError, match='both'):
        CalibrationConfig(fx=1.0)
    # explicit calib wins over the dataset's; no rectification ignores the calibration
    own = paper_framing(rectify='pinhole', calib=CalibrationConfig(fx=150.0, fy=150.0))
    assert with_calibration(own, DAVIS) is own
    assert with_calibration(paper_framing(), DAVIS) == paper_framing()
    assert _rectified('equidistant').calib.cx == 121.3


def edge_and_noise(rng: np.random.Generator, seconds: float = 0.2
                   ) -> tuple[EventArray, np.ndarray]:
    """A vertical edge sweeping right at 400 px/s (every pixel of its column fires once)
    plus uniform noise of 1 event per pixel per second; also the mask of the edge events."""
    n_cols = int(400 * seconds)
    t_edge = np.repeat(np.arange(n_cols) * 2_500_000, 180) + np.tile(np.arange(180) * 1000,
                                                                     n_cols)
    x_edge = np.repeat(20 + np.arange(n_cols), 180)
    y_edge = np.tile(np.arange(180), n_cols)
    n_noise = int(240 * 180 * seconds)
    t_noise = rng.integers(0, int(seconds * 1e9), n_noise)
    t = np.concatenate([t_edge, t_noise])
    x = np.concatenate([x_edge, rng.integers(0, 240, n_noise)])
    y = np.concatenate([y_edge, rng.integers(0, 180, n_noise)])
    edge = np.concatenate([np.ones(len(t_edge), bool), np.zeros(n_noise, bool)])
    order = np.argsort(t, kind='stable')
    ev = EventArray.from_arrays(t[order] + 10**9, x[order], y[order], np.ones(len(t), np.uint8))
    return ev, edge[order]


def test_denoising_drops_the_noise_keeps_the_edge(rng: np.random.Generator) -> None:
    """5 ms bins: an edge pixel's column neighbours fire within 1 ms, so every edge event is
    kept; a noise event's support spans 5-10 ms, so 8 neighbours at 1 Hz support about 8 % of
    them (a little more next to the edge; measured 9.4-10.3 % on three seeds)."""
    ev, edge = edge_and_noise(rng)
    cfg = paper_framing(events_per_frame=1000, denoise_ms=5.0)
    pk = Packetizer(cfg)
    frames = pk.push(ev)
    kept = len(ev) - pk.denoised - pk.denoise_pending
    n_edge, n_noise = int(edge.sum()), int((~edge).sum())
    assert n_edge <= kept <= n_edge + 0.13 * n_noise
    # frames of the denoised events; columns 0-7 (sensor x < 20) see noise only
    t_ref, img_ref = frames_from_events(ev, cfg)
    np.testing.assert_array_equal(np.stack([f.image for f in frames]), img_ref[:len(frames)])
    _, img_raw = frames_from_events(ev, paper_framing(events_per_frame=1000))
    assert img_ref[:, :, :8].sum() <= 0.2 * img_raw[:, :, :8].sum()


def test_denoised_streaming_equals_batch_for_any_split(rng: np.random.Generator) -> None:
    ev, _ = edge_and_noise(rng, 0.1)
    cfg = paper_framing(events_per_frame=500, denoise_ms=2.0)
    t_ref, img_ref = frames_from_events(ev, cfg)
    pk = Packetizer(cfg)
    cuts = np.sort(rng.choice(np.arange(1, len(ev)), 80, replace=False))
    frames = []
    for a, b in zip(np.concatenate([[0], cuts]), np.concatenate([cuts, [len(ev)]]),
                    strict=True):
        frames += pk.push(ev[a:b])
    # the batch form flushes the last bin: at most its events' frames are missing here
    assert 0 < len(frames) <= len(t_ref) and len(t_ref) - len(frames) <= 3
    assert [f.t_ns for f in frames] == t_ref[:len(frames)].tolist()
    np.testing.assert_array_equal(np.stack([f.image for f in frames]), img_ref[:len(frames)])


@settings(max_examples=200, deadline=None)
@given(gaps=st.lists(st.sampled_from([0, 0, 1, 3, 50, 400, 5000]), min_size=1, max_size=300),
       k=st.integers(1, 40), m=st.integers(1, 40), span=st.sampled_from([0, 1, 100, 1000]),
       cuts=st.lists(st.integers(0, 300), max_size=12))
def test_time_capped_packets_hold_for_any_stream_and_split(
        gaps: list[int], k: int, m: int, span: int, cuts: list[int]) -> None:
    """Every packet: at most k events; fewer only when closed by time (at least m events, or
    just m when the window held fewer); pushes split anywhere (equal times across the split)
    give the batch's packets."""
    m = min(m, k)
    t = np.cumsum(np.asarray(gaps, np.int64)) + 10**6
    n = len(t)
    cfg = paper_framing(events_per_frame=k, min_frame_events=m, max_frame_ms=span / 1e6,
                        sensor_width=4, sensor_height=4, downsample=1.0)
    ends = packet_ends(t, cfg)
    starts = ends - np.diff(ends, prepend=0)
    for s, e in zip(starts.tolist(), ends.tolist(), strict=True):
        assert 0 < e - s <= k
        if e - s < k:
            assert span > 0 and e - s >= m
            assert t[-1] >= t[s] + span                       # its window is over
            if e - s > m:                                     # it holds its whole window
                assert t[e - 1] < t[s] + span <= t[e]
    ev = EventArray.from_arrays(t, np.arange(n) % 4, np.arange(n) // 4 % 4, np.zeros(n, np.int64))
    pk = Packetizer(cfg)
    got = []
    bounds = sorted({0, n, *[c for c in cuts if c < n]})
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        got += [f.n_events for f in pk.push(ev[a:b])]
    assert got == np.diff(ends, prepend=0).tolist()


def test_sensor_bounds_and_frame_usability_by_hand() -> None:
    """y == sensor_height is outside (checked over every event of the batch); a frame is
    usable with 1 .. max_fill x pixels on, and refused with a NaN."""
    pk = Packetizer(paper_framing(sensor_width=240, sensor_height=180))
    for y in ([0, 180], [180, 0]):
        bad = EventArray.from_arrays(np.array([1, 2]), np.array([3, 3]), np.array(y),
                                     np.array([0, 0]))
        with pytest.raises(DatasetError, match='outside the 240x180 sensor'):
            pk.push(bad)
    img = np.zeros((10, 10), np.uint8)
    assert not check_event_frame(img, 10, 10, 0.3, 'resonator')[1]   # nothing on
    img.flat[:30] = 1
    assert check_event_frame(img, 10, 10, 0.3, 'resonator')[1]       # exactly 30 %
    img.flat[30] = 1
    assert not check_event_frame(img, 10, 10, 0.3, 'resonator')[1]
    f = np.zeros((10, 10))
    f[2, 3] = np.nan
    with pytest.raises(TrackingError, match='non-finite'):
        check_event_frame(f, 10, 10, 0.3, 'resonator')
    f[2, 3] = 1.0
    assert check_event_frame(f, 10, 10, 0.3, 'resonator')[1]
