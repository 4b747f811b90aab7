"""Thin rclpy nodes: translate messages and parameters, call the core, publish.

A node process spends its first second importing (numpy, scipy, rclpy); a stop signal then
would end it with a KeyboardInterrupt traceback (SIGINT) or killed (SIGTERM), before
``rclpy.init`` and :func:`hrn_vo_ros.nodes.process.run` install their own handling. When this
package is imported on the way to running a node (a node executable, or ``python -m
hrn_vo_ros.nodes.<node>``), both signals end the process at once with exit 0 until then:
nothing has started, so there is nothing to clean up. Importing it anywhere else (tests, the
CLI) changes no signal handling.
"""

import os
import signal
import sys
from types import FrameType

NODE_EXECUTABLES = ('packetizer_node', 'resonator_node', 'loihi_node', 'bag_recorder',
                    'bag_player')


def _exit_during_start_up(signum: int, frame: FrameType | None) -> None:
    os._exit(0)


def _starting_a_node() -> bool:
    exe = os.path.basename(sys.argv[0]) if sys.argv else ''
    # ``python -m hrn_vo_ros.nodes.X`` imports this package while argv[0] is still '-m'
    return exe in NODE_EXECUTABLES or exe == '-m'


if _starting_a_node():
    for _sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(_sig, _exit_during_start_up)
