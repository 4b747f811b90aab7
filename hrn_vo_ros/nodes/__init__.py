"""Thin rclpy nodes: translate messages and parameters, call the core, publish."""
