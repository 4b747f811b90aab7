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
unknown is an error naming the file.
"""

from __future__ import annotations

from collections.abc import Mapping
import dataclasses
from pathlib import Path
from typing import Any

import yaml

from hrn_vo_ros.core.configbase import from_dict
from hrn_vo_ros.core.frames import PacketizerConfig
from hrn_vo_ros.core.hrn import ResonatorConfig
from hrn_vo_ros.core.nodeconfig import PacketizerNodeConfig, ResonatorNodeConfig
from hrn_vo_ros.errors import ConfigError

PACKETIZER_NODE = 'packetizer_node'
RESONATOR_NODE = 'resonator_node'
_NODE_ONLY: dict[str, set[str]] = {
    PACKETIZER_NODE: {f.name for f in dataclasses.fields(PacketizerNodeConfig)} | {'node'},
    RESONATOR_NODE: {f.name for f in dataclasses.fields(ResonatorNodeConfig)} | {'node'},
}


def load_sections(path: Path | str) -> dict[str, dict[str, Any]]:
    """The ``ros__parameters`` dictionary of every node section of a params file.

    Raises:
        ConfigError: for a missing or unreadable file, or a section without ros__parameters.
    """
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f'{path}: config file not found (see config/*.yaml for examples)')
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as err:
        raise ConfigError(f'{path}: not valid YAML: {err}') from None
    if not isinstance(data, Mapping):
        raise ConfigError(f'{path}: expected node sections ({PACKETIZER_NODE}:, '
                          f'{RESONATOR_NODE}:) at the top level')
    out: dict[str, dict[str, Any]] = {}
    for node, section in data.items():
        params = section.get('ros__parameters') if isinstance(section, Mapping) else None
        if not isinstance(params, Mapping):
            raise ConfigError(f'{path}: section {node!r} needs a ros__parameters: mapping')
        out[str(node)] = dict(params)
    return out


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
    pk = _merge(algorithm_params(sections, PACKETIZER_NODE), packetizer or {})
    rs = _merge(algorithm_params(sections, RESONATOR_NODE), resonator or {})
    try:
        return (from_dict(PacketizerConfig, pk, source=source),
                from_dict(ResonatorConfig, rs, source=source))
    except ConfigError as err:
        msg = str(err) if str(err).startswith(source) else f'{source}: {err}'
        raise ConfigError(msg) from None
