"""Record raw (CDR) messages into a ROS 2 bag from a background thread (rosbag2_py stand-in).

Subscription callbacks only :meth:`BagRecorder.put` the serialised bytes into a bounded queue;
one writer thread owns the :class:`~hrn_vo_ros.io.bags.BagWriter` (crash-safe: the bag appears
at its path only after a clean :meth:`BagRecorder.close`). A full queue drops the message and
counts it instead of blocking the caller.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path
import queue
import threading
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hrn_vo_ros.errors import BagError
from hrn_vo_ros.io.bags import BagWriter, iter_messages, make_qos, open_bag, Storage, typestore

_STOP = None


class BagRecorder:
    """A bag being recorded by a writer thread.

    Args:
        dst: The bag directory to create (must not exist).
        topics: ``(topic, msgtype)`` pairs, e.g. ``('/odom', 'nav_msgs/msg/Odometry')``.
        storage: ``'mcap'`` or ``'sqlite3'``.
        max_queue: Messages buffered before :meth:`put` starts dropping.

    Raises:
        BagError: if ``dst`` exists or a message type is unknown.
    """

    def __init__(self, dst: Path | str, topics: list[tuple[str, str]], *,
                 storage: Storage = 'mcap', max_queue: int = 100_000) -> None:
        self._writer = BagWriter(dst, storage=storage)
        unknown = [t for _, t in topics if t not in self._writer.ts.types]
        if unknown:
            raise BagError(f'unknown message type(s) {", ".join(unknown)}: use pkg/msg/Name')
        self._topics = list(topics)
        self._queue: queue.Queue[tuple[str, int, bytes] | None] = queue.Queue(max_queue)
        self.dropped: Counter[str] = Counter()
        self.written: Counter[str] = Counter()
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
                while (item := self._queue.get()) is not _STOP:
                    topic, t_ns, raw = item
                    w.write(conns[topic], t_ns, raw)
                    self.written[topic] += 1
        except BaseException as err:  # reported by close(); the partial bag is deleted
            self._error = err
            self._ready.set()

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
        ``(t_ns, values)``: header stamps and one array per factor name (h, v, r [, z]).

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
