"""``--rate HZ`` on every command that reads a take: a file without a rate is read with it, never refused."""

import json
from pathlib import Path

import pytest

from handmocap.app.cli.main import build_parser, main

NOKOV = Path(__file__).resolve().parents[1] / "io" / "fixtures" / "nokov.csv"

#: every command that reads a take, with its other required arguments
TAKE_COMMANDS = [
    ["gui", "T"],
    ["info", "T"],
    ["solve", "T", "--layout", "dense", "--out", "o.npz"],
    ["label", "T", "--layout", "dense", "--out", "o.c3d"],
    ["fill", "T", "--max-gap", "5", "--out", "o.c3d"],
    ["export", "T", "--format", "c3d", "--out", "o.c3d"],
    ["layout", "fit", "T", "--layout", "dense", "--out", "o.json"],
    ["layout", "learn", "T", "--out", "o.json"],
    ["camera", "register", "T", "video.mp4", "--camera", "c.json", "--out", "o.json"],
    ["camera", "overlay", "T", "video.mp4", "--camera", "c.json", "--out", "o.mp4"],
    ["fuse", "T", "--camera", "c.json", "--rgbd", "frames", "--out", "o.npz"],
    ["evaluate", "gaps", "T"],
    ["evaluate", "label", "--take", "T"],
]


@pytest.mark.parametrize("argv", TAKE_COMMANDS, ids=lambda argv: " ".join(argv[:2]))
def test_every_command_that_reads_a_take_takes_a_rate(argv):
    assert build_parser().parse_args(argv + ["--rate", "120"]).rate == 120.0
    assert build_parser().parse_args(argv).rate is None


def test_info_reads_a_nokov_export_at_the_given_rate(capsys):
    assert main(["info", str(NOKOV), "--rate", "120", "--json"]) == 0
    info = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert info["vendor"] == "NOKOV" and info["frame_rate_hz"] == 120.0 and info["frames"] == 4
    assert info["marker_names"] == ["Marker1", "L-A1", "R-Wan-nei"]
    assert main(["info", str(NOKOV), "--rate", "120"]) == 0
    assert "nokov.csv: NOKOV, 4 frames at 120 Hz" in capsys.readouterr().out


def test_without_a_rate_the_error_says_how_to_give_it(capsys):
    assert main(["info", str(NOKOV)]) == 2
    error = capsys.readouterr().err.strip()
    assert error == "handmocap: error: nokov.csv: the file has no frame rate; give it with --rate HZ"


@pytest.mark.parametrize("rate", ["0", "-100", "nan", "fast"])
def test_a_rate_that_is_no_positive_number_is_refused(capsys, rate):
    with pytest.raises(SystemExit) as exit_info:
        main(["info", str(NOKOV), "--rate", rate])
    assert exit_info.value.code == 2
    assert "positive number of Hz" in capsys.readouterr().err
