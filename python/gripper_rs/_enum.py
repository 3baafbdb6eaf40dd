"""Enums that keep the numbers the manuals do not list (Rust: ``Unknown(n)`` variants)."""

from __future__ import annotations

import enum
from typing import Any


class OpenIntEnum(enum.IntEnum):
    """An ``IntEnum`` whose unknown values become members named ``UNKNOWN_<n>`` instead of
    raising: a device may send a number a newer manual added."""

    @classmethod
    def _missing_(cls, value: Any) -> Any:
        if not isinstance(value, int):
            return None
        member = int.__new__(cls, value)
        member._name_ = f"UNKNOWN_{value}"
        member._value_ = value
        return member

    @property
    def known(self) -> bool:
        """Whether the manual lists this value."""
        return self._value_ in type(self)._value2member_map_
