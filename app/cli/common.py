"""Helpers shared by the ``handmocap`` subcommand modules: figure printing and progress output."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable


def print_json(figures: dict) -> None:
    """Print ``figures`` as one JSON object on one line."""
    print(json.dumps(figures))


def print_figures(figures: dict, as_json: bool) -> None:
    """One ``key value`` line per figure; with ``as_json`` also one JSON object as the last line."""
    for key, value in figures.items():
        print(f"  {key:<28} {value}")
    if as_json:
        print_json(figures)


def print_summary(summary: str, figures: dict, as_json: bool) -> None:
    """A benchmark's one-line ``summary``; with ``as_json`` the ``figures`` as one JSON object after it."""
    print(summary)
    if as_json:
        print_json(figures)


def progress_printer() -> Callable[[float], None]:
    """A progress callback that prints every 10 % to stderr."""
    state = {"last": -1}

    def report(fraction: float) -> None:
        percent = int(fraction * 100)
        if percent // 10 != state["last"] // 10:
            state["last"] = percent
            print(f"  {percent:3d} %", file=sys.stderr, flush=True)

    return report


def add_json_flag(parser: argparse.ArgumentParser) -> None:
    """The ``--json`` flag of benchmarks and evaluations."""
    parser.add_argument("--json", action="store_true", help="print one JSON object as the last line")
