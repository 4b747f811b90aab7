"""Threaded raw-CDR bag recording and reading the readouts back (io/recording.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hrn_vo_ros.errors import BagError, DatasetError
from hrn_vo_ros.io.bags import typestore
from hrn_vo_ros.io.recording import BagRecorder, read_readout_estimates, read_readouts

TOPIC = '/resonator_node/readout'
TS = typestore()


def joint_state(t_ns: int, values: dict[str, float]) -> bytes:
    """CDR of a readout message (rosbags' serialiser: rclpy's pads the end of its buffer)."""
    T = TS.types
    msg = T['sensor_msgs/msg/JointState'](
        header=T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
            sec=t_ns // 10**9, nanosec=t_ns % 10**9), frame_id=''),
        name=list(values), position=np.array(list(values.values()), float),
        velocity=np.array([]), effort=np.array([]))
    return bytes(TS.serialize_cdr(msg, 'sensor_msgs/msg/JointState'))


def test_recorded_readouts_read_back_in_stamp_order(tmp_path: Path) -> None:
    rec = BagRecorder(tmp_path / 'bag', [(TOPIC, 'sensor_msgs/msg/JointState')])
    assert not (tmp_path / 'bag').exists()          # appears only when closed cleanly
    stamps = [30, 10, 20]                              # arrival order differs from stamp order
    for i, t in enumerate(stamps):
        assert rec.put(TOPIC, 1000 + i, joint_state(t, {'h': i, 'v': -i, 'r': 0.5 * i}))
    rec.close()
    assert rec.written[TOPIC] == 3 and not rec.dropped
    t, vals = read_readouts(tmp_path / 'bag', TOPIC)
    assert t.tolist() == [10, 20, 30]
    np.testing.assert_array_equal(vals['h'], [1.0, 2.0, 0.0])
    np.testing.assert_array_equal(vals['r'], [0.5, 1.0, 0.0])
    with pytest.raises(BagError, match='no topic /other'):
        read_readouts(tmp_path / 'bag', '/other')


def test_readouts_with_quality_and_state_codes_read_as_an_estimate_file(tmp_path: Path
                                                                         ) -> None:
    rec = BagRecorder(tmp_path / 'bag', [(TOPIC, 'sensor_msgs/msg/JointState')])
    for i, (q, code) in enumerate([(0.9, 0), (0.4, 1), (0.1, 2)]):
        rec.put(TOPIC, i, joint_state(10 + i, {'h': i, 'v': 0.0, 'r': 0.1 * i, 'quality': q,
                                               'state': code}))
    rec.close()
    ef = read_readout_estimates(tmp_path / 'bag', TOPIC)
    assert ef.series.t.tolist() == [10, 11, 12] and ef.series.z is None
    np.testing.assert_array_equal(ef.series.h, [0.0, 1.0, 2.0])
    assert ef.quality is not None and ef.quality.tolist() == [0.9, 0.4, 0.1]
    assert ef.state == ['tracking', 'degraded', 'lost']
    # an unknown state code is refused, naming the codes
    rec = BagRecorder(tmp_path / 'bad', [(TOPIC, 'sensor_msgs/msg/JointState')])
    rec.put(TOPIC, 0, joint_state(1, {'h': 0.0, 'v': 0.0, 'r': 0.0, 'state': 7}))
    rec.close()
    with pytest.raises(DatasetError, match=r'state code 7\.0 is not one of 0 \(tracking\)'):
        read_readout_estimates(tmp_path / 'bad', TOPIC)
    # older readouts (h, v, r only) read without quality and state
    rec = BagRecorder(tmp_path / 'old', [(TOPIC, 'sensor_msgs/msg/JointState')])
    rec.put(TOPIC, 0, joint_state(1, {'h': 0.0, 'v': 0.0, 'r': 0.0}))
    rec.close()
    old = read_readout_estimates(tmp_path / 'old', TOPIC)
    assert old.quality is None and old.state is None and len(old.series) == 1


def test_refuses_to_overwrite_and_unknown_types(tmp_path: Path) -> None:
    (tmp_path / 'bag').mkdir()
    with pytest.raises(BagError, match='exists'):
        BagRecorder(tmp_path / 'bag', [(TOPIC, 'sensor_msgs/msg/JointState')])
    with pytest.raises(BagError, match='unknown message type'):
        BagRecorder(tmp_path / 'b2', [(TOPIC, 'nope/msg/Nothing')])


def test_a_full_queue_drops_instead_of_blocking(tmp_path: Path) -> None:
    rec = BagRecorder(tmp_path / 'bag', [(TOPIC, 'sensor_msgs/msg/JointState')], max_queue=1)
    raw = joint_state(1, {'h': 0.0})
    results = [rec.put(TOPIC, i, raw) for i in range(2000)]
    rec.close()
    assert rec.dropped[TOPIC] == results.count(False) > 0
    assert rec.written[TOPIC] == results.count(True)
