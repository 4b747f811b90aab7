"""ROS parameters declared from config dataclasses (nodes/params.py), on real rclpy nodes."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
import math
from pathlib import Path

import pytest
import rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
import yaml

from hrn_vo_ros.core.configbase import nested, param, validate
from hrn_vo_ros.errors import ConfigError
from hrn_vo_ros.io.nodeconfig import PacketizerNodeConfig, ResonatorNodeConfig
from hrn_vo_ros.nodes.params import declare_config, leaf_types


@dataclass(frozen=True, slots=True)
class Inner:
    mu: float = param(0.5, 'a weight', lo=0.0, hi=1.0)
    mode: str = param('fast', 'how', choices=('fast', 'dense'))

    def __post_init__(self) -> None:
        validate(self)


@dataclass(frozen=True, slots=True)
class Demo:
    n: int = param(96, 'a size', lo=1, hi=1000, read_only=True)
    gamma: float = param(0.9, 'update speed', lo=0.0, hi=1.0)
    flag: bool = param(False, 'a switch')
    name: str = param('x', 'a frame id')
    weights: tuple[float, ...] = param((1.0, 2.0), 'some weights', lo=0.0)
    seed: int | None = param(None, 'optional seed')
    inner: Inner = nested(Inner, 'a section')

    def __post_init__(self) -> None:
        validate(self)
        if self.gamma > 0.95 and self.flag:
            raise ConfigError('gamma > 0.95 needs flag = false')


@pytest.fixture
def ros() -> Iterator[None]:
    rclpy.init()
    try:
        yield
    finally:
        rclpy.try_shutdown()


def make(overrides: list[Parameter] | None = None) -> Node:
    return Node('params_probe', parameter_overrides=overrides or [])


@pytest.mark.ros
def test_declared_names_types_ranges_and_defaults(ros: None) -> None:
    node = make()
    params = declare_config(node, Demo)
    assert params.config == Demo()
    assert sorted(params.names) == sorted(leaf_types(Demo))
    assert 'inner.mu' in params.names
    d = node.describe_parameter('gamma')
    assert d.description == 'update speed'
    assert (d.floating_point_range[0].from_value, d.floating_point_range[0].to_value) == (0, 1)
    d = node.describe_parameter('n')
    assert d.read_only and d.integer_range[0].to_value == 1000
    assert 'dense' in node.describe_parameter('inner.mode').description
    assert node.get_parameter('weights').value == [1.0, 2.0]
    assert node.get_parameter('seed').type_ == Parameter.Type.NOT_SET
    node.destroy_node()


@pytest.mark.ros
def test_overrides_build_the_dataclass(ros: None) -> None:
    node = make([Parameter('gamma', value=0.5), Parameter('inner.mode', value='dense'),
                 Parameter('weights', value=[3.0]), Parameter('seed', value=7)])
    cfg = declare_config(node, Demo).config
    assert cfg == Demo(gamma=0.5, inner=Inner(mode='dense'), weights=(3.0,), seed=7)
    node.destroy_node()


@pytest.mark.ros
def test_invalid_start_values_raise_config_error(ros: None) -> None:
    node = make([Parameter('inner.mode', value='slow')])
    with pytest.raises(ConfigError, match='one of fast, dense'):
        declare_config(node, Demo)
    node.destroy_node()


@pytest.mark.ros
def test_run_time_changes_are_validated_by_the_config(ros: None) -> None:
    node = make()
    seen: list[Demo] = []
    params = declare_config(node, Demo, on_change=seen.append)
    ok = node.set_parameters([Parameter('gamma', value=0.25)])[0]
    assert ok.successful and params.config.gamma == 0.25 and seen[-1].gamma == 0.25
    # range from the descriptor
    bad = node.set_parameters([Parameter('gamma', value=1.5)])[0]
    assert not bad.successful and params.config.gamma == 0.25
    # a cross-field rule only the dataclass knows: rejected with its ConfigError message
    node.set_parameters([Parameter('gamma', value=0.99)])
    bad = node.set_parameters([Parameter('flag', value=True)])[0]
    assert not bad.successful and 'gamma > 0.95 needs flag = false' in bad.reason
    bad = node.set_parameters([Parameter('weights', value=[-1.0])])[0]
    assert not bad.successful and 'out of range' in bad.reason
    # structural values are read-only
    bad = node.set_parameters([Parameter('n', value=10)])[0]
    assert not bad.successful and params.config.n == 96
    assert len(seen) == 2
    node.destroy_node()


@pytest.mark.ros
def test_node_configs_declare_together_without_clashes(ros: None) -> None:
    node = make([Parameter('odometry.focal_length_px', value=100.0),
                 Parameter('publish_tf', value=True)])
    res = declare_config(node, ResonatorNodeConfig).config
    assert res.publish_tf and res.odometry.focal_length_px == 100.0
    node.destroy_node()
    node = make()
    assert declare_config(node, PacketizerNodeConfig).config == PacketizerNodeConfig()
    assert math.isinf(node.describe_parameter('log_throttle_s').floating_point_range[0]
                      .to_value) is False
    node.destroy_node()


def _flat(d: dict, prefix: str = '') -> set[str]:
    out: set[str] = set()
    for k, v in d.items():
        out |= _flat(v, f'{prefix}{k}.') if isinstance(v, dict) else {prefix + k}
    return out


PARAMS_FILES = sorted(p for p in (Path(__file__).resolve().parents[2] / 'config').glob('*.yaml')
                      if p.stem != 'ekf_example')     # robot_localization's, not ours
CONFIGS = [p for p in PARAMS_FILES if not p.stem.startswith('live')]  # full dataset configs


@pytest.mark.parametrize('path', CONFIGS, ids=[p.stem for p in CONFIGS])
def test_yaml_keys_are_the_dataclass_fields(path: Path) -> None:
    from hrn_vo_ros.core.configbase import flat_keys
    from hrn_vo_ros.core.events.packet_config import PacketizerConfig
    from hrn_vo_ros.core.hrn.config import ResonatorConfig

    data = yaml.safe_load(path.read_text())
    for node, algo, opts in (('packetizer_node', PacketizerConfig, PacketizerNodeConfig),
                             ('resonator_node', ResonatorConfig, ResonatorNodeConfig)):
        keys = _flat(data[node]['ros__parameters'])
        assert flat_keys(algo) <= keys, f'{node} lacks {sorted(flat_keys(algo) - keys)}'
        extra = keys - flat_keys(algo) - flat_keys(opts)
        assert not extra, f'{node}: unknown keys {sorted(extra)}'


@pytest.mark.ros
@pytest.mark.parametrize('path', PARAMS_FILES, ids=[p.stem for p in PARAMS_FILES])
def test_params_file_declares_the_same_configs_as_yamlconfig(ros: None, path: Path) -> None:
    from hrn_vo_ros.core.events.packet_config import PacketizerConfig
    from hrn_vo_ros.core.hrn.config import ResonatorConfig
    from hrn_vo_ros.io.yamlconfig import load_configs

    want_pk, want_rs = load_configs(path)
    args = ['--ros-args', '--params-file', str(path)]
    node = Node('packetizer_node', cli_args=args)
    assert declare_config(node, PacketizerConfig).config == want_pk
    node.destroy_node()
    node = Node('resonator_node', cli_args=args)
    assert declare_config(node, ResonatorConfig).config == want_rs
    node.destroy_node()
