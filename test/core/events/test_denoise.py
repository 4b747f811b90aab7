"""The background-activity filter (core/events/denoise.py) on hand-built events."""

from __future__ import annotations

import numpy as np
import pytest

from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.denoise import NeighbourFilter
from hrn_vo_ros.errors import ConfigError

MS = 1_000_000


def events(rows: list[tuple[int, int, int]]) -> EventArray:
    """Events from (t_ns, x, y) rows, polarity 1."""
    t, x, y = (np.array(c, np.int64) for c in zip(*rows, strict=True))
    return EventArray.from_arrays(t, x, y, np.ones(len(t), np.uint8))


def run(rows: list[tuple[int, int, int]], window_ms: float = 5.0,
        splits: tuple[int, ...] = ()) -> list[tuple[int, int, int]]:
    """Filter ``rows`` pushed in pieces cut at ``splits``, flushed at the end."""
    f = NeighbourFilter(10, 8, int(window_ms * MS))
    ev = events(rows)
    cuts = [0, *splits, len(ev)]
    out = [f.push(ev[a:b]) for a, b in zip(cuts[:-1], cuts[1:], strict=True)] + [f.flush()]
    kept = EventArray.concatenate(out)
    assert f.kept == len(kept) and f.kept + f.dropped == len(ev)
    return [(int(a), int(b), int(c)) for a, b, c in zip(kept.t, kept.x, kept.y, strict=True)]


def test_lone_events_and_hot_pixels_go_neighbours_stay() -> None:
    rows = [(1 * MS, 5, 5),                      # alone: dropped
            (2 * MS, 1, 1), (3 * MS, 1, 1), (4 * MS, 1, 1),   # one pixel firing: dropped
            (2 * MS, 3, 6), (2 * MS + 1, 4, 7)]  # diagonal neighbours: both kept
    rows.sort()
    assert run(rows) == [(2 * MS, 3, 6), (2 * MS + 1, 4, 7)]


def test_support_reaches_into_the_previous_bin_only() -> None:
    """Bins of 5 ms: [0, 5), [5, 10), [10, 15). An event at 6 ms is supported by its
    neighbour at 1 ms (previous bin), not one at 11 ms is by the one at 1 ms (two bins)."""
    assert run([(1 * MS, 2, 2), (6 * MS, 3, 2)]) == [(6 * MS, 3, 2)]
    assert run([(1 * MS, 2, 2), (11 * MS, 3, 2)]) == []
    # within its own bin, support may come later (the bin is decided as a whole)
    assert run([(5 * MS, 2, 2), (9 * MS, 2, 3)]) == [(5 * MS, 2, 2), (9 * MS, 2, 3)]
    # but not from the next bin: the earlier event gets no support from the later one
    assert run([(4 * MS, 2, 2), (6 * MS, 2, 3)]) == [(6 * MS, 2, 3)]


def test_borders_do_not_wrap() -> None:
    """(9, 3) and (0, 4) are neighbours in flat index (y * 10 + x = 39, 40) only."""
    assert run([(1 * MS, 9, 3), (1 * MS, 0, 4)]) == []
    assert run([(1 * MS, 9, 7), (1 * MS, 8, 6)]) == [(1 * MS, 9, 7), (1 * MS, 8, 6)]


def test_equal_timestamps_and_any_batching_give_the_same_events() -> None:
    rng = np.random.default_rng(3)
    n = 120                                      # about 15 events per bin on 80 pixels
    t = np.sort(rng.integers(0, 40 * MS, n))
    t[40:50] = t[40]                             # a run of equal timestamps across a split
    rows = [(int(a), int(b), int(c)) for a, b, c in
            zip(t, rng.integers(0, 10, n), rng.integers(0, 8, n), strict=True)]
    whole = run(rows)
    assert 0 < len(whole) < n
    for splits in [(1,), (45,), (30, 31, 32, 100), tuple(range(1, n, 7))]:
        assert run(rows, splits=splits) == whole
    # the brute-force definition, event by event
    ref = []
    for tk, xk, yk in rows:
        b = tk // (5 * MS)
        if any(abs(x - xk) <= 1 and abs(y - yk) <= 1 and (x, y) != (xk, yk)
               and b - 1 <= t2 // (5 * MS) <= b for t2, x, y in rows):
            ref.append((tk, xk, yk))
    assert whole == ref


def test_newest_bin_is_held_until_complete() -> None:
    f = NeighbourFilter(10, 8, 5 * MS)
    assert len(f.push(events([(1 * MS, 2, 2), (2 * MS, 3, 3)]))) == 0
    assert f.pending == 2
    out = f.push(events([(7 * MS, 0, 0)]))       # bin 1 starts: bin 0 is decided
    assert len(out) == 2 and f.pending == 1
    assert len(f.flush()) == 0 and f.pending == 0


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ConfigError, match='positive window'):
        NeighbourFilter(10, 8, 0)
    for w, h in ((0, 8), (10, 0), (-1, -1)):
        with pytest.raises(ConfigError, match='positive window and sensor size'):
            NeighbourFilter(w, h, MS)
    NeighbourFilter(1, 1, 1)                     # the smallest sensor and bin


def test_bins_processed_in_chunks_equal_the_brute_force_definition(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Many bins at once are decided a few at a time (occupancy images of at most _CHUNK
    bytes): with chunks of 1, 2 and 3 bins (a chunk boundary between every pair of bins) the
    kept events equal the definition, event by event."""
    rng = np.random.default_rng(4)
    n = 150
    t = np.sort(rng.integers(0, 60 * MS, n))
    rows = [(int(a), int(b), int(c)) for a, b, c in
            zip(t, rng.integers(0, 10, n), rng.integers(0, 8, n), strict=True)]
    ref = [(tk, xk, yk) for tk, xk, yk in rows
           if any(abs(x - xk) <= 1 and abs(y - yk) <= 1 and (x, y) != (xk, yk)
                  and tk // (5 * MS) - 1 <= t2 // (5 * MS) <= tk // (5 * MS)
                  for t2, x, y in rows)]
    assert 0 < len(ref) < n
    for bins in (1, 2, 3):
        monkeypatch.setattr(NeighbourFilter, '_CHUNK', 12 * 10 * bins)   # (10 + 2) x (8 + 2)
        assert run(rows) == ref
