"""Helpers shared by the package's nodes: QoS profiles, throttled rejects and notes, the
camera_info input and diagnostics (the process entry point ``run``: :mod:`.process`)."""

from __future__ import annotations

from collections.abc import Callable
import time
from typing import Any

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo

from hrn_vo_ros.core.clock import Throttle
from hrn_vo_ros.core.events.stream import Note
from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.nodes.stats import NodeStats


def qos(depth: int, *, reliable: bool = True, keep_all: bool = False) -> QoSProfile:
    """KEEP_LAST ``depth`` (or KEEP_ALL), VOLATILE, RELIABLE or BEST_EFFORT."""
    return QoSProfile(history=HistoryPolicy.KEEP_ALL if keep_all else HistoryPolicy.KEEP_LAST,
                      depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE if reliable
                      else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.VOLATILE)


class Rejects:
    """Counts malformed messages by kind and logs each kind at most once per throttle period.

    Each kind logs through its own child logger, so one noisy kind cannot hide another.
    """

    def __init__(self, node: Node, stats: NodeStats, throttle_s: Callable[[], float]) -> None:
        self._node = node
        self._stats = stats
        self._throttle_s = throttle_s
        self._loggers: dict[str, Any] = {}

    def __call__(self, kind: str, detail: object) -> None:
        """Count one rejected message of ``kind`` and log why (throttled)."""
        self._stats.reject(kind)
        logger = self._loggers.get(kind)
        if logger is None:
            logger = self._loggers[kind] = self._node.get_logger().get_child(kind)
        logger.warning(f'dropped a message ({kind}, {self._stats.bad[kind]} so far): {detail}',
                       throttle_duration_sec=self._throttle_s())


class NoteLog:
    """Logs the notes of a node's core logic (:class:`~hrn_vo_ros.core.events.stream.Note`):
    rejects counted into ``stats`` and logged by :attr:`reject` (:class:`Rejects`, also the
    node's own), info as info, warnings as warnings, throttled ones at most once per
    ``throttle_s()`` per kind."""

    def __init__(self, node: Node, stats: NodeStats, throttle_s: Callable[[], float]) -> None:
        self._node, self._throttle_s = node, throttle_s
        self.reject = Rejects(node, stats, throttle_s)
        self._throttle = Throttle()

    def __call__(self, note: Note) -> None:
        if note.level == 'reject':
            self.reject(note.kind, note.text)
        elif note.level == 'info':
            self._node.get_logger().info(note.text)
        elif not note.throttled or self._throttle.due(note.kind, self._throttle_s()):
            self._node.get_logger().warning(note.text)


class CameraInfoInput:
    """A node's ``~/camera_info`` subscription (``sensor_msgs/CameraInfo``, depth 1) that takes
    latched and volatile publishers alike.

    BEST_AVAILABLE resolves against the publishers present when it is created, so the caller's
    timer calls :meth:`recheck`, which re-subscribes when the set of publishers changed.
    """

    def __init__(self, node: Node, callback: Callable[[CameraInfo], None]) -> None:
        self._node, self._callback = node, callback
        self.topic = node.resolve_topic_name('~/camera_info')
        self._sub: Any = None
        self._publishers = -1
        self._subscribe()

    def _subscribe(self) -> None:
        self.close()
        self._publishers = self._node.count_publishers(self.topic)
        latched_or_not = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_AVAILABLE,
                                    durability=DurabilityPolicy.BEST_AVAILABLE)
        self._sub = self._node.create_subscription(CameraInfo, '~/camera_info', self._callback,
                                                   latched_or_not)

    def recheck(self) -> None:
        """Re-subscribe if the publishers of the topic changed since the last subscription."""
        if self._sub is not None and self._node.count_publishers(self.topic) != self._publishers:
            self._subscribe()

    def close(self) -> None:
        """Stop listening (no more callbacks)."""
        if self._sub is not None:
            self._node.destroy_subscription(self._sub)
            self._sub = None


_RANK = {'ok': 0, 'warn': 1, 'error': 2, 'stale': 3}


def worst(*levels: tuple[str, str]) -> tuple[str, str]:
    """The most severe of ``(level, message)`` pairs (the first of equal ones)."""
    out = ('ok', 'running')
    for lv in levels:
        if _RANK[lv[0]] > _RANK[out[0]]:
            out = lv
    return out


def publish_diagnostics(node: Node, pub: Any, stats: NodeStats, extra: list[tuple[str, object]],
                        *, level: str = 'ok', message: str = 'running',
                        window_s: float = 10.0) -> None:
    """Publish the node's counters (plus ``extra``) as one DiagnosticStatus.

    The level describes the current window: ``level`` (the node's own state, e.g. WARN while
    holding events), raised to WARN while a message was rejected in the last ``window_s``
    seconds; OK again once the cause has passed. The counters keep the totals.
    """
    t_ns = time.time_ns()
    name = f'{node.get_name()}: {node.get_fully_qualified_name()}'
    if stats.rejected_within(window_s):
        level, message = worst((level, message), (
            'warn', f'malformed messages dropped in the last {window_s:g} s '
            f'({sum(stats.bad.values())} in all)'))
    extra = extra + [('level_window_s', window_s)]
    msg = ros_msgs.diagnostics(t_ns, name, 'hrn_vo_ros', level, message,
                               extra + stats.values())
    pub.publish(msg)
