"""A minimal TOML writer for model files (the standard library only reads TOML).

:func:`to_toml` writes the nested tables, arrays, strings and numbers of a model spec;
reading the text back with ``tomllib`` gives the same data (tested).
"""

import json
import re
from collections.abc import Mapping

_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def _toml_key(k: str) -> str:
    return k if _BARE.match(k) else _toml_string(k)


def _toml_string(s: str) -> str:
    out = json.dumps(s, ensure_ascii=True)  # JSON escapes are valid TOML basic-string escapes
    return out.replace("\x7f", "\\u007f")


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return _toml_string(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def to_toml(data: Mapping) -> str:
    """Write the model schema (plain values first, then tables, then tables of tables) as TOML."""
    lines = []
    for k, v in data.items():
        if not isinstance(v, Mapping):
            lines.append(f"{_toml_key(k)} = {_toml_value(v)}")
    for k, v in data.items():
        if not isinstance(v, Mapping):
            continue
        flat = {kk: vv for kk, vv in v.items() if not isinstance(vv, Mapping)}
        nested = {kk: vv for kk, vv in v.items() if isinstance(vv, Mapping)}
        if flat or not nested:
            lines += ["", f"[{_toml_key(k)}]"]
            lines += [f"{_toml_key(kk)} = {_toml_value(vv)}" for kk, vv in flat.items()]
        for kk, vv in nested.items():
            lines += ["", f"[{_toml_key(k)}.{_toml_key(kk)}]"]
            lines += [f"{_toml_key(k3)} = {_toml_value(v3)}" for k3, v3 in vv.items()]
    return "\n".join(lines) + "\n"
