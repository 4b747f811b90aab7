"""The event-camera simulator (textured scenes, motions, events, IMU, ground truth)."""
