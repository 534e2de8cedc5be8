"""Test-time control settings given as NAME=VALUE on a command line (--control-set), for choosing them on val."""
from __future__ import annotations


def control_config_from(settings: list[str]):
    """A ControlConfig with NAME=VALUE overrides (None without any): ValueError naming a bad one."""
    if not settings:
        return None
    from ..control import ControlConfig     # here, not at the top: a command's --help needs no PyTorch
    from ..errors import InputError
    fields = ControlConfig.__dataclass_fields__
    values = {}
    for kv in settings:
        name, sep, value = kv.partition("=")
        if not sep or name not in fields:
            raise ValueError(f"--control-set {kv!r}: give NAME=VALUE with NAME one of {', '.join(fields)}")
        try:
            values[name] = int(value) if isinstance(fields[name].default, int) else float(value)
        except ValueError:
            raise ValueError(f"--control-set {kv!r}: {value!r} is not a number") from None
    try:
        return ControlConfig(**values)
    except InputError as exc:
        raise ValueError(str(exc)) from None
