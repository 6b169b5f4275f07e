"""The handmocap command: help, version, errors as one line with exit code 2, end-to-end runs."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from handmocap.app.cli.main import build_parser, main
from handmocap.core.evaluation.data import REAL_RECORDING


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "handmocap.app.cli.main", *args], capture_output=True, text=True,
                          timeout=600, cwd=Path(__file__).resolve().parents[2])


def test_version_and_help_of_every_subcommand(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0 and "handmocap" in capsys.readouterr().out
    subcommands = build_parser()._subparsers._group_actions[0].choices
    for name in subcommands:
        with pytest.raises(SystemExit) as exit_info:
            main([name, "--help"])
        assert exit_info.value.code == 0
        assert "usage: handmocap" in capsys.readouterr().out


@pytest.mark.parametrize("args", [
    ["info", "does-not-exist.c3d"],
    ["solve", "does-not-exist.c3d", "--layout", "dense", "--out", "x.npz"],
    ["info", __file__],
])
def test_errors_are_one_line_with_exit_code_2(args):
    completed = run(*args)
    assert completed.returncode == 2
    assert "Traceback" not in completed.stderr
    assert len(completed.stderr.strip().splitlines()) == 1
    assert completed.stderr.startswith("handmocap: error:")


def test_bad_layout_is_a_clear_error(tmp_path, capsys):
    take = tmp_path / "t.c3d"
    assert main(["simulate", "--frames", "20", "--out", str(take), "--truth", str(tmp_path / "t.npz")]) == 0
    assert main(["solve", str(take), "--layout", "no-such-layout", "--out", str(tmp_path / "r.npz")]) == 2
    assert "unknown layout 'no-such-layout'" in capsys.readouterr().err


def test_simulate_then_solve_round_trip(tmp_path, capsys):
    take, truth = tmp_path / "take.c3d", tmp_path / "truth.npz"
    assert main(["simulate", "--layout", "dense", "--frames", "120", "--seed", "4", "--out", str(take),
                 "--truth", str(truth)]) == 0
    with np.load(truth) as data:
        assert data["joint_angles"].shape == (120, 26)
        assert data["marker_positions"].shape == (120, 24, 3)
    result, csv = tmp_path / "result.npz", tmp_path / "angles.csv"
    assert main(["solve", str(take), "--layout", "dense", "--out", str(result), "--csv", str(csv),
                 "--quiet"]) == 0
    with np.load(result) as solved, np.load(truth) as data:
        error = np.degrees(np.abs(solved["joint_angles"][:, 6:] - data["joint_angles"][:, 6:]))
        assert error.mean() < 0.5
        assert np.nanmean(solved["residuals_mm"]) < 0.05
    assert len(csv.read_text().splitlines()) == 121
    capsys.readouterr()
    assert main(["info", str(take), "--json"]) == 0
    info = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert info["frames"] == 120 and info["markers"] == 24 and info["frame_rate_hz"] == 100.0


def test_unlabelled_simulation_writes_point_marker(tmp_path):
    take, truth = tmp_path / "raw.c3d", tmp_path / "truth.npz"
    assert main(["simulate", "--layout", "glove-13", "--frames", "60", "--seed", "1", "--noise", "0.3",
                 "--ghosts", "0.1", "--occlusion", "--unlabelled", "--out", str(take), "--truth", str(truth)]) == 0
    with np.load(truth) as data:
        assert data["point_marker"].shape[0] == 60
        assert (data["point_marker"] == -1).any()


@pytest.mark.skipif(not REAL_RECORDING.exists(), reason="shared data absent")
def test_info_on_the_real_recording(capsys):
    assert main(["info", str(REAL_RECORDING), "--json"]) == 0
    info = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert info["frames"] == 3000 and info["markers"] == 21 and info["vendor"] == "Qualisys"
    assert "thumb_tip" in info["marker_names"]


def test_bench_and_evaluate_print_json_last(capsys):
    assert main(["bench", "ik", "--frames", "200", "--json"]) == 0
    figures = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert figures["frames_per_s"] > 0 and figures["markers"] == 24
    assert main(["bench", "load", "--frames", "2000", "--json"]) == 0
    figures = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert figures["frames"] == 2000 and figures["markers"] == 40 and figures["seconds"] > 0


def test_layout_optimize_and_evaluate(tmp_path, capsys):
    out = tmp_path / "layout.json"
    assert main(["layout", "optimize", "--markers", "4", "--method", "greedy", "--out", str(out)]) == 0
    assert json.loads(out.read_text())["markers"][0]["vertex"] >= 0
    capsys.readouterr()
    assert main(["layout", "evaluate", str(out), "--json"]) == 0
    figures = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert figures["markers"] == 4 and 0 < figures["mean_mm"] <= figures["max_mm"]
    assert main(["layout", "optimize", "--markers", "100000", "--out", str(out), "--overwrite"]) == 2
    assert "cannot place 100000 markers" in capsys.readouterr().err


def test_version_and_info_load_no_compiled_kernels_nor_qt(tmp_path):
    """The fixed cost of a call (issue 25: ≤ 0.5 s): the parser reads the fill methods and export formats only
    when they are asked for, so ``--version`` and ``info`` import neither numba (half a second) nor Qt."""
    from handmocap.core.io import save_take
    from handmocap.core.simulate import simulate_take

    path = tmp_path / "small.c3d"
    save_take(simulate_take(layout="grasp-6", n_frames=20, seed=1).take, path)
    probe = ("import sys; from handmocap.app.cli.main import main\n"
             "for args in (['--version'], ['info', sys.argv[1]]):\n"
             "    try:\n"
             "        main(args)\n"
             "    except SystemExit:\n"
             "        pass\n"
             "print(sorted({name.split('.')[0] for name in sys.modules} & {'numba', 'PySide6', 'scipy', 'cv2'}))")
    completed = subprocess.run([sys.executable, "-c", probe, str(path)], capture_output=True, text=True, timeout=120)
    assert completed.returncode == 0, completed.stderr
    assert completed.stdout.strip().splitlines()[-1] == "[]"
    assert "20 frames" in completed.stdout
