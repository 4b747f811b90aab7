"""``bag_player``: publishes a ROS 2 bag for machines without ``ros2 bag play``.

Every selected topic is published with its recorded type as raw CDR (no re-serialisation:
``publish(bytes)``; the message class is imported only for its type support) and with its
recorded QoS profile (best effort for event packets, transient local for camera info; with
``reliable`` every topic is RELIABLE, for lossless replay into reliable subscribers). Timing
follows the bag (:class:`~hrn_vo_ros.io.playback.PlaybackSchedule`): real time, a ``rate``
factor, or ``max_rate`` (no timing; RELIABLE + KEEP_ALL writers, so reliable KEEP_ALL subscribers
pace the player). With ``clock`` it
publishes ``/clock`` for ``use_sim_time`` nodes. It exits when the bag is done and logs the
messages sent per topic.

    ros2 run hrn_vo_ros bag_player --ros-args -p bag:=shapes_rotation -p rate:=2.0 -p clock:=true
"""

from __future__ import annotations

from contextlib import ExitStack
import sys
import time
from typing import Any

from rclpy._rclpy_pybind11 import RCLError
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

from hrn_vo_ros.errors import BagError, ConfigError, HrnVoError
from hrn_vo_ros.io import bags, ros_msgs
from hrn_vo_ros.io.playback import play, PlaybackConfig, publish_retrying
from hrn_vo_ros.nodes.process import run_task

EVENT_TYPES = (bags.EVENT_PACKET, bags.DVS_EVENT_ARRAY)
LINGER_S = 0.5  # after the last record, so that best-effort samples leave the process
SETTLE_S = 0.5  # after subscribers matched, so that they have matched the player too


def qos_profile(conn: Any, *, reliable: bool = False, keep_all: bool = False) -> QoSProfile:
    """The rclpy QoS of a recorded topic (events without a record: best effort, depth 1000).

    Args:
        conn: The bag connection (topic, type, recorded QoS profiles).
        reliable: Force RELIABLE, so that reliable subscribers match (a best-effort writer does
            not match them); best-effort subscribers still match a reliable writer.
        keep_all: Force KEEP_ALL (max-rate playback: the writer blocks while its history is
            full, so KEEP_ALL reliable subscribers pace the player and lose nothing).
    """
    recorded = bags.qos_profiles(conn)
    events = conn.msgtype in EVENT_TYPES
    best_effort = (recorded[0].reliability.name == 'BEST_EFFORT' if recorded else events)
    depth = max(int(recorded[0].depth), 1) if recorded else (1000 if events else 10)
    history_all = keep_all or bool(recorded and recorded[0].history.name == 'KEEP_ALL')
    latched = bool(recorded and recorded[0].durability.name == 'TRANSIENT_LOCAL')
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL if history_all else HistoryPolicy.KEEP_LAST, depth=depth,
        reliability=ReliabilityPolicy.BEST_EFFORT if best_effort and not reliable
        else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


class BagPlayer(Node):
    """Bag → topics (see the module docstring).

    Args:
        config: Options; None reads them from ROS parameters (the ``bag_player`` executable).

    Raises:
        BagError: for a missing, unfinished or corrupt bag or topics it does not hold.
    """

    def __init__(self, config: PlaybackConfig | None = None, **kwargs: Any) -> None:
        super().__init__('bag_player', **kwargs)
        if config is None:
            from hrn_vo_ros.nodes.params import declare_config
            config = declare_config(self, PlaybackConfig).config
        if not config.bag:
            raise BagError('bag_player needs the parameter bag (a ROS 2 bag directory)')
        self.cfg = config
        self._stack = ExitStack()
        try:
            self._setup(config)
        except BaseException:
            self._stack.close()
            raise

    def _setup(self, config: PlaybackConfig) -> None:
        self.reader = self._stack.enter_context(bags.open_bag(config.bag))
        conns = {c.topic: c for c in self.reader.connections}
        missing = sorted(set(config.topics) - set(conns))
        if missing:
            raise BagError(f'{config.bag} has no topic(s) {", ".join(missing)}; it has '
                           f'{", ".join(sorted(conns))}')
        self.topics: list[str] = []
        self.pubs: dict[str, Any] = {}
        for t in list(config.topics) or sorted(conns):
            try:
                cls = ros_msgs.message_class(conns[t].msgtype)
            except HrnVoError as err:
                if config.topics:  # asked for explicitly
                    raise
                self.get_logger().warning(f'skipping {t}: {err}')
                continue
            self.topics.append(t)
            self.pubs[t] = self.create_publisher(
                cls, t, qos_profile(conns[t], keep_all=config.max_rate,
                                    reliable=config.reliable or config.max_rate))
        missing = [t for t in config.wait_topics if t not in self.pubs]
        if missing:
            raise ConfigError(f'wait_topics {missing} are not played from {config.bag} (played: '
                              f'{self.topics}): wait on played topics only')
        self.waited_for = list(config.wait_topics) or [
            t for t in self.topics if conns[t].msgtype in EVENT_TYPES] or self.topics
        self.clock_pub = self.create_publisher(Clock, '/clock', 10) if config.clock else None
        self.sent = dict.fromkeys(self.topics, 0)

    def wait_for_subscribers(self) -> bool:
        """Wait until every topic of ``waited_for`` (``wait_topics``, or the event topics) has
        ``wait_for_subscribers`` subscribers (or timeout)."""
        need, deadline = self.cfg.wait_for_subscribers, time.monotonic() + self.cfg.wait_timeout_s
        while any(self.pubs[t].get_subscription_count() < need for t in self.waited_for):
            if time.monotonic() > deadline:
                self.get_logger().warning(f'no {need} subscriber(s) on {self.waited_for} after '
                                          f'{self.cfg.wait_timeout_s} s: playing anyway')
                return False
            time.sleep(0.02)
        time.sleep(SETTLE_S)
        return True

    def play(self) -> dict[str, int]:
        """Publish the whole bag; returns the messages sent per topic."""
        cfg = self.cfg
        if cfg.wait_for_subscribers:
            self.wait_for_subscribers()
        records = ((m.topic, m.t_ns, bytes(m.raw))
                   for m in bags.iter_messages(self.reader, self.topics))
        def publish(topic: str, raw: bytes) -> None:
            if cfg.max_rate:    # KEEP_ALL writers block, then time out while readers lag
                publish_retrying(self.pubs[topic].publish, raw, cfg.ack_timeout_s,
                                 retry_on=RCLError)
            else:
                self.pubs[topic].publish(raw)

        sent = play(records, publish,
                    rate=None if cfg.max_rate else cfg.rate, clock_hz=cfg.clock_hz,
                    clock=self._publish_clock if self.clock_pub is not None else None)
        ack = Duration(seconds=cfg.ack_timeout_s)
        for pub in self.pubs.values():
            pub.wait_for_all_acked(ack)
        time.sleep(LINGER_S)
        self.sent.update(sent)
        self.get_logger().info(f'played {cfg.bag}: {self.sent}')
        return dict(self.sent)

    def _publish_clock(self, t_ns: int) -> None:
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = divmod(t_ns, 1_000_000_000)
        assert self.clock_pub is not None
        self.clock_pub.publish(msg)

    def destroy_node(self) -> None:
        """Close the bag with the node."""
        self._stack.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Console script ``bag_player``: play, report, exit 0 (a package error's exit code, e.g. 4
    for a bad bag; 130 when stopped; the clean-up is bounded: ``nodes/process.py``)."""
    return run_task(BagPlayer, _play, args, logger='bag_player')


def _play(node: BagPlayer) -> int:
    """``bag_player``'s job: the whole bag (its counts are logged by ``play``), exit 0."""
    node.play()
    return 0


if __name__ == '__main__':
    sys.exit(main())
