"""The nodes' note log (nodes/common.py NoteLog) on a real rclpy node, in its own process:
what reaches the log, how often, and what is counted."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.ros

SCRIPT = """
import rclpy
from rclpy.node import Node
from hrn_vo_ros.core.events.stream import Note
from hrn_vo_ros.nodes.common import NoteLog
from hrn_vo_ros.nodes.stats import NodeStats

rclpy.init()
node = Node('notes_probe')
stats = NodeStats()
log = NoteLog(node, stats, lambda: 60.0)
for i in range(3):
    log(Note('warn', 'clock', f'throttled warning {i}', throttled=True))
    log(Note('warn', 'focal', f'plain warning {i}'))
    log(Note('reject', 'decode', f'bad packet {i}'))
log(Note('warn', 'frame_size', 'another kind, throttled', throttled=True))
log(Note('info', 'calib', 'an info line'))
print('counted', dict(stats.bad), flush=True)
node.destroy_node()
rclpy.shutdown()
"""


def test_throttled_notes_once_per_kind_plain_ones_always_rejects_counted() -> None:
    proc = subprocess.run([sys.executable, '-c', SCRIPT], capture_output=True, text=True,
                          timeout=60, env=dict(os.environ, PYTHONUNBUFFERED='1'))
    assert proc.returncode == 0, proc.stderr[-2000:]
    err = proc.stderr
    assert 'throttled warning 0' in err and 'throttled warning 1' not in err
    assert all(f'plain warning {i}' in err for i in range(3))
    assert 'another kind, throttled' in err                 # its own throttle per kind
    assert '[INFO]' in err.split('an info line')[0].splitlines()[-1]
    # rejects: each counted, logged once per period (rclpy's throttle)
    assert "counted {'decode': 3}" in proc.stdout
    assert 'dropped a message (decode, 1 so far): bad packet 0' in err
    assert 'bad packet 1' not in err and 'bad packet 2' not in err
