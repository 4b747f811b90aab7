"""``hrn-vo check BAG`` on a converted bag, a damaged one and inputs that are no bag."""

from __future__ import annotations

from pathlib import Path

import pytest

from hrn_vo_ros.cli.main import main

SEQ = Path(__file__).resolve().parents[1] / 'fixtures' / 'seq1s'


def test_check_a_converted_bag_and_refuse_broken_ones(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]
                                                      ) -> None:
    bag = tmp_path / 'bag'
    assert main(['convert', str(SEQ), str(bag)]) == 0
    capsys.readouterr()
    assert main(['check', str(bag)]) == 0
    out = capsys.readouterr().out
    assert '/event_camera/events: 2048 events decoded' in out
    assert 'matches the stored checksum' in out and f'{bag}: OK (mcap)' in out
    assert '0 MCAP chunk CRCs' not in out
    # not a bag: a dataset folder, a missing path, an unknown topic
    assert main(['check', str(SEQ)]) == 4
    assert 'metadata.yaml' in capsys.readouterr().err
    assert main(['check', str(tmp_path / 'nope')]) == 4
    assert 'does not exist' in capsys.readouterr().err
    assert main(['check', str(bag), '--topic', '/imu']) == 4
    assert '/imu' in capsys.readouterr().err
    # a flipped byte inside the MCAP file is found
    mcap = next(bag.glob('*.mcap'))
    data = bytearray(mcap.read_bytes())
    data[len(data) // 2] ^= 0xFF
    mcap.write_bytes(bytes(data))
    assert main(['check', str(bag)]) in (3, 4)
    assert str(bag) in capsys.readouterr().err
