"""Codecs of ``event_camera_msgs/msg/EventPacket`` payloads, one module per encoding.

:mod:`hrn_vo_ros.io.eventpacket` is the public entry point (dispatch on the encoding name and
re-exports); these modules hold the vectorised numpy decoders themselves.
"""
