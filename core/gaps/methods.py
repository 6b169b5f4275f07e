"""The gap-fill methods: one registry that the fill check, the command line, batch and the GUI read.

A method is a :class:`FillMethod` made known with :func:`register_fill_method` (the built-in ones in
:mod:`core.gaps.builtin_methods`). "auto" is not a method: it is the fill check's ranking over the registered
methods (:mod:`core.gaps.check`). The registration order is the order the fill check tries them in.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.gaps.context import ModelContext
from handmocap.core.model.provenance import MEASURED, MISSING
from handmocap.core.registry import Registry

AUTO = "auto"

#: a fill: ``(positions (F, M, 3) mm, marker column, start frame, length, model context or None, joint angles
#: (F, 26) or None)`` -> the marker's positions (length, 3) mm over frames ``start .. start + length - 1``;
#: InputError with the reason when it cannot apply
FillFunction = Callable[[np.ndarray, int, int, int, ModelContext | None, np.ndarray | None], np.ndarray]


@dataclass(frozen=True)
class FillMethod:
    """One gap-fill method.

    ``name``: on the command line, in pipeline files and in the labelled C3D's provenance names; ``label``: in
    menus and the gap list; ``description``: what it does, one line (help, tooltips); ``needs``: what it needs
    to apply, one line; ``code``: the provenance code of the samples it fills (stored in labelled C3D files,
    1..127, never reused); ``colour``: RGB of its fills in the GUI; ``fill``: the :data:`FillFunction`;
    ``reach``: frames on each side of the gap it reads (the fill check keeps that many around its hidden
    stretches); ``menu_rank``: its place in the GUI's lists (lower first); ``needs_model``: it needs a hand
    model and a marker layout (the fill is given a :class:`ModelContext`)."""

    name: str
    label: str
    description: str
    needs: str
    code: int
    colour: tuple[int, int, int]
    fill: FillFunction
    reach: int
    menu_rank: int
    needs_model: bool = False


_METHODS: Registry[FillMethod] = Registry("fill method", lambda method: method.name,
                                         lambda method: {"provenance code": method.code})


def register_fill_method(method: FillMethod) -> FillMethod:
    """Make ``method`` known to every list of fill methods; ValueError when its name or code is taken."""
    if method.name == AUTO:
        raise ValueError(f"fill method name '{AUTO}' is taken")
    if not 0 < method.code < 128:
        raise ValueError(f"fill method '{method.name}': provenance code {method.code} is not in 1..127")
    return _METHODS.add(method)


def unregister_fill_method(name: str) -> None:
    """Forget the fill method ``name`` (tests, plug-ins)."""
    _METHODS.remove(name)


def fill_method(name: str) -> FillMethod:
    """The registered method ``name``; InputError naming the known ones otherwise."""
    return _METHODS.get(name)


def fill_methods() -> tuple[FillMethod, ...]:
    """Every registered method, in the order the fill check tries them."""
    return _METHODS.entries()


def fill_method_names() -> tuple[str, ...]:
    """The names of :func:`fill_methods`."""
    return _METHODS.names()


def fill_choices() -> tuple[str, ...]:
    """What a user may ask for: "auto" and every method's name."""
    return (AUTO, *_METHODS.names())


def check_fill_choice(name: str) -> str:
    """``name`` when it is one of :func:`fill_choices`; InputError naming them otherwise."""
    if name != AUTO and name not in _METHODS:
        raise InputError(f"unknown fill method '{name}' (use {', '.join(fill_choices())})")
    return name


def menu_fill_methods() -> tuple[FillMethod, ...]:
    """Every registered method in the order the GUI lists them (:attr:`FillMethod.menu_rank`)."""
    return tuple(sorted(_METHODS.entries(), key=lambda method: method.menu_rank))


def fill_codes() -> dict[str, int]:
    """Provenance code of each method: ``{name: code}``."""
    return {method.name: method.code for method in _METHODS.entries()}


def provenance_names() -> dict[int, str]:
    """Provenance code -> name: the methods' codes, :data:`MEASURED` "measured" and :data:`MISSING` "missing"."""
    return {MISSING: "missing", MEASURED: "measured", **{code: name for name, code in fill_codes().items()}}
