"""Durable writes (core.io.durable) for every export format: past a file-size limit (EFBIG, as on a full disk)
and through a symbolic link the old file keeps its bytes, no temporary is left and the error is one line."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from handmocap.core.errors import InputError
from handmocap.core.io.durable import WriteError, durable_path, durable_stream, write_atomic

ROOT = Path(__file__).resolve().parents[2]
LIMIT_BYTES = 2048  # every case below writes more than this

# The child builds the data, then limits the size of the files it writes (SIGXFSZ ignored: write() fails
# with EFBIG instead of killing the process) and writes one format to argv[2].
CHILD = r"""
import json, resource, signal, sys
import numpy as np
case, path, limit = sys.argv[1], sys.argv[2], int(sys.argv[3])
sys.path.insert(0, sys.argv[4])
from test_durable_writes import writer
write = writer(case)
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
try:
    write(path)
except Exception as error:
    kind = {"type": type(error).__name__, "input_error": isinstance(error, InputError)}
    print(json.dumps(kind | {"message": str(error)}))
else:
    print(json.dumps({"type": None}))
""".replace("import numpy as np", "import numpy as np\nfrom handmocap.core.errors import InputError")


def _take(frames: int = 400, points: int = 6):
    from handmocap.core.io import Take

    rng = np.random.default_rng(3)
    positions = rng.uniform(-500.0, 500.0, (frames, points, 3))
    positions[rng.random((frames, points)) < 0.1] = np.nan
    return Take([f"m{index}" for index in range(points)], positions, frame_rate=100.0)


def writer(case: str):
    """A function ``write(path)`` that writes one file of format ``case`` (data built here, before the limit)."""
    from handmocap.core.model import load_template

    angles = np.zeros((300, 26))
    angles[:, 6:] = np.linspace(0.0, 0.5, 300)[:, None]
    if case in ("c3d", "trc", "csv"):
        from handmocap.core.io import save_take

        take = _take()
        return lambda path: save_take(take, path)
    if case == "labelled_c3d":
        from handmocap.core.io.labelled_c3d import write_labelled_c3d

        take = _take()
        provenance = np.where(np.isfinite(take.marker_positions).all(axis=2), 0, -1)
        return lambda path: write_labelled_c3d(path, take.marker_names, take.marker_positions, provenance, 100.0,
                                               unlabelled=take.marker_positions[:, :2], ghost=provenance[:, :2] == 0)
    if case == "bvh":
        from handmocap.core.model.bvh import write_bvh

        skeleton = load_template().skeleton
        return lambda path: write_bvh(path, skeleton, angles, 100.0)
    if case == "angles_csv":
        from handmocap.core.model.joint_angles import write_joint_angles_csv

        return lambda path: write_joint_angles_csv(path, [("", angles)], 1, 100.0)
    if case in ("glb", "gltf"):
        from handmocap.core.model.gltf import save_gltf_hand

        model = load_template()
        return lambda path: save_gltf_hand(model, path)
    if case == "result_npz":
        from handmocap.core.ik import IKResult

        result = IKResult(angles, np.ones((300, 4)), np.ones((300, 4, 3)), ["a", "b", "c", "d"], "layered")
        return result.save
    if case == "model_npz":
        return load_template().save
    if case == "truth_npz":
        from handmocap.core.simulate import save_truth

        truth = {"joint_angles": angles}
        return lambda path: save_truth(truth, path)
    if case == "layout_json":
        from handmocap.core.model import load_layout, save_layout

        layout = load_layout("dense")
        return lambda path: save_layout(layout, path)
    raise ValueError(case)


CASES = {"c3d": ".c3d", "labelled_c3d": ".c3d", "trc": ".trc", "csv": ".csv", "bvh": ".bvh",
         "angles_csv": ".csv", "glb": ".glb", "gltf": ".gltf", "result_npz": ".npz", "model_npz": ".npz",
         "truth_npz": ".npz", "layout_json": ".json"}
OLD_BYTES = b"the previous file, which must survive\n" * 4


def _assert_one_line_naming(message: str, path: Path) -> None:
    assert "\n" not in message and str(path) in message, message


@pytest.mark.parametrize("case", sorted(CASES))
def test_file_size_limit_keeps_the_old_file(case: str, tmp_path: Path) -> None:
    target = tmp_path / f"output{CASES[case]}"
    target.write_bytes(OLD_BYTES)
    completed = subprocess.run([sys.executable, "-c", CHILD, case, str(target), str(LIMIT_BYTES),
                                str(Path(__file__).parent)],
                               capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert completed.returncode == 0, completed.stderr[-2000:]
    outcome = json.loads(completed.stdout.strip().splitlines()[-1])
    assert outcome["type"] == "WriteError" and outcome["input_error"], outcome
    _assert_one_line_naming(outcome["message"], target)
    assert "too large" in outcome["message"] and "old file is kept" in outcome["message"]
    assert target.read_bytes() == OLD_BYTES
    assert [path.name for path in tmp_path.iterdir()] == [target.name]  # no temporary left


@pytest.mark.parametrize("case", sorted(CASES))
def test_symbolic_link_target_is_refused(case: str, tmp_path: Path) -> None:
    victim = tmp_path / "elsewhere" / "victim.txt"
    victim.parent.mkdir()
    victim.write_bytes(OLD_BYTES)
    link = tmp_path / f"output{CASES[case]}"
    link.symlink_to(victim)
    write = writer(case)
    with pytest.raises(InputError, match="symbolic link") as raised:
        write(link)
    _assert_one_line_naming(str(raised.value), link)
    assert victim.read_bytes() == OLD_BYTES and link.is_symlink()
    assert sorted(path.name for path in tmp_path.iterdir()) == ["elsewhere", link.name]


def test_planted_predictable_temporary_names_are_not_followed(tmp_path: Path) -> None:
    """``simulate --truth`` used to write ``<name>.tmp.npz`` and followed a link planted there."""
    victim = tmp_path / "victim.txt"
    victim.write_bytes(OLD_BYTES)
    target = tmp_path / "truth.npz"
    for name in ("truth.npz.tmp.npz", "truth.npz.tmp", ".truth.npz.tmp", "truth.tmp.npz"):
        (tmp_path / name).symlink_to(victim)
    writer("truth_npz")(target)
    assert victim.read_bytes() == OLD_BYTES
    assert np.load(target)["joint_angles"].shape == (300, 26)


def test_errors_inside_the_block_keep_the_old_file(tmp_path: Path) -> None:
    target = tmp_path / "out.bin"
    target.write_bytes(OLD_BYTES)
    with pytest.raises(RuntimeError), durable_stream(target) as stream:
        stream.write(b"half")
        raise RuntimeError("the writer failed")
    with pytest.raises(RuntimeError), durable_path(target) as temporary:
        temporary.write_bytes(b"half")
        raise RuntimeError("the writer failed")
    assert target.read_bytes() == OLD_BYTES
    assert [path.name for path in tmp_path.iterdir()] == ["out.bin"]


def test_failed_verification_keeps_the_old_file(tmp_path: Path) -> None:
    target = tmp_path / "out.c3d"
    target.write_bytes(OLD_BYTES)

    def refuse(path: Path) -> None:
        raise InputError("does not open")

    with (pytest.raises(WriteError, match="does not read back") as raised,
          durable_stream(target, verify=refuse) as stream):
        stream.write(b"new bytes")
    _assert_one_line_naming(str(raised.value), target)
    assert target.read_bytes() == OLD_BYTES
    assert [path.name for path in tmp_path.iterdir()] == ["out.c3d"]


def test_write_atomic_writes_new_files_with_the_umask_mode(tmp_path: Path) -> None:
    previous = os.umask(0o027)
    try:
        write_atomic(tmp_path / "new.txt", b"content")
    finally:
        os.umask(previous)
    assert (tmp_path / "new.txt").read_bytes() == b"content"
    assert (tmp_path / "new.txt").stat().st_mode & 0o777 == 0o640


def test_write_errors_are_input_and_os_errors(tmp_path: Path) -> None:
    """Callers that wrap OSError in their own message (the session) keep working."""
    with pytest.raises(WriteError) as raised:
        write_atomic(tmp_path / "missing" / "file.txt", b"x")
    assert isinstance(raised.value, OSError) and isinstance(raised.value, InputError)
    assert raised.value.strerror and "does not exist" in str(raised.value)
    (tmp_path / "folder.txt").mkdir()
    with pytest.raises(WriteError, match="is a folder"):
        write_atomic(tmp_path / "folder.txt", b"x")
