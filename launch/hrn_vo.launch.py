"""Launch the HRN odometry graph: packetizer_node → resonator_node [+ a bag player].

Usage (ROS 2 Jazzy with this package built by colcon, or the tools scripts/setup.sh installs)::

    ros2 launch hrn_vo_ros hrn_vo.launch.py         # any live camera on event_camera/events
    ros2 launch hrn_vo_ros hrn_vo.launch.py dataset:=shapes_rotation focal_px:=79.6
    ros2 launch hrn_vo_ros hrn_vo.launch.py dataset:=shapes_translation use_imu:=true
    ros2 launch hrn_vo_ros hrn_vo.launch.py config:=/path/my.yaml bag:=/path/to/bag
    ros2 launch hrn_vo_ros hrn_vo.launch.py namespace:=cam0 use_sim_time:=true

``ros2 launch hrn_vo_ros hrn_vo.launch.py --show-args`` lists the arguments with their
descriptions. Topic arguments are resolved in the graph's namespace unless absolute; the
resonator always reads the frames of the packetizer in its own namespace. Under a namespace the
parameter sections of the config (``packetizer_node:``, ``resonator_node:``, ``/**:``) apply to
the namespaced nodes.

Machines without ``launch`` start the same graph with ``hrn-vo demo`` (hrn_vo_ros/cli/graph.py).
"""

import atexit
import contextlib
import functools
import os
import tempfile

from ament_index_python.packages import get_package_share_directory
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
import yaml

from launch import LaunchDescription

ARGUMENTS = [
    ('dataset', 'live',
     'name of a parameter file in share/hrn_vo_ros/config (without .yaml); live: any camera '
     'turning, no calibration (shapes_rotation: a calibrated DAVIS240C, waits for CameraInfo)'),
    ('config', '', 'a parameter file path; overrides dataset'),
    ('namespace', '', 'ROS namespace of the nodes (empty: the root namespace)'),
    ('events_topic', 'event_camera/events',
     'the event_camera_msgs/EventPacket topic of the camera driver or bag'),
    ('camera_info_topic', 'event_camera/camera_info',
     'the CameraInfo topic (read when the config rectifies without calib.*, and for the '
     'focal length while focal_px is 0)'),
    ('imu_topic', 'event_camera/imu',
     "the sensor_msgs/Imu topic (used with use_imu:=true; libcaer_driver's, as events_topic; "
     "bag:= remaps a converted bag's /imu to it)"),
    ('use_imu', 'false', 'fuse the gyro (sets imu.enabled of the resonator and the packetizer)'),
    ('focal_px', '0.0',
     'focal length in frame pixels, fx / the downsample factor the packetizer logs (about '
     '79.6 for a DAVIS240C at 2.5), for the IMU prediction, the sphere correction and the '
     "odometry calibration (odometry.focal_length_px); 0: the camera_info's fx / that "
     "factor, or without one the config's values"),
    ('publish_tf', 'false', 'publish odom -> base_link on /tf'),
    ('use_sim_time', 'false',
     'run the nodes on the /clock topic (the bag player of bag:= then publishes it)'),
    ('bag', '', "a ROS 2 bag to replay with this package's bag player (empty: none)"),
    ('rate', '1.0', 'replay rate of the bag player'),
]


def _flag(context, name):
    return LaunchConfiguration(name).perform(context).strip().lower() in ('true', '1', 'yes')


def _merge(into, params):
    """Merge nested parameter dicts (``params`` wins; sub-sections merge key by key)."""
    for key, value in params.items():
        if isinstance(value, dict) and isinstance(into.get(key), dict):
            _merge(into[key], value)
        else:
            into[key] = value
    return into


def _node_params(config, name, namespace, overrides=None):
    """One params file for node ``name``: the sections of ``config`` that apply to it
    (``/**`` first) merged under the node's full name, then ``overrides`` (dotted names).

    ROS matches a section key without a namespace (``packetizer_node:``) only to a node in the
    root namespace, hence one section keyed by the full name. Overrides go into the same file
    rather than to launch_ros as dicts, which it writes to files of its own and never removes;
    this file is removed when the launch process exits.
    """
    doc = {}
    if config:
        with open(config) as f:
            doc = yaml.safe_load(f) or {}
    full = '/' + '/'.join(p for p in (namespace.strip('/'), name) if p)
    params = {}
    for key in ('/**', '/**/' + name, name, '/' + name, full):
        section = doc.get(key) or {}
        _merge(params, section.get('ros__parameters') or {})
    for dotted, value in (overrides or {}).items():
        *path, leaf = dotted.split('.')
        _merge(params, functools.reduce(lambda v, k: {k: v}, reversed(path), {leaf: value}))
    with tempfile.NamedTemporaryFile('w', prefix=f'hrn_vo_{name}_', suffix='.yaml',
                                     delete=False) as out:
        yaml.safe_dump({full: {'ros__parameters': params}}, out)
    # the nodes read it at start-up; the launch process removes it when it exits
    atexit.register(_remove, out.name)
    return out.name


def _remove(path):
    with contextlib.suppress(OSError):
        os.unlink(path)


def _nodes(context, *args, **kwargs):
    share = get_package_share_directory('hrn_vo_ros')
    config = LaunchConfiguration('config').perform(context)
    if not config:
        dataset = LaunchConfiguration('dataset').perform(context)
        config = os.path.join(share, 'config', dataset + '.yaml')
    namespace = LaunchConfiguration('namespace').perform(context)
    sim_time = {'use_sim_time': _flag(context, 'use_sim_time')}
    resonator = {'imu.enabled': _flag(context, 'use_imu'),
                 'publish_tf': _flag(context, 'publish_tf')}
    focal = float(LaunchConfiguration('focal_px').perform(context))
    if focal > 0.0:
        resonator['focal_px'] = focal
        resonator['odometry.focal_length_px'] = focal   # one focal length for every stage
    topic = {name: LaunchConfiguration(name).perform(context)
             for name in ('events_topic', 'camera_info_topic', 'imu_topic')}
    actions = [
        Node(package='hrn_vo_ros', executable='packetizer_node', name='packetizer_node',
             namespace=namespace,
             # use_imu: the packets of a fused gyro (imu.max_frame_ms of the config)
             parameters=[_node_params(config, 'packetizer_node', namespace,
                                      {'imu.enabled': resonator['imu.enabled'], **sim_time})],
             remappings=[('~/events', topic['events_topic']),
                         ('~/camera_info', topic['camera_info_topic'])],
             output='screen'),
        Node(package='hrn_vo_ros', executable='resonator_node', name='resonator_node',
             namespace=namespace,
             parameters=[_node_params(config, 'resonator_node', namespace,
                                      {**resonator, **sim_time})],
             # relative: the packetizer of this namespace
             remappings=[('~/frames', 'packetizer_node/frames'),
                         ('~/imu', topic['imu_topic']),
                         ('~/camera_info', topic['camera_info_topic'])],
             output='screen'),
    ]
    bag = LaunchConfiguration('bag').perform(context)
    if bag:
        rate = float(LaunchConfiguration('rate').perform(context))
        actions.append(Node(package='hrn_vo_ros', executable='bag_player', name='bag_player',
                            namespace=namespace,
                            # with use_sim_time the player publishes /clock (runs on wall time)
                            parameters=[_node_params('', 'bag_player', namespace, {
                                'bag': bag, 'rate': rate, 'wait_for_subscribers': 1,
                                'clock': sim_time['use_sim_time']})],
                            # the drivers' topics, as bags record them, to the graph's inputs
                            remappings=[('/event_camera/events', topic['events_topic']),
                                        ('/event_camera/camera_info',
                                         topic['camera_info_topic']),
                                        ('/imu', topic['imu_topic'])],
                            output='screen'))
    return actions


def generate_launch_description():
    """The launch description: the arguments of ARGUMENTS, then the nodes."""
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=description)
         for name, default, description in ARGUMENTS]
        + [OpaqueFunction(function=_nodes)])
