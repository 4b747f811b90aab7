"""Odometry: estimates, rotations, gyro integration, readout to ROS poses."""
