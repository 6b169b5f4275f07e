"""Every ``handmocap`` command that writes a file refuses to replace one without ``--overwrite`` and checks its
outputs (folder, folder or link as target) before any work starts: one line on stderr, exit code 2."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from handmocap.app.cli.main import build_parser, main

#: options that name a file a command writes
OUTPUT_OPTIONS = {"out", "report", "csv", "truth", "gltf", "screenshot"}

# argv per command with OUT where an output goes; the inputs do not exist: the output check comes first.
COMMANDS = {
    "simulate --out": ["simulate", "--out", "OUT", "--truth", "NEW.npz"],
    "simulate --truth": ["simulate", "--out", "NEW.c3d", "--truth", "OUT"],
    "solve --out": ["solve", "missing.c3d", "--layout", "dense", "--out", "OUT"],
    "solve --csv": ["solve", "missing.c3d", "--layout", "dense", "--out", "NEW.npz", "--csv", "OUT"],
    "template build": ["template", "build", "--out", "OUT"],
    "prior build": ["prior", "build", "--out", "OUT"],
    "label --out": ["label", "missing.c3d", "--layout", "dense", "--out", "OUT"],
    "label --report": ["label", "missing.c3d", "--layout", "dense", "--out", "NEW.c3d", "--report", "OUT"],
    "fill --out": ["fill", "missing.c3d", "--max-gap", "5", "--out", "OUT"],
    "calibrate --out": ["calibrate", "missing.ply", "--landmarks", "missing.json", "--out", "OUT"],
    "calibrate --report": ["calibrate", "missing.ply", "--landmarks", "missing.json", "--out", "NEW.npz",
                           "--report", "OUT"],
    "calibrate --gltf": ["calibrate", "missing.ply", "--landmarks", "missing.json", "--out", "NEW.npz",
                         "--gltf", "OUT"],
    "layout fit": ["layout", "fit", "missing.c3d", "--layout", "dense", "--out", "OUT"],
    "layout optimise": ["layout", "optimise", "--markers", "4", "--out", "OUT"],
    "layout sheet": ["layout", "sheet", "dense", "--out", "OUT"],
    "layout view": ["layout", "view", "--screenshot", "OUT"],
    "gui": ["gui", "--screenshot", "OUT"],
}
OLD_BYTES = b"an earlier output\n"


def _run(argv: list[str], out: Path, folder: Path) -> list[str]:
    """``argv`` with OUT replaced by ``out`` and the other relative files placed in ``folder``."""
    return [str(out) if arg == "OUT" else str(folder / arg) if arg.startswith(("NEW", "missing")) else arg
            for arg in argv]


def _error(capsys: pytest.CaptureFixture[str]) -> str:
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    return lines[0]


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_existing_output_is_not_replaced_without_overwrite(command: str, tmp_path: Path, capsys) -> None:
    out = tmp_path / "existing.out"
    out.write_bytes(OLD_BYTES)
    assert main(_run(COMMANDS[command], out, tmp_path)) == 2
    assert _error(capsys) == f"handmocap: error: {out} exists; use --overwrite to replace it"
    assert out.read_bytes() == OLD_BYTES
    assert sorted(path.name for path in tmp_path.iterdir()) == ["existing.out"]


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_outputs_are_checked_before_the_work(command: str, tmp_path: Path, capsys) -> None:
    victim = tmp_path / "victim.txt"
    victim.write_bytes(OLD_BYTES)
    link = tmp_path / "link.out"
    link.symlink_to(victim)
    assert main([*_run(COMMANDS[command], link, tmp_path), "--overwrite"]) == 2
    assert "symbolic link" in _error(capsys)
    assert victim.read_bytes() == OLD_BYTES and link.is_symlink()

    assert main(_run(COMMANDS[command], tmp_path / "no folder" / "out.x", tmp_path)) == 2
    assert "does not exist" in _error(capsys)
    assert main(_run(COMMANDS[command], tmp_path, tmp_path)) == 2
    assert "is a folder" in _error(capsys)


def test_with_overwrite_the_file_is_replaced(tmp_path: Path, capsys) -> None:
    out, truth = tmp_path / "take.c3d", tmp_path / "truth.npz"
    out.write_bytes(OLD_BYTES)
    assert main(["simulate", "--frames", "20", "--out", str(out), "--truth", str(truth), "--overwrite"]) == 0
    assert out.read_bytes()[:2] == bytes([2, 0x50])  # a C3D header
    assert main(["simulate", "--frames", "20", "--out", str(out), "--truth", str(out), "--overwrite"]) == 2
    assert "named as two outputs" in _error(capsys)


def _subparsers(parser: argparse.ArgumentParser):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, child in action.choices.items():
                yield name, child
                yield from _subparsers(child)


def test_every_command_with_an_output_declares_it() -> None:
    """A new command with ``--out`` (or another output option) must be checked like the others."""
    for name, parser in _subparsers(build_parser()):
        options = {action.dest for action in parser._actions} & OUTPUT_OPTIONS
        declared = set(parser.get_default("outputs") or ())
        assert options <= declared, f"'{name}' writes {sorted(options - declared)} without the output check"
        if declared:
            assert "overwrite" in {action.dest for action in parser._actions}
