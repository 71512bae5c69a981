"""Read access to a typed result by its report.json keys, for scripts written against the dicts these were."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Iterator

__all__ = ["JsonView"]


class JsonView(Mapping):
    """Mixin for a frozen dataclass with ``to_json()``: ``obj["key"]`` reads ``obj.to_json()["key"]``."""

    def to_json(self) -> dict:
        raise NotImplementedError

    def __getitem__(self, key: str):
        return self.to_json()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.to_json())

    def __len__(self) -> int:
        return len(self.to_json())
