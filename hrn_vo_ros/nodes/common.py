"""Helpers shared by the package's nodes: QoS profiles, throttled rejects, the Jazzy main()."""

from __future__ import annotations

from collections.abc import Callable
import contextlib
import signal
import time
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo

from hrn_vo_ros.errors import ConfigError
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


def _ignore_stop_signals() -> None:
    """From here on SIGINT and SIGTERM cannot interrupt the (short, bounded) clean-up.

    ``ros2 launch`` sends SIGINT to every process and escalates with SIGTERM; a user may press
    Ctrl-C twice. A second signal inside ``destroy_node`` would otherwise raise there (a
    traceback and exit -2) and leave e.g. the recorder's bag unfinished.
    """
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(ValueError, OSError):   # not the main thread: keep them
            signal.signal(sig, signal.SIG_IGN)


def _executor() -> SingleThreadedExecutor | None:
    """rclpy's executor, made with the stop signals held back until it exists; None when a
    signal already shut the context down (while the node was being made).

    An executor made on a shut-down context, or interrupted in its constructor, is left
    half-made and its ``__del__`` prints a traceback; held back, a signal arrives right after
    and stops the node as at any other point.
    """
    stop = {signal.SIGINT, signal.SIGTERM}
    old = signal.pthread_sigmask(signal.SIG_BLOCK, stop)
    try:
        return SingleThreadedExecutor() if rclpy.ok() else None
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def default_stop_signals() -> None:
    """SIGINT raises KeyboardInterrupt and SIGTERM ends the process again (Python's defaults),
    replacing the start-up handlers of :mod:`hrn_vo_ros.nodes`; ``rclpy.init`` then installs
    its own handlers on top, as in any rclpy program."""
    with contextlib.suppress(ValueError, OSError):   # not the main thread: keep them
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _shut_down(node: Node | None) -> None:
    """Destroy the node and shut rclpy down, ignoring further stop signals meanwhile."""
    steps: list[Callable[[], object]] = [] if node is None else [node.destroy_node]
    steps.append(rclpy.try_shutdown)
    while steps:
        try:
            _ignore_stop_signals()
            steps[0]()
        except KeyboardInterrupt:   # a signal that came before the handlers were replaced
            continue                # the step was interrupted: run it again, now shielded
        except Exception as err:     # the clean-up goes on; logged
            rclpy.logging.get_logger('hrn_vo_ros').warning(f'during shutdown: {err!r}')
        steps.pop(0)


def run(make_node: Callable[[], Node], args: list[str] | None = None) -> int:
    """The Jazzy entry point: init, spin, shut down cleanly on Ctrl-C or external shutdown.

    A :class:`ConfigError` while the node starts (bad parameters) is logged and gives exit 2.
    SIGINT or SIGTERM at any point from here on — during start-up, spin or shutdown, once or
    repeatedly — ends the process promptly with exit 0 and no traceback: a signal during
    start-up stops it there (rclpy's handler shuts the context down, so whatever the node was
    creating fails; that failure is not reported as an error), and once shutting down further
    signals are ignored until the bounded clean-up is done (the process is ending: they
    stay ignored).
    """
    node = None
    code = 0
    initialised = False
    default_stop_signals()   # drop the import-time exit (hrn_vo_ros.nodes) before rclpy's own
    try:
        rclpy.init(args=args)
        initialised = True
        node = make_node()
        executor = _executor()
        if executor is not None:
            rclpy.spin(node, executor=executor)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ConfigError as err:
        rclpy.logging.get_logger('hrn_vo_ros').error(f'invalid parameters: {err}')
        code = 2
    except Exception:
        if not initialised or rclpy.ok():   # a real error, not a signal during start-up
            raise
    finally:
        _shut_down(node)
    return code
