"""Built-in TOML data by name, or a user's TOML file by path (schedules, hands, sensors)."""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

from .errors import GyrosimError

__all__ = ["builtin_names", "load_named_toml"]


def builtin_names(*folder: str) -> list[str]:
    """Names of the ``*.toml`` files shipped in ``gyrosim/<folder...>``."""
    path = resources.files("gyrosim").joinpath(*folder)
    return sorted(p.name[:-5] for p in path.iterdir() if p.name.endswith(".toml"))


def load_named_toml(folder: tuple[str, ...], name_or_path: str | Path, what: str,
                    error: type[GyrosimError]) -> tuple[str, dict[str, Any]]:
    """(name, table) of a built-in ``name`` in ``gyrosim/<folder>`` or of a TOML file path.

    Raises ``error`` naming the built-ins when neither exists, or quoting the parser when the TOML
    is malformed.
    """
    name = str(name_or_path)
    names = builtin_names(*folder)
    if name in names:
        text = resources.files("gyrosim").joinpath(*folder, f"{name}.toml").read_text()
    elif Path(name).is_file():
        text = Path(name).read_text()
        name = Path(name).stem
    else:
        raise error(f"unknown {what} {name!r}; use one of {', '.join(names)} or the path of a TOML file")
    try:
        return name, tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{what} {name!r} is not valid TOML: {exc}") from exc
