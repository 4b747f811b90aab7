"""One frozen dataclass per stage is the single source of truth for configuration.

A stage config is a ``@dataclass(frozen=True, slots=True)`` whose fields are made with
:func:`param`, which records a one-line description, an optional numeric range, allowed choices and
whether the value is structural (read-only once a node runs). The same metadata drives:

* validation (:func:`validate`, called from each config's ``__post_init__``),
* YAML files (``config/*.yaml``, read by :func:`from_dict` after the I/O layer parsed them),
* declared ROS parameters (the node helper walks :func:`describe`).

Nested stage configs are allowed (a field whose type is another config dataclass); they flatten to
dotted names (``map.mu1``), which is how ROS 2 parameters nest YAML dictionaries.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
import dataclasses
from dataclasses import dataclass
import types
import typing
from typing import Any, TypeVar

from hrn_vo_ros.errors import ConfigError

C = TypeVar('C')

Scalar = bool | int | float | str


@dataclass(frozen=True, slots=True)
class ParamInfo:
    """Description of one leaf parameter, as a node declares it."""

    name: str
    default: Any
    doc: str
    lo: float | None
    hi: float | None
    choices: tuple[str, ...] | None
    read_only: bool


def param(default: Any, doc: str, *, lo: float | None = None, hi: float | None = None,
          choices: tuple[str, ...] | None = None, read_only: bool = False) -> Any:
    """A config field with its description and constraints.

    Args:
        default: The default value (immutable: use tuples for sequences).
        doc: One line saying what the value means, with its unit.
        lo: Inclusive lower bound for numbers.
        hi: Inclusive upper bound for numbers.
        choices: Allowed strings.
        read_only: Structural value that cannot change while a node runs.
    """
    meta = {'doc': doc, 'lo': lo, 'hi': hi, 'choices': choices, 'read_only': read_only}
    return dataclasses.field(default=default, metadata=meta)


def nested(factory: type[Any], doc: str) -> Any:
    """A field holding a nested stage config (default-constructed)."""
    return dataclasses.field(default_factory=factory, metadata={'doc': doc, 'nested': True})


def _field_types(cls: type[Any]) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def validate(cfg: Any) -> None:
    """Check every field of ``cfg`` against its range and choices.

    Raises:
        ConfigError: naming the field, the bad value and the allowed values.
    """
    name = type(cfg).__name__
    for f in dataclasses.fields(cfg):
        value = getattr(cfg, f.name)
        meta = f.metadata
        if meta.get('nested'):
            continue
        choices = meta.get('choices')
        if choices is not None and value not in choices:
            msg = f'{name}.{f.name} = {value!r} is not one of {", ".join(choices)}'
            raise ConfigError(msg)
        values: tuple[Any, ...] = value if isinstance(value, tuple) else (value,)
        for v in values:
            if isinstance(v, bool) or not isinstance(v, int | float):
                continue
            lo, hi = meta.get('lo'), meta.get('hi')
            if v != v or (lo is not None and v < lo) or (hi is not None and v > hi):
                msg = (f'{name}.{f.name} = {value!r} is out of range '
                       f'[{"-inf" if lo is None else lo}, {"inf" if hi is None else hi}]')
                raise ConfigError(msg)


def _coerce(value: Any, typ: Any, where: str) -> Any:
    """Convert a YAML/ROS value to the annotated field type, or raise ConfigError."""
    origin = typing.get_origin(typ)
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ConfigError(f'{where}: expected a list, got {value!r}')
        args = typing.get_args(typ)
        elem = args[0] if args else float
        return tuple(_coerce(v, elem, where) for v in value)
    if origin in (typing.Union, types.UnionType):
        members = [a for a in typing.get_args(typ) if a is not type(None)]
        if value is None:
            return None
        return _coerce(value, members[0], where)
    if typ is bool:
        if not isinstance(value, bool):
            raise ConfigError(f'{where}: expected true or false, got {value!r}')
        return value
    if typ is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f'{where}: expected an integer, got {value!r}')
        return value
    if typ is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f'{where}: expected a number, got {value!r}')
        return float(value)
    if typ is str:
        if not isinstance(value, str):
            raise ConfigError(f'{where}: expected a string, got {value!r}')
        return value
    return value


def from_dict(cls: type[C], data: Mapping[str, Any], *, source: str = '') -> C:
    """Build config ``cls`` from a (possibly nested or dotted) mapping, defaults elsewhere.

    Args:
        cls: A stage config dataclass.
        data: Values by field name; nested configs as dicts or dotted keys (``map.mu1``).
        source: Where the values came from, for error messages (a file name).

    Raises:
        ConfigError: on unknown keys (listing the valid ones) or values of the wrong type.
    """
    prefix = f'{source}: ' if source else ''
    tree: dict[str, Any] = {}
    for key, value in data.items():
        head, _, rest = key.partition('.')
        if rest:
            tree.setdefault(head, {})
            if not isinstance(tree[head], dict):
                raise ConfigError(f'{prefix}{head} is given both as a value and as a section')
            tree[head][rest] = value
        elif isinstance(value, Mapping) and head in tree:
            tree[head].update(value)
        else:
            tree[head] = value
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    types = _field_types(cls)
    unknown = sorted(set(tree) - set(fields))
    if unknown:
        msg = (f'{prefix}unknown {cls.__name__} key(s) {", ".join(unknown)}; '
               f'valid keys: {", ".join(fields)}')
        raise ConfigError(msg)
    kwargs: dict[str, Any] = {}
    for key, value in tree.items():
        f = fields[key]
        where = f'{prefix}{cls.__name__}.{key}'
        if f.metadata.get('nested'):
            if not isinstance(value, Mapping):
                raise ConfigError(f'{where}: expected a section (mapping), got {value!r}')
            kwargs[key] = from_dict(types[key], value, source=source)
        else:
            kwargs[key] = _coerce(value, types[key], where)
    return cls(**kwargs)


def to_dict(cfg: Any) -> dict[str, Any]:
    """The config as a nested dict of plain values (tuples become lists), e.g. for YAML."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(cfg):
        value = getattr(cfg, f.name)
        if f.metadata.get('nested'):
            out[f.name] = to_dict(value)
        elif isinstance(value, tuple):
            out[f.name] = list(value)
        else:
            out[f.name] = value
    return out


def describe(cls_or_cfg: Any, prefix: str = '') -> Iterator[ParamInfo]:
    """Every leaf parameter of a config class or instance, with dotted names."""
    cfg = cls_or_cfg if not isinstance(cls_or_cfg, type) else cls_or_cfg()
    for f in dataclasses.fields(cfg):
        value = getattr(cfg, f.name)
        meta = f.metadata
        if meta.get('nested'):
            yield from describe(value, prefix + f.name + '.')
            continue
        yield ParamInfo(name=prefix + f.name, default=value, doc=meta.get('doc', ''),
                        lo=meta.get('lo'), hi=meta.get('hi'), choices=meta.get('choices'),
                        read_only=bool(meta.get('read_only', False)))


def flat_keys(cls: type[Any]) -> set[str]:
    """The dotted names of all leaf parameters of ``cls``."""
    return {p.name for p in describe(cls)}
