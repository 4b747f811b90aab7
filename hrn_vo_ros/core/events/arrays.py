"""Events as a struct of contiguous arrays: the one event type of the package.

Clock: ``t`` is the event's **sensor time** in int64 nanoseconds (the camera's clock: for an
EventPacket ``time_base + dt``, for the Event Camera Dataset the ``events.txt`` seconds times 1e9).
Coordinates are sensor pixels, (0, 0) top-left, x to the right, y down. Polarity is 1 for ON and
0 for OFF.
"""

from __future__ import annotations

from dataclasses import dataclass
import hashlib

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True, slots=True, eq=False)
class EventArray:
    """A batch of events in time order.

    Shapes:
        t, x, y, p: (n,) each; t int64 ns, x and y uint16, p uint8 (1 = ON).
    """

    t: NDArray[np.int64]
    x: NDArray[np.uint16]
    y: NDArray[np.uint16]
    p: NDArray[np.uint8]

    @classmethod
    def empty(cls) -> EventArray:
        """An array of no events."""
        return cls(np.empty(0, np.int64), np.empty(0, np.uint16), np.empty(0, np.uint16),
                   np.empty(0, np.uint8))

    @classmethod
    def from_arrays(cls, t: NDArray[np.generic], x: NDArray[np.generic],
                    y: NDArray[np.generic], p: NDArray[np.generic]) -> EventArray:
        """Build from any integer arrays, converting dtypes (copies only when needed)."""
        return cls(np.ascontiguousarray(t, np.int64), np.ascontiguousarray(x, np.uint16),
                   np.ascontiguousarray(y, np.uint16), np.ascontiguousarray(p, np.uint8))

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def __getitem__(self, index: slice | NDArray[np.bool_] | NDArray[np.intp]) -> EventArray:
        return EventArray(self.t[index], self.x[index], self.y[index], self.p[index])

    @staticmethod
    def concatenate(parts: list[EventArray]) -> EventArray:
        """Join batches in the given order."""
        if not parts:
            return EventArray.empty()
        return EventArray(np.concatenate([e.t for e in parts]),
                          np.concatenate([e.x for e in parts]),
                          np.concatenate([e.y for e in parts]),
                          np.concatenate([e.p for e in parts]))


def runs(keys: NDArray[np.integer]) -> list[tuple[int, int]]:
    """The ``[start, end)`` index ranges of the runs of equal consecutive values of ``keys``
    (e.g. the time bin of each event, in time order), in order; none for no keys."""
    edges = (np.flatnonzero(np.diff(keys)) + 1).tolist()
    return list(zip([0, *edges], [*edges, len(keys)], strict=True)) if len(keys) else []


class EventChecksum:
    """An order-sensitive running checksum of (t, x, y, p), to prove that nothing was lost.

    Feed batches in order with :meth:`update`; two streams agree iff the same events arrived in
    the same order (up to SHA-256 collisions). Batch boundaries do not matter.
    """

    def __init__(self) -> None:
        self._h = hashlib.sha256()
        self.count = 0

    def update(self, ev: EventArray) -> None:
        """Add a batch of events."""
        rec = np.empty(len(ev), dtype=[('t', '<i8'), ('x', '<u2'), ('y', '<u2'), ('p', 'u1')])
        rec['t'] = ev.t
        rec['x'] = ev.x
        rec['y'] = ev.y
        rec['p'] = ev.p
        self._h.update(rec.tobytes())
        self.count += len(ev)

    def hexdigest(self) -> str:
        """The checksum so far."""
        return self._h.hexdigest()
