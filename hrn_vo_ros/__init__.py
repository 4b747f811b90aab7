"""hrn_vo_ros: event-camera visual odometry with hierarchical resonator networks.

Layers (imports only go downwards):

* :mod:`hrn_vo_ros.core` holds every piece of math (numpy/scipy only, no ROS, no bags);
* :mod:`hrn_vo_ros.io` converts messages, reads datasets and writes/reads bags;
* :mod:`hrn_vo_ros.nodes` and :mod:`hrn_vo_ros.cli` are thin ROS nodes and command-line tools.

Time is int64 nanoseconds everywhere inside the package (docs/architecture.md, "Time").
"""

import logging

__version__ = '0.1.0'

logging.getLogger(__name__).addHandler(logging.NullHandler())
