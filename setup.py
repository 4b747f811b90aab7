"""ament_python build of hrn_vo_ros (colcon on a ROS 2 install, pip on a wheels-only machine)."""

from glob import glob
import os

from setuptools import find_packages, setup

PACKAGE = 'hrn_vo_ros'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'bench', 'bench.*']),
    package_data={PACKAGE: ['py.typed', 'io/msg/*/*.msg']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        (os.path.join('share', PACKAGE), ['package.xml']),
        (os.path.join('share', PACKAGE, 'config'), glob('config/*.yaml')),
        (os.path.join('share', PACKAGE, 'launch'), glob('launch/*.launch.py')),
    ],
    install_requires=['setuptools', 'numpy', 'scipy', 'rosbags>=0.11,<0.12', 'PyYAML'],
    extras_require={'test': ['pytest'], 'plot': ['matplotlib']},
    zip_safe=True,
    maintainer='hrn_vo_ros developers',
    maintainer_email='hrn-vo@example.org',
    description='Event-camera visual odometry with hierarchical resonator networks.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'hrn-vo = hrn_vo_ros.cli.main:main',
            'packetizer_node = hrn_vo_ros.nodes.packetizer_node:main',
            'resonator_node = hrn_vo_ros.nodes.resonator_node:main',
            'loihi_node = hrn_vo_ros.nodes.loihi_node:main',
            'bag_recorder = hrn_vo_ros.nodes.bag_recorder:main',
            'bag_player = hrn_vo_ros.nodes.bag_player:main',
        ],
    },
)
