"""Hand Mocap Studio, installed as the one import package ``handmocap``.

The repository's folders are its sub-packages: ``handmocap.core`` (the Qt-free computing core),
``handmocap.app`` (the command line and the Qt window), ``handmocap.widgets`` and ``handmocap.resources``.
The wheel places them under ``handmocap/``; a development install (``installer/setup.sh``) links them under
``.venv/src/handmocap/``. ``handmocap.__version__`` is the installed distribution's version.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("handmocap")
except PackageNotFoundError:  # the sources without an installation (e.g. a frozen bundle's metadata missing)
    __version__ = "0+unknown"
