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

from hrn_vo_ros.errors import BagError
from hrn_vo_ros.io.bags import BagWriter, make_qos, Storage

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
