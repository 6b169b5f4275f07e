"""The files shipped with the application (``handmocap.resources``: template hand, priors, layouts, icons),
found through :mod:`importlib.resources`, wherever the package is installed or frozen."""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path


def resource_path(*parts: str) -> Path:
    """The file or folder ``parts`` under ``handmocap/resources`` as a path on disk (the package is a folder,
    never a zip: numpy, Qt and the layout reader open these files by name)."""
    return Path(str(files("handmocap.resources").joinpath(*parts)))
