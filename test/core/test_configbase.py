"""Config values as they enter from YAML files and ROS parameters (core/configbase.py):
coerced to the field's type or refused with the field's name."""

from __future__ import annotations

import pytest

from hrn_vo_ros.core.configbase import describe, from_dict
from hrn_vo_ros.core.events.packet_config import PacketizerConfig
from hrn_vo_ros.core.hrn.config import ResonatorConfig
from hrn_vo_ros.errors import ConfigError


@pytest.mark.parametrize(('cls', 'key', 'value', 'message'), [
    (PacketizerConfig, 'events_per_frame', '2000', 'expected an integer'),
    (PacketizerConfig, 'events_per_frame', True, 'expected an integer'),
    (PacketizerConfig, 'events_per_frame', 2000.0, 'expected an integer'),
    (PacketizerConfig, 'events_per_frame', 0, 'out of range'),
    (ResonatorConfig, 'max_fill', '0.3', 'expected a number'),
    (ResonatorConfig, 'max_fill', False, 'expected a number'),
    (ResonatorConfig, 'max_fill', 1.5, 'out of range'),
    (PacketizerConfig, 'refill', 1, 'expected true or false'),
    (PacketizerConfig, 'rectify', 3, 'expected a string'),
    (PacketizerConfig, 'rectify', 'fisheye', 'is not one of'),
    (PacketizerConfig, 'calib.dist', 0.1, 'expected a list'),
    (PacketizerConfig, 'calib.dist', [0.1, True, 0.0, 0.0, 0.0], 'expected a number'),
])
def test_values_of_the_wrong_type_or_range_are_refused_by_name(
        cls: type, key: str, value: object, message: str) -> None:
    with pytest.raises(ConfigError, match=message) as info:
        from_dict(cls, {key: value}, source='my.yaml')
    assert key.split('.')[-1] in str(info.value)


def test_values_are_coerced_to_the_field_types() -> None:
    """An integer for a float field becomes a float; a list for a tuple field a tuple of
    floats; the bounds themselves are inside."""
    cfg = from_dict(ResonatorConfig, {'max_fill': 1})
    assert cfg.max_fill == 1.0 and isinstance(cfg.max_fill, float)
    pk = from_dict(PacketizerConfig, {'calib.dist': [0, 1, 0, 0, 0], 'events_per_frame': 1})
    assert pk.calib.dist == (0.0, 1.0, 0.0, 0.0, 0.0)
    assert all(isinstance(v, float) for v in pk.calib.dist) and pk.events_per_frame == 1
    assert from_dict(ResonatorConfig, {'max_fill': 0.0}).max_fill == 0.0


def test_describe_lists_read_only_parameters() -> None:
    """Parameters are writable at run time unless marked read-only (a size that rebuilds the
    network is)."""
    info = {p.name: p for p in describe(ResonatorConfig)}
    assert info['logpolar.n_theta'].read_only and not info['max_fill'].read_only
