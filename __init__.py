"""Hand Mocap Studio, installed as the one import package ``handmocap``.

The repository's folders are its sub-packages: ``handmocap.core`` (the Qt-free computing core),
``handmocap.app`` (the command line and the Qt window), ``handmocap.widgets`` and ``handmocap.resources``.
The wheel places them under ``handmocap/``; a development install (``installer/setup.sh``) links them under
``.venv/src/handmocap/``. ``handmocap.__version__`` is the installed distribution's version.

The Python API (:mod:`handmocap.core.api`: ``read_take``, ``label``, ``fill``, ``solve``, ``export``,
``learn_template``, ``evaluate_labelling``...) is available here, imported on first use so that the
command line does not pay for it.
"""

from importlib import import_module

__all__ = ["__version__", "CancelledError", "FilledGap", "FillResult", "InputError", "LabTemplate", "LabelResult",
           "SolvedHand", "Take", "evaluate_labelling", "export", "fill", "label", "learn_template", "read_take",
           "save_take", "save_template", "simulate_take", "solve"]
#: the names of the Python API, each read from handmocap.core.api when first asked for
API = frozenset(__all__) - {"__version__"}


def __getattr__(name: str) -> object:
    """The API's names, imported from :mod:`handmocap.core.api` on first use, and ``__version__``, read from
    the installed distribution's metadata when first asked for (reading it costs a tenth of a second at every
    start) (PEP 562)."""
    if name == "__version__":
        return _installed_version()
    if name in API:
        return getattr(import_module("handmocap.core.api"), name)
    raise AttributeError(f"module 'handmocap' has no attribute '{name}'")


def _installed_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("handmocap")
    except PackageNotFoundError:  # the sources without an installation (e.g. a frozen bundle's metadata missing)
        return "0+unknown"


def __dir__() -> list[str]:
    return sorted([*globals(), *API])
