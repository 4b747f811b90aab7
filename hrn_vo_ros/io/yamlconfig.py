"""``config/*.yaml`` (ROS 2 params-file form) → the stage configs.

Layout, also read by ``ros2 launch`` (nested dictionaries become dotted parameter names)::

    packetizer_node:
      ros__parameters:
        <PacketizerConfig fields>            # plus PacketizerNodeConfig fields (node only)
    resonator_node:
      ros__parameters:
        <ResonatorConfig fields, nested sections as nested dictionaries>
        <ResonatorNodeConfig fields>         # node only (frames, rates, odometry, ...)

:func:`load_configs` builds ``PacketizerConfig`` and ``ResonatorConfig`` from such a file; keys
that belong to the node-only configs (or a ``node`` sub-section) are skipped, anything else
unknown is an error naming the file. :func:`dataset_configs` adds what a dataset implies (sensor
size, frame size, focal length), as ``hrn-vo run``, ``hrn-vo graph`` and the benchmarks need it.
"""

from __future__ import annotations

from collections.abc import Mapping
import dataclasses
from pathlib import Path
from typing import Any, get_type_hints

import yaml

from hrn_vo_ros.core.configbase import from_dict
from hrn_vo_ros.core.events.packet_config import PacketizerConfig
from hrn_vo_ros.core.hrn.config import needs_focal, ResonatorConfig, sphere_rectify_problem
from hrn_vo_ros.errors import ConfigError
from hrn_vo_ros.io import ecd
from hrn_vo_ros.io.nodeconfig import PacketizerNodeConfig, ResonatorNodeConfig

PACKETIZER_NODE = 'packetizer_node'
RESONATOR_NODE = 'resonator_node'
SECTIONS = (PACKETIZER_NODE, RESONATOR_NODE, 'loihi_node', 'bag_player', 'bag_recorder', '/**')
"""The top-level sections a params file may have: the package's nodes (``/**`` = every node,
ROS's wildcard); any other name is refused as a misspelling."""
_NODE_ONLY: dict[str, set[str]] = {
    PACKETIZER_NODE: {f.name for f in dataclasses.fields(PacketizerNodeConfig)} | {'node'},
    RESONATOR_NODE: {f.name for f in dataclasses.fields(ResonatorNodeConfig)} | {'node'},
}


@dataclasses.dataclass(frozen=True)
class DatasetConfigs:
    """The stage configs for one dataset and the overrides that give them (for nodes, which
    take the overrides as parameters)."""

    packetizer: PacketizerConfig
    resonator: ResonatorConfig
    packetizer_overrides: dict[str, Any]
    resonator_overrides: dict[str, Any]


def dataset_configs(path: Path | str | None, dataset: Path, *,
                    packetizer: Mapping[str, Any] | None = None,
                    resonator: Mapping[str, Any] | None = None) -> DatasetConfigs:
    """:func:`load_configs` plus what the dataset implies.

    The sensor size (``meta.json`` or the events), the resonator's frame size = the
    packetizer's, and ``focal_px`` = fx / downsample from ``calib.txt`` where the IMU prediction
    or the sphere correction need it and it is unset. Overrides from the caller win over the
    file; the sensor size wins over both.

    Raises:
        ConfigError: as :func:`load_configs`, or for the sphere correction on frames that are
            not equidistant-rectified. DatasetError: for a missing or malformed dataset file.
    """
    width, height = ecd.read_sensor_size(dataset)
    pk = {**(packetizer or {}), 'sensor_width': width, 'sensor_height': height}
    rs = dict(resonator or {})
    pcfg, rcfg = load_configs(path, packetizer=pk, resonator=rs)
    rs.update(width=pcfg.width, height=pcfg.height)
    if needs_focal(rcfg):
        rs['focal_px'] = ecd.read_calib(dataset).fx / pcfg.factor
    pcfg, rcfg = load_configs(path, packetizer=pk, resonator=rs)
    problem = sphere_rectify_problem(pcfg.rectify, rcfg)
    if problem is not None:
        raise ConfigError(problem)
    return DatasetConfigs(pcfg, rcfg, pk, rs)


def load_sections(path: Path | str) -> dict[str, dict[str, Any]]:
    """The ``ros__parameters`` dictionary of every node section of a params file.

    Raises:
        ConfigError: for a missing or unreadable file, or a section without ros__parameters.
    """
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f'{path}: config file not found (see config/*.yaml for examples)')
    try:
        text = path.read_bytes().decode('utf-8')
    except UnicodeDecodeError as err:
        raise ConfigError(f'{path}: not a UTF-8 text file (byte {err.start}); expected a YAML '
                          'params file') from None
    except OSError as err:
        raise ConfigError(f'{path}: cannot read: {err.strerror or err}') from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise ConfigError(f'{path}: not valid YAML: {err}') from None
    except (ValueError, TypeError, RecursionError, OverflowError) as err:
        # e.g. a timestamp or number the YAML resolver cannot convert, nesting too deep
        raise ConfigError(f'{path}: not valid YAML: {type(err).__name__}: {err}') from None
    if not isinstance(data, Mapping):
        raise ConfigError(f'{path}: expected node sections ({PACKETIZER_NODE}:, '
                          f'{RESONATOR_NODE}:) at the top level')
    unknown = [str(k) for k in data if k not in SECTIONS]
    if unknown:
        raise ConfigError(f'{path}: unknown section(s) {", ".join(repr(k) for k in unknown)}; '
                          f'expected {", ".join(SECTIONS)}')
    out: dict[str, dict[str, Any]] = {}
    for node, section in data.items():
        params = section.get('ros__parameters') if isinstance(section, Mapping) else None
        if not isinstance(params, Mapping):
            raise ConfigError(f'{path}: section {node!r} needs a ros__parameters: mapping')
        extra = [str(k) for k in section if k != 'ros__parameters']
        if extra:
            raise ConfigError(f'{path}: section {node!r}: unknown key(s) '
                              f'{", ".join(repr(k) for k in extra)}; expected ros__parameters')
        bad = _non_string_key(params)
        if bad is not None:
            raise ConfigError(f'{path}: section {node!r}: parameter name {bad!r} is not a '
                              'string')
        out[str(node)] = dict(params)
    return out


def _non_string_key(tree: Mapping[Any, Any]) -> object | None:
    """The first key of ``tree`` (nested mappings included) that is not a string, or None."""
    for key, value in tree.items():
        if not isinstance(key, str):
            found: object = key
            return found
        if isinstance(value, Mapping):
            bad = _non_string_key(value)
            if bad is not None:
                return bad
    return None


def algorithm_params(sections: Mapping[str, Mapping[str, Any]], node: str) -> dict[str, Any]:
    """The parameters of ``node`` without its node-only keys."""
    skip = _NODE_ONLY.get(node, {'node'})
    return {k: v for k, v in sections.get(node, {}).items() if k.split('.')[0] not in skip}


def _merge(base: dict[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in overrides.items():
        head, _, rest = key.partition('.')
        if rest:
            sub = out.get(head)
            out[head] = _merge(dict(sub) if isinstance(sub, Mapping) else {}, {rest: value})
        else:
            out[key] = value
    return out


_NODE_CONFIGS: dict[str, type] = {PACKETIZER_NODE: PacketizerNodeConfig,
                                  RESONATOR_NODE: ResonatorNodeConfig}


def _unknown_keys(cls: type[Any], tree: Mapping[str, Any], prefix: str = ''
                  ) -> list[tuple[str, type[Any]]]:
    """``(dotted key, config class)`` of the keys of ``tree`` that are no field of the config
    dataclass ``cls`` (nested sections recursively); values are not checked here."""
    fields = {f.name: f for f in dataclasses.fields(cls)}
    types = get_type_hints(cls)
    out: list[tuple[str, type[Any]]] = []
    for key, value in tree.items():
        f = fields.get(str(key))
        if f is None:
            out.append((f'{prefix}{key}', cls))
        elif f.metadata.get('nested') and isinstance(value, Mapping):
            out += _unknown_keys(types[f.name], value, f'{prefix}{key}.')
    return out


def _check_node_only(sections: Mapping[str, Mapping[str, Any]], source: str) -> None:
    """Refuse unknown keys inside the node-only settings of a params file (e.g. a misspelled
    key of ``odometry:``), which :func:`load_configs` would otherwise skip silently. Their
    values are the nodes' business (ROS reads them), only the names are checked.

    Raises:
        ConfigError: naming the file, the unknown keys and the valid ones.
    """
    for node, cls in _NODE_CONFIGS.items():
        fields = {f.name for f in dataclasses.fields(cls)}
        own = {k: v for k, v in sections.get(node, {}).items() if k.split('.')[0] in fields}
        unknown = _unknown_keys(cls, _merge({}, own))
        if unknown:
            where = unknown[0][1]
            valid = ', '.join(f.name for f in dataclasses.fields(where))
            raise ConfigError(f'{source}: {node}: unknown key(s) '
                              f'{", ".join(k for k, _ in unknown)}; valid {where.__name__} '
                              f'keys: {valid}')


def load_configs(path: Path | str | None, *,
                 packetizer: Mapping[str, Any] | None = None,
                 resonator: Mapping[str, Any] | None = None
                 ) -> tuple[PacketizerConfig, ResonatorConfig]:
    """Build the packetizer and resonator configs from a params file plus overrides.

    Args:
        path: A ``config/*.yaml`` file, or None for the defaults.
        packetizer: Overrides by (dotted) field name, applied after the file.
        resonator: Overrides by (dotted) field name, e.g. ``{'imu.enabled': True}``.

    Raises:
        ConfigError: naming the file for unknown keys, wrong types or invalid values.
    """
    sections = load_sections(path) if path is not None else {}
    source = str(path) if path is not None else 'defaults'
    _check_node_only(sections, source)
    pk = _merge(algorithm_params(sections, PACKETIZER_NODE), packetizer or {})
    rs = _merge(algorithm_params(sections, RESONATOR_NODE), resonator or {})
    try:
        return (from_dict(PacketizerConfig, pk, source=source),
                from_dict(ResonatorConfig, rs, source=source))
    except ConfigError as err:
        msg = str(err) if str(err).startswith(source) else f'{source}: {err}'
        raise ConfigError(msg) from None
