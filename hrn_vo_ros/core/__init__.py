"""The pure core: all of the math, numpy/scipy and the standard library only.

No module below this package may import rclpy, rosbags or ROS message packages
(``test/test_layering.py`` enforces it).
"""
