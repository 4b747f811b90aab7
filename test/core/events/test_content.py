"""The frame-structure measure: hand-counted pairs, noise, lines and simulated frames."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hrn_vo_ros.core.events.content import frame_structure, neighbour_ratio


def test_pairs_are_counted_against_random_placement() -> None:
    """4x4 frame, a row of three and a lone pixel: 2 pairs; 24 neighbour slots, so 4 random
    pixels give 24 * 4 * 3 / (16 * 15) = 1.2 pairs on average: 5/3. A 2x2 block: 4 pairs."""
    f = np.zeros((4, 4), np.uint8)
    f[0, :3] = 1
    f[3, 3] = 1
    assert neighbour_ratio(f) == pytest.approx(2 / 1.2)
    g = np.zeros((4, 4), bool)
    g[1:3, 1:3] = True
    assert neighbour_ratio(g) == pytest.approx(4 / 1.2)
    # diagonal neighbours are no pairs
    assert neighbour_ratio(np.eye(4)) == 0.0


def test_noise_reads_one_and_a_thin_line_one_over_twice_its_density() -> None:
    rng = np.random.default_rng(7)
    frames = np.zeros((60, 72, 96), np.uint8)
    for f in frames:
        f.flat[rng.choice(f.size, 700, replace=False)] = 1
    assert frame_structure(frames) == pytest.approx(1.0, abs=0.03)    # measured 1.004
    line = np.zeros((72, 96), np.uint8)
    line[6:66, 40] = 1                       # 60 pixels, 59 pairs
    expected = (72 * 95 + 96 * 71) * 60 * 59 / (6912 * 6911)
    assert neighbour_ratio(line) == pytest.approx(59 / expected)
    assert neighbour_ratio(line) == pytest.approx(6912 / (2 * 60), rel=0.02)   # about


def test_too_few_pixels_are_nan_and_left_out_of_the_median() -> None:
    empty = np.zeros((8, 8), np.uint8)
    one = empty.copy()
    one[2, 2] = 1
    two = empty.copy()
    two[2, 2:4] = 1                           # 1 pair of 112 * 2 / (64 * 63) expected
    assert math.isnan(neighbour_ratio(empty)) and math.isnan(neighbour_ratio(one))
    assert frame_structure(np.stack([empty, one, two])) == pytest.approx(64 * 63 / 224)
    assert math.isnan(frame_structure(np.stack([empty, one])))
    assert math.isnan(neighbour_ratio(np.ones((1, 1))))
    with pytest.raises(ValueError, match='2-D frame'):
        neighbour_ratio(np.zeros((2, 3, 4)))


def test_simulated_edges_stand_out_from_simulated_noise() -> None:
    """Frames of a simulated shapes rotation (no sensor noise) against frames of uniformly
    scattered events at the same count, through the same packetizer."""
    from hrn_vo_ros.core.events.arrays import EventArray
    from hrn_vo_ros.core.events.frames import frames_from_events
    from hrn_vo_ros.core.events.packet_config import PacketizerConfig
    from hrn_vo_ros.core.sim.config import SimulatorConfig
    from hrn_vo_ros.core.sim.simulator import simulate
    cfg = PacketizerConfig(events_per_frame=2000, sensor_width=240, sensor_height=180,
                           downsample=2.5)
    quiet = SimulatorConfig(noise_rate_hz=0.0, hot_pixels=0)
    seq = simulate('rotation', 0.5, seed=3, config=quiet)
    _, edges = frames_from_events(seq.events, cfg)
    rng = np.random.default_rng(3)
    n = len(seq.events)
    noise = EventArray(np.sort(rng.integers(0, 500_000_000, n)).astype(np.int64),
                       rng.integers(0, 240, n).astype(np.uint16),
                       rng.integers(0, 180, n).astype(np.uint16), rng.integers(0, 2, n) > 0)
    _, scattered = frames_from_events(noise, cfg)
    assert len(edges) >= 5 and len(scattered) >= 5
    assert frame_structure(scattered) == pytest.approx(1.0, abs=0.03)   # measured 0.997
    assert 8.0 < frame_structure(edges) < 16.0                          # measured 11.9
