"""The files shipped with the application (``handmocap.resources``: template hand, priors, layouts, icons),
found through :mod:`importlib.resources`, wherever the package is installed or frozen."""

from __future__ import annotations

from importlib.resources import files
from importlib.resources.abc import Traversable
from pathlib import Path


def resource_path(*parts: str) -> Path:
    """The file or folder ``parts`` under ``handmocap/resources`` as a path on disk (the package is a folder,
    never a zip: numpy, Qt and the layout reader open these files by name)."""
    return joined_path(files("handmocap.resources"), parts)


def joined_path(root: Traversable, parts: tuple[str, ...]) -> Path:
    """``root`` joined with ``parts`` one at a time: a frozen bundle's resources are a ``MultiplexedPath``
    (the bundle's archive and its data folder), whose ``joinpath`` takes one name in Python 3.11."""
    for part in parts:
        root = root.joinpath(part)
    return Path(str(root))
