"""The command line (issue 23 item 6): one in-place progress line with rate and time left for every long command
(quiet when stderr is not a terminal), every argument with help, one meaning of --overwrite, simulate without
--truth, label naming each hand once."""

from __future__ import annotations

import argparse
import io
import subprocess
import sys

from rich.console import Console

from handmocap.app.cli.common import OVERWRITE_HELP
from handmocap.app.cli.main import build_parser
from handmocap.app.cli.progress import ProgressLine

HANDMOCAP = [sys.executable, "-m", "handmocap.app.cli.main"]


def _arguments(parser: argparse.ArgumentParser, path: tuple[str, ...] = ("handmocap",)):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _arguments(sub, (*path, name))
        elif not isinstance(action, argparse._HelpAction):
            yield " ".join(path), action


def test_every_argument_has_help_and_overwrite_one_meaning():
    missing, overwrite = [], set()
    for command, action in _arguments(build_parser()):
        if not action.help:
            missing.append(f"{command} {'/'.join(action.option_strings) or action.dest}")
        if "--overwrite" in action.option_strings:
            overwrite.add(action.help.split(";")[0])
    assert not missing, missing
    assert overwrite == {OVERWRITE_HELP}, overwrite


def test_the_progress_line_gives_the_rate_and_the_time_left():
    text = io.StringIO()
    console = Console(file=text, force_terminal=True, width=150, color_system=None)
    line = ProgressLine("labelling", 20_000, console=console)
    for step in range(1, 11):
        line(step / 10)
    assert line._progress is None                          # 1.0 ends the line
    drawn = [row for row in text.getvalue().replace("\r", "\n").splitlines() if "labelling" in row]
    last = drawn[-1]
    assert "labelling" in last and "100%" in last and "frames/s" in last and "left" in last, last


def test_the_progress_line_is_quiet_when_not_on_a_terminal():
    line = ProgressLine("labelling", 100, console=Console(file=io.StringIO(), force_terminal=False))
    assert not line.enabled
    line(0.5)
    line(1.0)


def test_simulate_needs_no_truth_and_label_names_each_hand_once(tmp_path):
    take = tmp_path / "raw.c3d"
    done = subprocess.run([*HANDMOCAP, "simulate", "--frames", "120", "--unlabelled", "--out", str(take)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert " and truth " not in done.stdout and done.stderr == ""      # no terminal: no progress line
    done = subprocess.run([*HANDMOCAP, "label", str(take), "--layout", "dense", "--hands", "right",
                           "--out", str(tmp_path / "labelled.c3d")], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "right hand" in done.stdout and "right right" not in done.stdout, done.stdout
    assert "%" not in done.stderr.replace("% of", ""), done.stderr
