"""``bag_recorder``: records topics as raw CDR into a ROS 2 bag (rosbag2_py is not available).

Each topic of the ``topics`` parameter (``TOPIC:pkg/msg/Type``) is subscribed RELIABLE with
``raw=True``; callbacks only queue the bytes (bag time = receive time), a writer thread writes
them (io/recording.py). The bag appears at ``output`` when the node shuts down cleanly (Ctrl-C,
SIGTERM). Killed (SIGKILL, a crash), it leaves ``output.partial``: the writer closes its MCAP
chunk and flushes the file at least once a second, and ``hrn-vo recover output.partial``
rewrites every complete chunk as the bag ``output``. ``/diagnostics`` reports the messages
recorded per topic.
"""

from __future__ import annotations

import sys
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node

from hrn_vo_ros.errors import ConfigError
from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.io.nodeconfig import RecorderNodeConfig
from hrn_vo_ros.io.recording import BagRecorder
from hrn_vo_ros.nodes.common import publish_diagnostics, qos
from hrn_vo_ros.nodes.params import declare_config
from hrn_vo_ros.nodes.process import run
from hrn_vo_ros.nodes.stats import NodeStats


class BagRecorderNode(Node):
    """Topics → bag (see the module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('bag_recorder', **kwargs)
        opts = declare_config(self, RecorderNodeConfig).config
        if not opts.output or not opts.topics:
            raise ConfigError('bag_recorder needs the parameters output (a new bag directory) '
                              'and topics (TOPIC:pkg/msg/Type ...)')
        pairs = [tuple(s.split(':', 1)) for s in opts.topics]
        classes = {t: ros_msgs.message_class(m) for t, m in pairs}
        self.recorder = BagRecorder(opts.output, [(t, m) for t, m in pairs],
                                    storage=opts.storage)  # type: ignore[arg-type]
        self.stats = NodeStats()
        for topic, cls in classes.items():
            self.create_subscription(cls, topic, self._callback(topic), qos(opts.depth),
                                     raw=True)
        self._diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.create_timer(opts.diagnostics_period_s, self._on_timer)
        self.get_logger().info(f'recording {len(pairs)} topic(s) into {opts.output}')

    def _callback(self, topic: str) -> Any:
        def on_message(raw: bytes) -> None:
            self.stats.count('recorded ' + topic)
            if not self.recorder.put(topic, time.time_ns(), raw):
                self.stats.reject('queue_full')
        return on_message

    def _on_timer(self) -> None:
        publish_diagnostics(self, self._diag, self.stats, [])

    def destroy_node(self) -> None:
        """Finish the bag before the node goes away."""
        self.recorder.close()
        self.get_logger().info(f'bag written: {dict(self.recorder.written)}')
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Console script ``bag_recorder``."""
    return run(BagRecorderNode, args)


if __name__ == '__main__':
    sys.exit(main())
