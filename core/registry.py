"""A registry of named entries kept in registration order: the fill methods (:mod:`core.gaps.methods`) and the
export formats (:mod:`core.review.export_formats`), which the command line, batch and the window list."""

from __future__ import annotations

from collections.abc import Callable
from typing import Generic, TypeVar

from handmocap.core.errors import InputError

Entry = TypeVar("Entry")


class Registry(Generic[Entry]):
    """Entries by name, in the order they were added. ``what`` names an entry in messages ("fill method");
    ``unique`` maps an entry to the values no two entries may share besides the name (e.g. a provenance code)."""

    def __init__(self, what: str, name_of: Callable[[Entry], str],
                 unique: Callable[[Entry], dict[str, object]] | None = None) -> None:
        self.what, self._name_of, self._unique = what, name_of, unique
        self._entries: dict[str, Entry] = {}

    def add(self, entry: Entry) -> Entry:
        """Make ``entry`` known; ValueError when its name or a unique value is taken."""
        name = self._name_of(entry)
        if name in self._entries:
            raise ValueError(f"{self.what} name '{name}' is taken")
        if self._unique is not None:
            taken = [self._unique(other) for other in self._entries.values()]
            for key, value in self._unique(entry).items():
                if any(values[key] == value for values in taken):
                    raise ValueError(f"{self.what} '{name}': {key} {value!r} is taken")
        self._entries[name] = entry
        return entry

    def remove(self, name: str) -> None:
        """Forget the entry ``name`` (tests, plug-ins)."""
        del self._entries[name]

    def get(self, name: str) -> Entry:
        """The entry ``name``; InputError naming the known ones otherwise."""
        try:
            return self._entries[name]
        except KeyError:
            raise InputError(f"unknown {self.what} '{name}' (use {', '.join(self._entries)})") from None

    def entries(self) -> tuple[Entry, ...]:
        """Every entry, in registration order."""
        return tuple(self._entries.values())

    def names(self) -> tuple[str, ...]:
        """The names of :meth:`entries`."""
        return tuple(self._entries)

    def __contains__(self, name: object) -> bool:
        return name in self._entries
