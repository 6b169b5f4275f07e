"""The command line's choices come from the registries (issue 26 item 3): ``fill --method`` from the fill
methods, ``export --format`` from the export formats; a method or format registered shows up in a parser
built after it, and is gone once unregistered."""

from __future__ import annotations

import argparse

import numpy as np

from handmocap.app.cli.main import build_parser
from handmocap.core.gaps import FillMethod, fill_choices, register_fill_method, unregister_fill_method
from handmocap.core.review.export_formats import (
    ExportFormat,
    export_format_names,
    register_export_format,
    unregister_export_format,
)


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
    register_fill_method(FillMethod(name="hold", label="Hold", description="The sample before the gap held",
                                    needs="", code=42, colour=(0, 0, 0), reach=1, menu_rank=9,
                                    fill=lambda positions, marker, start, length, _c, _a: np.repeat(
                                        positions[start - 1:start, marker], length, axis=0)))
    register_export_format(ExportFormat(name="names", label="Label names", suffixes=(".txt",), name_tag="_names",
                                        batch_ending=".names.txt", writer=lambda review, path, options: [path]))
    try:
        assert _choices("fill", "--method")[-1] == "hold"
        assert _choices("export", "--format")[-1] == "names"
    finally:
        unregister_fill_method("hold")
        unregister_export_format("names")
    assert "hold" not in _choices("fill", "--method") and "names" not in _choices("export", "--format")
