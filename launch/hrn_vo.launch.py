"""Launch the HRN odometry graph: packetizer_node → resonator_node [+ a bag player].

Usage (ROS 2 Jazzy with this package built by colcon)::

    ros2 launch hrn_vo_ros hrn_vo.launch.py         # a live camera on /event_camera/events
    ros2 launch hrn_vo_ros hrn_vo.launch.py dataset:=shapes_translation use_imu:=true
    ros2 launch hrn_vo_ros hrn_vo.launch.py config:=/path/my.yaml bag:=/path/to/bag

Arguments:
    dataset: name of a parameter file in share/hrn_vo_ros/config (without .yaml).
    config: a parameter file path; overrides ``dataset``.
    events_topic: the EventPacket topic of the camera driver or bag.
    camera_info_topic: the CameraInfo topic (read when the config rectifies without calib.*).
    imu_topic: the sensor_msgs/Imu topic (used with use_imu:=true).
    use_imu: fuse the gyro (sets the resonator's ``imu.enabled``).
    focal_px: focal length in frame pixels, fx / downsample (about 79.6 for a DAVIS240C at 2.5),
        for the IMU prediction and the sphere correction of shapes_rotation; 0 keeps the
        config's value (without one the resonator node runs without the sphere correction).
    publish_tf: publish odom → base_link on /tf.
    bag: a ROS 2 bag to replay with this package's bag player (empty: none).
    rate: replay rate of the bag player.

Machines without ``launch`` start the same graph with ``hrn-vo demo`` (hrn_vo_ros/cli/graph.py).
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from launch import LaunchDescription


def _nodes(context, *args, **kwargs):
    share = get_package_share_directory('hrn_vo_ros')
    config = LaunchConfiguration('config').perform(context)
    if not config:
        dataset = LaunchConfiguration('dataset').perform(context)
        config = os.path.join(share, 'config', dataset + '.yaml')
    use_imu = LaunchConfiguration('use_imu').perform(context).lower() == 'true'
    publish_tf = LaunchConfiguration('publish_tf').perform(context).lower() == 'true'
    events_topic = LaunchConfiguration('events_topic').perform(context)
    camera_info_topic = LaunchConfiguration('camera_info_topic').perform(context)
    imu_topic = LaunchConfiguration('imu_topic').perform(context)
    bag = LaunchConfiguration('bag').perform(context)
    resonator = {'imu.enabled': use_imu, 'publish_tf': publish_tf}
    focal = float(LaunchConfiguration('focal_px').perform(context))
    if focal > 0.0:
        resonator['focal_px'] = focal
    actions = [
        Node(package='hrn_vo_ros', executable='packetizer_node', name='packetizer_node',
             parameters=[config], remappings=[('~/events', events_topic),
                                                      ('~/camera_info', camera_info_topic)],
             output='screen'),
        Node(package='hrn_vo_ros', executable='resonator_node', name='resonator_node',
             parameters=[config, resonator],
             remappings=[('~/frames', '/packetizer_node/frames'), ('~/imu', imu_topic)],
             output='screen'),
    ]
    if bag:
        rate = LaunchConfiguration('rate').perform(context)
        actions.append(Node(package='hrn_vo_ros', executable='bag_player', name='bag_player',
                            parameters=[{'bag': bag, 'rate': float(rate),
                                         'wait_for_subscribers': 1}], output='screen'))
    return actions


def generate_launch_description():
    """The launch description (arguments documented in the module docstring)."""
    return LaunchDescription([
        DeclareLaunchArgument('dataset', default_value='shapes_rotation'),
        DeclareLaunchArgument('config', default_value=''),
        DeclareLaunchArgument('events_topic', default_value='/event_camera/events'),
        DeclareLaunchArgument('camera_info_topic', default_value='/event_camera/camera_info'),
        DeclareLaunchArgument('imu_topic', default_value='/imu'),
        DeclareLaunchArgument('use_imu', default_value='false'),
        DeclareLaunchArgument('focal_px', default_value='0.0'),
        DeclareLaunchArgument('publish_tf', default_value='false'),
        DeclareLaunchArgument('bag', default_value=''),
        DeclareLaunchArgument('rate', default_value='1.0'),
        OpaqueFunction(function=_nodes),
    ])
