"""loihi_node as a real rclpy node over DDS: odometry, spike raster and Loihi accounting."""

from __future__ import annotations

from collections.abc import Callable

from diagnostic_msgs.msg import DiagnosticArray
from hrn_synth import event_frame, random_scene
from nav_msgs.msg import Odometry
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from ros_helpers import spin_until
from sensor_msgs.msg import Image

from hrn_vo_ros.io import ros_msgs
from hrn_vo_ros.nodes.common import qos
from hrn_vo_ros.nodes.loihi_node import LoihiNode

pytestmark = pytest.mark.ros


def test_loihi_node_publishes_odometry_raster_and_accounting() -> None:
    rclpy.init()
    steps = 16
    node = LoihiNode(parameter_overrides=[
        Parameter('diagnostics_period_s', value=0.2), Parameter('map_image_rate_hz', value=50.0),
        Parameter('backend.name', value='float'),          # the preset wins: still spiking
        Parameter('backend.spiking.steps_per_cycle', value=steps)])
    probe = Node('loihi_probe')
    odoms: list[Odometry] = []
    rasters: list[Image] = []
    diags: dict[str, dict[str, str]] = {}

    def on_diag(msg: DiagnosticArray) -> None:
        diags[msg.status[0].name.split(':')[0]] = ros_msgs.diagnostic_values(msg)

    pub = probe.create_publisher(Image, '/loihi_node/frames', qos(100))
    probe.create_subscription(Odometry, '/loihi_node/odom', odoms.append, qos(1000))
    probe.create_subscription(Image, '/loihi_node/spike_raster', rasters.append, 10)
    probe.create_subscription(DiagnosticArray, '/diagnostics', on_diag, 100)
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    ex.add_node(probe)

    def wait(cond: Callable[[], bool], timeout: float = 15.0) -> bool:
        return spin_until(ex, cond, timeout)

    try:
        assert node.get_parameter('backend.name').value == 'spiking'
        assert wait(lambda: pub.get_subscription_count() > 0)
        rng = np.random.default_rng(0)
        scene = random_scene(rng)
        n = 12
        for i in range(n):
            img = event_frame(scene, (0.3 * i, 0.0, 0.0, 0.0), rng)
            pub.publish(ros_msgs.frame_to_image(img, 1_000_000_000 + i * 5_000_000,
                                                'cam'))
            ex.spin_once(timeout_sec=0.01)
        assert wait(lambda: len(odoms) == n and len(rasters) > 0
                    and 'loihi_synops' in diags.get('loihi_node', {}))
        raster = rasters[-1]
        # h, v, r populations: the canvas (4/3 of 96x72) and the roll codebook
        assert raster.width == steps and raster.height == 2 * (128 + 96 + 192)
        d = diags['loihi_node']
        assert float(d['loihi_synops']) > float(d['loihi_spikes']) > 0
        assert float(d['loihi_energy_uJ']) > 0 and float(d['loihi_time_us']) > 0
    finally:
        node.destroy_node()
        probe.destroy_node()
        rclpy.try_shutdown()
