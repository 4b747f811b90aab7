"""Real ROS 2 smoke tests: two processes over Fast DDS on localhost, and the built type hashes."""

from __future__ import annotations

import json
import os
from pathlib import Path
import subprocess
import sys

import pytest

HERE = Path(__file__).resolve().parents[1]

# Official Jazzy RIHS01 hashes (of the Jazzy message definitions; the tf2_msgs one as rosbags
# computes it for its Jazzy typestore).
OFFICIAL_HASHES = {
    'event_camera_msgs/msg/EventPacket':
        'RIHS01_d6fa176260b1f37e5a40845305315e150a0f18191241eb64f407442aa29844aa',
    'tf2_msgs/msg/TFMessage':
        'RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087',
    'dvs_msgs/msg/EventArray':
        'RIHS01_0ea4aa5f4670adab1336550158b2e3c9bf60fe515a284c4215ed605bd559c995',
}


def run_pair(talker_domain: str, listener_domain: str,
             seconds: float = 15.0) -> subprocess.CompletedProcess[str]:
    script = str(HERE / 'ros_helpers' / 'smoke_peer.py')
    env_t = {**os.environ, 'ROS_DOMAIN_ID': talker_domain}
    env_l = {**os.environ, 'ROS_DOMAIN_ID': listener_domain}
    listener = subprocess.Popen([sys.executable, script, 'listener', str(seconds)], env=env_l,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    talker = subprocess.Popen([sys.executable, script, 'talker', str(seconds + 2)], env=env_t,
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    out, err = listener.communicate(timeout=seconds + 30)
    talker.terminate()
    talker.wait(timeout=10)
    return subprocess.CompletedProcess(listener.args, listener.returncode, out, err)


@pytest.mark.ros
def test_event_packet_and_odometry_cross_processes() -> None:
    domain = os.environ['ROS_DOMAIN_ID']
    result = run_pair(domain, domain)
    assert result.returncode == 0, f'listener failed: {result.stdout} {result.stderr[-2000:]}'
    got = json.loads(result.stdout.strip().splitlines()[-1])
    assert got['events']['x'] == [1, 239, 17, 100]
    assert got['events']['dt'][-1] == 4_000_000_000
    assert got['odom']['q'] == [0.0, 0.0, 0.6, 0.8]


@pytest.mark.ros
def test_no_message_across_domains_fails() -> None:
    """The smoke test can fail: a talker on another domain delivers nothing."""
    domain = int(os.environ['ROS_DOMAIN_ID'])
    other = str(domain + 100 if domain < 100 else domain - 100)
    result = run_pair(other, str(domain), seconds=4.0)
    assert result.returncode == 1
    assert json.loads(result.stdout.strip().splitlines()[-1]) == {}


@pytest.mark.ros
def test_built_interfaces_have_the_official_type_hashes() -> None:
    import importlib

    import rclpy
    from rclpy.node import Node

    rclpy.init()
    try:
        node = Node('hash_probe')
        for full, want in OFFICIAL_HASHES.items():
            pkg, _, name = full.split('/')
            msg_type = getattr(importlib.import_module(f'{pkg}.msg'), name)
            topic = 'hash_probe/' + name.lower()
            node.create_publisher(msg_type, topic, 1)
            info = node.get_publishers_info_by_topic(topic)
            assert str(info[0].topic_type_hash) == want, full
        node.destroy_node()
    finally:
        rclpy.try_shutdown()
