"""ROS parameters declared from a core config dataclass, and the dataclass built back from them.

One frozen config dataclass (:mod:`hrn_vo_ros.core.configbase`) is the single source of truth:
every leaf field becomes one parameter (nested sections as dotted names, ``map.mu1``) with a
``ParameterDescriptor`` carrying its description, its numeric range and ``read_only`` for
structural fields. Values from ``--params-file``/``-p`` override the defaults as usual. A change
of a tunable at run time is validated by constructing a new config; a :class:`ConfigError` rejects
it with its message, so ``ros2 param set`` prints what to change.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
import dataclasses
import math
import types
import typing
from typing import Any, Generic, TypeVar

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.exceptions import ParameterException, ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter

from hrn_vo_ros.core import configbase
from hrn_vo_ros.errors import ConfigError

C = TypeVar('C')

INT64_MIN, INT64_MAX = -2**63, 2**63 - 1


def leaf_types(cls: type[Any], prefix: str = '') -> dict[str, Any]:
    """The annotated type of every leaf field of config ``cls``, by dotted name."""
    hints = typing.get_type_hints(cls)
    out: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        if f.metadata.get('nested'):
            out.update(leaf_types(hints[f.name], prefix + f.name + '.'))
        else:
            out[prefix + f.name] = hints[f.name]
    return out


def _ros_type(typ: Any) -> Parameter.Type:
    """The ROS parameter type for an annotated field type (Optional unwrapped)."""
    origin = typing.get_origin(typ)
    if origin in (typing.Union, types.UnionType):
        members = [a for a in typing.get_args(typ) if a is not type(None)]
        return _ros_type(members[0])
    if origin is tuple:
        elem = (typing.get_args(typ) or (float,))[0]
        arrays = {bool: Parameter.Type.BOOL_ARRAY, int: Parameter.Type.INTEGER_ARRAY,
                  float: Parameter.Type.DOUBLE_ARRAY, str: Parameter.Type.STRING_ARRAY}
        return arrays[elem]
    scalars = {bool: Parameter.Type.BOOL, int: Parameter.Type.INTEGER,
               float: Parameter.Type.DOUBLE, str: Parameter.Type.STRING}
    return scalars[typ]


def descriptor_for(info: configbase.ParamInfo, typ: Any) -> ParameterDescriptor:
    """The ``ParameterDescriptor`` of one config leaf: description, range, read-only flag."""
    ptype = _ros_type(typ)
    text = info.doc
    if info.choices:
        text += f' (one of: {", ".join(info.choices)})'
    desc = ParameterDescriptor(name=info.name, type=ptype.value, description=text,
                               read_only=info.read_only)
    if info.choices:
        desc.additional_constraints = 'one of: ' + ', '.join(info.choices)
    if info.lo is not None or info.hi is not None:
        if ptype is Parameter.Type.DOUBLE:
            lo = -math.inf if info.lo is None else float(info.lo)
            hi = math.inf if info.hi is None else float(info.hi)
            desc.floating_point_range = [FloatingPointRange(from_value=lo, to_value=hi, step=0.0)]
        elif ptype is Parameter.Type.INTEGER:
            lo_i = INT64_MIN if info.lo is None else math.ceil(info.lo)
            hi_i = INT64_MAX if info.hi is None else math.floor(info.hi)
            desc.integer_range = [IntegerRange(from_value=lo_i, to_value=hi_i, step=0)]
        else:  # arrays: ROS ranges are scalar only; the on-set callback checks every element
            desc.additional_constraints = (
                f'every element in [{info.lo}, {info.hi}]'
                if not desc.additional_constraints else desc.additional_constraints)
    return desc


def _plain(value: Any) -> Any:
    """A parameter value as configbase.from_dict expects it (arrays as lists)."""
    if value is None or isinstance(value, bool | int | float | str):
        return value
    return list(value)


def _ros_default(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value


class ConfigParameters(Generic[C]):
    """The parameters of one config dataclass on a node, and the config built from them.

    Args:
        node: The node that declares the parameters.
        cls: A config dataclass made with :func:`configbase.param`.
        prefix: A name prefix (``'odometry.'``) if the fields should not be top-level.
        on_change: Called with the new config after a tunable changed at run time.

    Raises:
        ConfigError: if the values given at start-up (params file, ``-p``) are invalid.
    """

    def __init__(self, node: Node, cls: type[C], *, prefix: str = '',
                 on_change: Callable[[C], None] | None = None) -> None:
        self._node = node
        self._cls = cls
        self._prefix = prefix
        self._on_change = on_change
        typs = self._types = leaf_types(cls)
        infos = list(configbase.describe(cls))
        self.names = [prefix + i.name for i in infos]
        for info in infos:
            typ = typs[info.name]
            desc = descriptor_for(info, typ)
            if info.default is None:  # Optional without a value: dynamically typed NOT_SET
                desc.type = Parameter.Type.NOT_SET.value
                desc.dynamic_typing = True
            value: Any = _ros_default(info.default)
            if value == []:  # an empty list has no element type: declare the type instead
                value = _ros_type(typ)
            try:
                node.declare_parameter(prefix + info.name, value, desc)
            except ParameterException as err:
                raise ConfigError(f'parameter {prefix + info.name}: {err}') from err
        self.config: C = self.build(self.current_values())
        node.add_on_set_parameters_callback(self._validate)
        node.add_post_set_parameters_callback(self._apply)

    def current_values(self) -> dict[str, Any]:
        """The node's current values of these parameters, by field name (dotted, no prefix)."""
        n = len(self._prefix)
        out = {}
        for name in self.names:
            try:
                value = self._node.get_parameter(name).value
            except ParameterUninitializedException:
                value = None
            if value is None and self._types[name[n:]] is not None and typing.get_origin(
                    self._types[name[n:]]) is tuple:
                value = []  # declared by type (empty default) and not set
            out[name[n:]] = _plain(value)
        return out

    def build(self, values: dict[str, Any]) -> C:
        """The config for ``values`` (ConfigError if invalid)."""
        return configbase.from_dict(self._cls, values, source=f'node {self._node.get_name()}')

    def _changed(self, params: Iterable[Parameter]) -> dict[str, Any]:
        n = len(self._prefix)
        return {p.name[n:]: _plain(p.value) for p in params if p.name in self.names}

    def _validate(self, params: list[Parameter]) -> SetParametersResult:
        changed = self._changed(params)
        if not changed:
            return SetParametersResult(successful=True)
        try:
            self.build({**self.current_values(), **changed})
        except ConfigError as err:
            return SetParametersResult(successful=False, reason=str(err))
        return SetParametersResult(successful=True)

    def _apply(self, params: list[Parameter]) -> None:
        if not self._changed(params):
            return
        self.config = self.build(self.current_values())
        if self._on_change is not None:
            self._on_change(self.config)


def declare_config(node: Node, cls: type[C], *, prefix: str = '',
                   on_change: Callable[[C], None] | None = None) -> ConfigParameters[C]:
    """Declare ``cls``'s parameters on ``node``; see :class:`ConfigParameters`."""
    return ConfigParameters(node, cls, prefix=prefix, on_change=on_change)
