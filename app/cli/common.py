"""Helpers shared by the ``handmocap`` subcommand modules: output checks, figure printing and progress output."""

from __future__ import annotations

import argparse
import copy
import json
import math
import os
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from handmocap.app.cli.progress import ProgressLine
from handmocap.core.errors import InputError
from handmocap.core.io.durable import check_target

OVERWRITE_HELP = "replace output files that already exist (without it the command stops before any work)"
"""The one meaning of ``--overwrite`` in every command."""


class DeferredHelpFormatter(argparse.HelpFormatter):
    """Help and descriptions that may be given as functions, called only when the help is shown: a text read
    from a registry (fill methods, export formats) costs the import of what fills the registry (numba's
    kernels among them, half a second), which no other call should pay for."""

    def _format_text(self, text: str | Callable[[], str]) -> str:
        return super()._format_text(text() if callable(text) else text)

    def _format_action(self, action: argparse.Action) -> str:
        if callable(action.help):
            action = copy.copy(action)
            action.help = action.help()
        return super()._format_action(action)


class DeferredChoices:
    """The values an option allows, read from a registry only when the option is given or its error shown
    (see :class:`DeferredHelpFormatter`); give the option a ``metavar``, as the usage line lists no choices."""

    def __init__(self, names: Callable[[], Iterable[str]]) -> None:
        self._names = names

    def __contains__(self, value: object) -> bool:
        return value in tuple(self._names())

    def __iter__(self) -> Iterator[str]:
        return iter(tuple(self._names()))


def add_outputs(parser: argparse.ArgumentParser, *options: str) -> None:
    """Declare the options of ``parser`` that name files the command writes (e.g. ``"out"``, ``"report"``),
    checked by :func:`check_outputs` before the command starts, and add its ``--overwrite`` flag."""
    parser.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    parser.set_defaults(outputs=options)


def check_outputs(args: argparse.Namespace) -> None:
    """Check every output file the command was given (see :func:`add_outputs`) before any work starts."""
    given = [getattr(args, option) for option in getattr(args, "outputs", ()) if getattr(args, option, None)]
    seen: set[Path] = set()
    for path in given:
        target = check_output(path, args.overwrite)
        if target.resolve() in seen:
            raise InputError(f"{path} is named as two outputs; give each output its own file")
        seen.add(target.resolve())


def check_output(path: str | os.PathLike[str], overwrite: bool) -> Path:
    """``path`` once it can be written as a new output: its folder exists and is writable, it is not a folder
    or a symbolic link, and it does not exist unless ``overwrite``. InputError (one line) otherwise."""
    target = check_target(path)
    if target.exists() and not overwrite:
        raise InputError(f"{path} exists; use --overwrite to replace it")
    if not os.access(target.parent, os.W_OK | os.X_OK):
        raise InputError(f"cannot write {path}: folder {target.parent} is not writable")
    return target


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


def progress_printer(what: str = "working", total: float | None = None, unit: str = "frames") -> ProgressLine:
    """The progress callback of a long command: one in-place line on stderr with what is done, the share, the
    rate in ``unit``/s (of ``total``; percent when None), the time spent and left; nothing when stderr is
    not a terminal (:mod:`app.cli.progress`)."""
    return ProgressLine(what, total, unit)


def add_json_flag(parser: argparse.ArgumentParser) -> None:
    """The ``--json`` flag of benchmarks and evaluations."""
    parser.add_argument("--json", action="store_true", help="print one JSON object as the last line")


def add_frames_command(commands: argparse._SubParsersAction, name: str, help: str, frames_help: str,
                       handler: Callable[..., object]) -> argparse.ArgumentParser:
    """A benchmark or evaluation on simulated takes: subcommand ``name`` with ``--frames N`` (``frames_help``)
    and ``--json``, run by ``handler``."""
    parser = commands.add_parser(name, help=help)
    parser.add_argument("--frames", type=int, help=frames_help)
    add_json_flag(parser)
    parser.set_defaults(handler=handler)
    return parser


def frame_rate_hz(text: str) -> float:
    """The argparse type of ``--rate``: a positive number of Hz."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"the frame rate must be a positive number of Hz, not '{text}'")
    return value


def add_rate_argument(parser: argparse.ArgumentParser) -> None:
    """The ``--rate HZ`` option of a command that reads a take (``args.rate``, None when not given)."""
    parser.add_argument("--rate", type=frame_rate_hz, metavar="HZ",
                        help="the take's frame rate in Hz: needed when its file states none (NOKOV CSV, a CSV "
                             "without a time column); it overrides the file's rate")
