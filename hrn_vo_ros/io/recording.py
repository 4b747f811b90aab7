"""Record raw (CDR) messages into a ROS 2 bag from a background thread (rosbag2_py stand-in).

Subscription callbacks only :meth:`BagRecorder.put` the serialised bytes into a bounded queue;
one writer thread owns the :class:`~hrn_vo_ros.io.bags.BagWriter` (crash-safe: the bag appears
at its path only after a clean :meth:`BagRecorder.close`). A full queue drops the message and
counts it instead of blocking the caller.

Killed recordings: the writer thread closes the pending MCAP chunk and flushes the file every
``flush_period_s`` seconds (and whenever a chunk fills), so a SIGKILLed recorder leaves a
``.partial`` bag whose complete chunks hold everything up to the last flush;
:func:`~hrn_vo_ros.io.bags.recover_bag` (``hrn-vo recover``) rewrites them as a bag.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path
import queue
import threading
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rosbags.interfaces import Connection

from hrn_vo_ros.core.evaluation.series import EstimateSeries
from hrn_vo_ros.errors import BagError, DatasetError
from hrn_vo_ros.io.bags import BagWriter, iter_messages, make_qos, open_bag, Storage, typestore
from hrn_vo_ros.io.estimates import EstimateFile, STATES

_STOP = None


class BagRecorder:
    """A bag being recorded by a writer thread.

    Args:
        dst: The bag directory to create (must not exist).
        topics: ``(topic, msgtype)`` pairs, e.g. ``('/odom', 'nav_msgs/msg/Odometry')``.
        storage: ``'mcap'`` or ``'sqlite3'``.
        max_queue: Messages buffered before :meth:`put` starts dropping.
        flush_period_s: Longest time a written message stays in memory (an open MCAP chunk)
            before the writer closes the chunk and flushes the file: what a SIGKILL can lose.

    Raises:
        BagError: if ``dst`` exists or a message type is unknown.
    """

    def __init__(self, dst: Path | str, topics: list[tuple[str, str]], *,
                 storage: Storage = 'mcap', max_queue: int = 100_000,
                 flush_period_s: float = 1.0) -> None:
        self._writer = BagWriter(dst, storage=storage)
        unknown = [t for _, t in topics if t not in self._writer.ts.types]
        if unknown:
            raise BagError(f'unknown message type(s) {", ".join(unknown)}: use pkg/msg/Name')
        self._topics = list(topics)
        self._flush_period_s = float(flush_period_s)
        self._queue: queue.Queue[tuple[str, int, bytes] | None] = queue.Queue(max_queue)
        self.dropped: Counter[str] = Counter()
        self.written: Counter[str] = Counter()
        self.flushes = 0
        self._error: BaseException | None = None
        self._ready = threading.Event()
        self._thread = threading.Thread(target=self._run, name='bag-writer', daemon=True)
        self._thread.start()
        self._ready.wait()
        if self._error is not None:
            raise self._error

    def _run(self) -> None:
        try:
            with self._writer as w:
                conns = {t: w.add_topic(t, m, make_qos(reliable=True, depth=1000))
                         for t, m in self._topics}
                self._ready.set()
                self._write_loop(w, conns)
        except BaseException as err:  # reported by close(); the partial bag is deleted
            self._error = err
            self._ready.set()

    def _write_loop(self, w: BagWriter, conns: dict[str, Connection]) -> None:
        period = self._flush_period_s
        due: float | None = None  # when the oldest unflushed message must be on disk
        while True:
            try:
                timeout = None if due is None else max(0.0, due - time.monotonic())
                item = self._queue.get(timeout=timeout)
            except queue.Empty:
                item = ('', 0, b'')  # nothing new: only the flush below is due
            if item is _STOP:
                return
            topic, t_ns, raw = item
            if topic:
                w.write(conns[topic], t_ns, raw)
                self.written[topic] += 1
                if due is None:
                    due = time.monotonic() + period
            if due is not None and time.monotonic() >= due:
                w.flush()
                self.flushes += 1
                due = None

    def put(self, topic: str, t_ns: int, raw: bytes) -> bool:
        """Queue one message without blocking; False (and counted) when the queue is full."""
        try:
            self._queue.put_nowait((topic, t_ns, raw))
        except queue.Full:
            self.dropped[topic] += 1
            return False
        return True

    def close(self, timeout: float = 60.0) -> None:
        """Write what is queued, finish the bag and make it appear at its path.

        Raises:
            BagError: if writing failed or did not finish within ``timeout`` seconds.
        """
        self._queue.put(_STOP)
        self._thread.join(timeout)
        if self._thread.is_alive():
            raise BagError(f'the bag writer did not finish within {timeout} s')
        if self._error is not None:
            raise BagError(f'recording failed: {self._error}') from self._error


def read_readouts(bag: Path | str, topic: str) -> tuple[NDArray[np.int64],
                                                         dict[str, NDArray[np.float64]]]:
    """The raw readouts (``sensor_msgs/JointState``, io/ros_msgs.py) recorded on ``topic``.

    Returns:
        ``(t_ns, values)``: header stamps and one array per joint name (h, v, r [, z], and the
        ``quality`` and ``state`` code the resonator node appends, io/ros_msgs.py).

    Shapes:
        t_ns: (n,) int64; values[name]: (n,) float64.

    Raises:
        BagError: if the bag is unreadable or the topic is missing.
    """
    reader = open_bag(bag)
    try:
        if topic not in {c.topic for c in reader.connections}:
            raise BagError(f'{bag}: no topic {topic}; it has '
                           f'{", ".join(sorted(c.topic for c in reader.connections))}')
        ts = typestore()
        stamps: list[int] = []
        rows: list[list[float]] = []
        names: list[str] = []
        for m in iter_messages(reader, [topic]):
            msg: Any = ts.deserialize_cdr(m.raw, m.msgtype)
            stamps.append(int(msg.header.stamp.sec) * 1_000_000_000
                          + int(msg.header.stamp.nanosec))
            names = list(msg.name)
            rows.append([float(v) for v in msg.position])
    finally:
        reader.close()
    order = np.argsort(np.asarray(stamps, np.int64), kind='stable')
    arr = np.asarray(rows, np.float64).reshape(len(rows), len(names))[order]
    return (np.asarray(stamps, np.int64)[order],
            {n: np.ascontiguousarray(arr[:, i]) for i, n in enumerate(names)})


def read_readout_estimates(bag: Path | str, topic: str) -> EstimateFile:
    """The recorded readouts as an estimate file: the series (h, v, r [, z]) and the quality
    and tracking state (decoded from the state codes, io/ros_msgs.py) where recorded.

    Raises:
        BagError: as :func:`read_readouts`. DatasetError: for no readouts, a missing h, v or
            r, or a state code outside 0..2.
    """
    t, vals = read_readouts(bag, topic)
    if len(t) == 0:
        raise DatasetError(f'no readouts on {topic}', path=Path(bag))
    missing = [k for k in ('h', 'v', 'r') if k not in vals]
    if missing:
        raise DatasetError(f'{topic}: readouts lack {", ".join(missing)}', path=Path(bag))
    state: list[str] | None = None
    if 'state' in vals:
        codes = vals['state']
        bad = ~np.isin(codes, np.arange(len(STATES), dtype=np.float64))
        if bad.any():
            raise DatasetError(f'{topic}: state code {float(codes[bad][0])!r} is not one of '
                               + ', '.join(f'{k} ({s})' for k, s in enumerate(STATES)),
                               path=Path(bag))
        state = [STATES[int(c)] for c in codes]
    series = EstimateSeries(t=t, h=vals['h'], v=vals['v'], r=vals['r'], z=vals.get('z'))
    return EstimateFile(series, vals.get('quality'), state)
