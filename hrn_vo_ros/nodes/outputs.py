"""The resonator node's outputs: the per-frame readout, pose, odometry and tf messages, the map
images (rate-limited) and the static transforms (``resonator_node``'s module docstring lists
the topics)."""

from __future__ import annotations

from collections.abc import Sequence

from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image, JointState
from tf2_msgs.msg import TFMessage

from hrn_vo_ros.core.clock import RateLimit
from hrn_vo_ros.core.hrn.backends import ResonatorBackend
from hrn_vo_ros.core.live import Step
from hrn_vo_ros.core.odometry.publish import StaticFrame
from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.io.nodeconfig import ResonatorNodeConfig
from hrn_vo_ros.nodes.common import qos


class OdometryOutputs:
    """The publishers of a resonator node (``/tf`` only with ``publish_tf``)."""

    def __init__(self, node: Node, publish_tf: bool) -> None:
        self._node = node
        self._steps = [node.create_publisher(JointState, '~/readout', qos(1000)),
                       node.create_publisher(PoseStamped, '~/pose', qos(1000)),
                       node.create_publisher(Odometry, '~/odom', qos(1000))] + (
            [node.create_publisher(TFMessage, '/tf', 100)] if publish_tf else [])
        self._map = node.create_publisher(Image, '~/map_image', 2)
        self._readout_image = node.create_publisher(Image, '~/readout_image', 2)
        self._image_rate = RateLimit()

    def step(self, step: Step, opts: ResonatorNodeConfig) -> None:
        """The readout, pose, odometry (and tf) messages of one processed frame."""
        for pub, m in zip(self._steps, ros_msgs.step_messages(
                step, opts.odom_frame_id, opts.base_frame_id, opts.camera_frame_id,
                with_tf=len(self._steps) > 3), strict=True):
            pub.publish(m)

    def images(self, t_ns: int, hrn: ResonatorBackend, opts: ResonatorNodeConfig) -> bool:
        """The map images, at most ``map_image_rate_hz``; whether they were published."""
        if not self._image_rate.due(opts.map_image_rate_hz):
            return False
        frame = opts.camera_frame_id
        self._map.publish(ros_msgs.float_image_to_mono8(hrn.map_image(), t_ns, frame))
        self._readout_image.publish(
            ros_msgs.float_image_to_mono8(hrn.egocentric_map_image(), t_ns, frame))
        return True

    def static(self, frames: Sequence[StaticFrame]) -> None:
        """``frames`` on ``/tf_static`` (latched: a transient-local publisher kept open)."""
        self._static = self._node.create_publisher(TFMessage, '/tf_static', QoSProfile(
            depth=1, reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self._static.publish(ros_msgs.static_transforms(
            self._node.get_clock().now().nanoseconds, frames))

    def subscribers(self) -> tuple[int, int]:
        """The fewest subscribers of readout, pose and odometry, and those of the odometry."""
        return (min(p.get_subscription_count() for p in self._steps[:3]),
                self._steps[2].get_subscription_count())
