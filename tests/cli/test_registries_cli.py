"""The command line's choices come from the registries (issue 26 item 3): ``fill --method`` from the fill
methods, ``export --format`` from the export formats; a method or format registered shows up in a parser
built after it, and is gone once unregistered."""

from __future__ import annotations

import argparse

from registry_extras import registered_extras

from handmocap.app.cli.main import build_parser
from handmocap.core.gaps import fill_choices
from handmocap.core.review.export_formats import export_format_names


def _choices(command: str, option: str) -> tuple[str, ...]:
    parser = build_parser()
    commands = next(action for action in parser._actions if isinstance(action, argparse._SubParsersAction))
    return tuple(next(action for action in commands.choices[command]._actions
                      if option in action.option_strings).choices)


def test_the_choices_are_the_registries():
    assert _choices("fill", "--method") == fill_choices() == ("auto", "linear", "spline", "pattern", "rigid",
                                                              "model", "pca")
    assert _choices("export", "--format") == export_format_names()


def test_a_registered_method_and_format_are_offered_then_gone():
    with registered_extras():
        assert _choices("fill", "--method")[-1] == "hold"
        assert _choices("export", "--format")[-1] == "names"
    assert "hold" not in _choices("fill", "--method") and "names" not in _choices("export", "--format")
