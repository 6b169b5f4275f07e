"""Qualisys TSV, TRC and CSV takes, `load_take`/`save_take` dispatch, atomic writes, bad input, Take."""

from pathlib import Path

import numpy as np
import pytest

from handmocap.core.errors import InputError
from handmocap.core.evaluation.data import REAL_RECORDING
from handmocap.core.io import Take, TakeFormatError, load_take, save_take


def _take(
    n_frames: int = 20, first_frame: int = 7, names: tuple[str, ...] = ("hand_top", "thumb_tip", "a,b")
) -> Take:
    rng = np.random.default_rng(3)
    positions = rng.uniform(-900.0, 900.0, (n_frames, len(names), 3))
    positions[2:5, 1] = np.nan
    positions[0, 0] = np.nan
    return Take(list(names), positions, frame_rate=120.0, first_frame=first_frame)


def _assert_same(copy: Take, take: Take) -> None:
    assert copy.marker_names == take.marker_names
    assert copy.frame_rate == pytest.approx(take.frame_rate, rel=1e-9)
    assert copy.first_frame == take.first_frame
    np.testing.assert_array_equal(copy.missing_mask, take.missing_mask)
    np.testing.assert_allclose(copy.marker_positions, take.marker_positions, atol=1e-5)


def _assert_one_line(error: pytest.ExceptionInfo[TakeFormatError], path: Path) -> None:
    message = str(error.value)
    assert "\n" not in message and message.startswith(f"{path.name}: "), message


def test_real_qualisys_tsv() -> None:
    if not REAL_RECORDING.is_file():
        pytest.skip(f"{REAL_RECORDING} is absent")
    take = load_take(REAL_RECORDING)
    assert (take.n_frames, take.n_markers, take.frame_rate, take.first_frame) == (3000, 21, 100.0, 1)
    assert {"hand_top", "thumb_tip", "index_tip", "pillow_right"} <= set(take.marker_names)
    assert take.vendor == "Qualisys" and take.source_units == "mm"
    assert take.duration_s == pytest.approx(30.0)
    np.testing.assert_allclose(
        take.marker_positions[0, take.marker_names.index("hand_top")], [110.406, 135.075, 460.584]
    )
    thumb = take.marker_names.index("thumb_tip")
    lines = REAL_RECORDING.read_text().splitlines()
    data_rows = [
        line.split("\t") for line in lines[lines.index(next(x for x in lines if x.startswith("Frame"))) + 1 :]
    ]
    file_gaps = np.array([row[2 + 3 * thumb].lower() == "nan" for row in data_rows])
    assert file_gaps.sum() == 175
    np.testing.assert_array_equal(take.missing_mask[:, thumb], file_gaps)
    assert take.missing_fraction_per_marker[take.marker_names.index("hand_top")] == 0.0


def test_tsv_variants(tmp_path: Path) -> None:
    header = (
        "NO_OF_FRAMES\t3\nNO_OF_MARKERS\t2\nFREQUENCY\t200\nDATA_INCLUDED\t3D\nMARKER_NAMES\tfoo\tbar\t\n"
    )
    with_columns = (
        header + "Frame\tTime\tfoo X\tfoo Y\tfoo Z\tbar X\tbar Y\tbar Z\t\n"
        "5\t0.000\t1.0\t2.0\t3.0\t0.000\t0.000\t0.000\n"
        "6\t0.005\t\t\t\t4.0\t5.0\t6.0\n"
        "7\t0.010\tnan\tnan\tnan\t7.0\t8.0\t9.0\t\n"
    )
    duplicates = (
        "FREQUENCY\t100\nMARKER_NAMES\tfoo\tfoo\nFrame\tfoo X\tfoo Y\tfoo Z\tfoo X\tfoo Y\tfoo Z\n"
        "1\t1\t2\t3\t4\t5\t6\n"
    )
    (tmp_path / "duplicates.tsv").write_text(duplicates)
    take = load_take(tmp_path / "duplicates.tsv")
    assert take.marker_names == ["foo", "foo_2"]
    np.testing.assert_allclose(take.marker_positions[0], [[1, 2, 3], [4, 5, 6]])
    bare = header + "1.0\t2.0\t3.0\t0\t0\t0\n\t\t\t4.0\t5.0\t6.0\n1.5\t2.5\t3.5\t7.0\t8.0\t9.0\n"
    for name, text, first_frame in (("columns.tsv", with_columns, 5), ("bare.tsv", bare, 1)):
        (tmp_path / name).write_text(text)
        take = load_take(tmp_path / name)
        assert take.marker_names == ["foo", "bar"] and take.frame_rate == 200.0
        assert take.first_frame == first_frame and take.n_frames == 3
        np.testing.assert_array_equal(
            take.missing_mask, [[False, True], [True, False], [name == "columns.tsv", False]]
        )
        np.testing.assert_allclose(take.marker_positions[1, 1], [4.0, 5.0, 6.0])


@pytest.mark.parametrize("suffix", [".trc", ".csv", ".c3d", ".CSV", ".Trc"])
def test_round_trip_keeps_names_rate_first_frame_and_gaps(tmp_path: Path, suffix: str) -> None:
    take = _take(names=("hand_top", "thumb_tip", "index tip 2"))
    save_take(take, tmp_path / f"take{suffix}")
    _assert_same(load_take(tmp_path / f"take{suffix}"), take)
    assert [path.name for path in tmp_path.iterdir()] == [f"take{suffix}"]  # no temporary file left


def test_csv_format_details(tmp_path: Path) -> None:
    take = _take()  # a name with a comma is quoted
    save_take(take, tmp_path / "take.csv")
    lines = (tmp_path / "take.csv").read_text().splitlines()
    assert lines[0] == "# handmocap take: frame_rate=120.0, units=mm"
    assert (
        lines[1] == "frame,time,hand_top_x,hand_top_y,hand_top_z,thumb_tip_x,thumb_tip_y,thumb_tip_z,"
        '"a,b_x","a,b_y","a,b_z"'
    )
    assert lines[2].startswith("7,0.000000,,,,")
    copy = load_take(tmp_path / "take.csv")
    _assert_same(copy, take)
    assert copy.vendor == "handmocap"
    # Hand-made: no rate line (rate from the time column), metres, no frame column.
    (tmp_path / "hand.csv").write_text("# units=m\ntime,p_x,p_y,p_z\n0.00,1,2,3\n0.02,1.5,,\n0.04,0,0,0\n")
    hand = load_take(tmp_path / "hand.csv")
    assert hand.frame_rate == pytest.approx(50.0) and hand.first_frame == 1 and hand.source_units == "m"
    np.testing.assert_allclose(hand.marker_positions[0, 0], [1000.0, 2000.0, 3000.0])
    np.testing.assert_array_equal(hand.missing_mask[:, 0], [False, True, True])


def test_trc_in_metres_and_header(tmp_path: Path) -> None:
    text = (
        "PathFileType\t4\t(X/Y/Z)\twalk.trc\n"
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n"
        "60.00\t60.00\t2\t2\tm\t60.00\t10\t2\n"
        "Frame#\tTime\tLASI\t\t\tRASI\t\t\n"
        "\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n"
        "\n"
        "10\t0.000\t0.1\t0.2\t0.3\t\t\t\n"
        "11\t0.017\t0.1\t0.2\t0.31\t1.0\t1.1\t1.2\n"
    )
    (tmp_path / "walk.trc").write_text(text)
    take = load_take(tmp_path / "walk.trc")
    assert take.marker_names == ["LASI", "RASI"] and take.frame_rate == 60.0 and take.first_frame == 10
    assert take.source_units == "m"
    np.testing.assert_allclose(take.marker_positions[1], [[100.0, 200.0, 310.0], [1000.0, 1100.0, 1200.0]])
    assert np.isnan(take.marker_positions[0, 1]).all()
    save_take(take, tmp_path / "copy.trc")
    lines = (tmp_path / "copy.trc").read_text().splitlines()
    assert lines[0] == "PathFileType\t4\t(X/Y/Z)\tcopy.trc"
    assert lines[2].split("\t") == ["60.0", "60.0", "2", "2", "mm", "60.0", "10", "2"]
    assert lines[3] == "Frame#\tTime\tLASI\t\t\tRASI\t\t"


def test_bad_input_raises_one_line_take_format_errors(tmp_path: Path) -> None:
    cases = {
        "missing.c3d": (None, "file not found"),
        "take.bvh": ("HIERARCHY\n", "unsupported file type '.bvh'"),
        "empty.tsv": ("", "file is empty"),
        "empty.trc": ("", "file is empty"),
        "empty.csv": ("", "file is empty"),
        "text.tsv": ("hello\nworld\n", "not a Qualisys TSV file"),
        "text.trc": ("hello\nworld\n", "not a TRC file"),
        "text.csv": ("hello,world\n1,2\n", "expected columns"),
        "no_rate.tsv": ("MARKER_NAMES\ta\n1\t2\t3\n", "FREQUENCY"),
        "zero_frames.tsv": ("FREQUENCY\t100\nMARKER_NAMES\ta\n", "contains no frames"),
        "zero_markers.tsv": ("FREQUENCY\t100\nMARKER_NAMES\n\n1\n", "contains no markers"),
        "zero_frames.csv": ("# frame_rate=100\nframe,time,a_x,a_y,a_z\n", "contains no frames"),
        "bad_number.csv": (
            "# frame_rate=100\nframe,time,a_x,a_y,a_z\n1,0,1,2,3\n2,0.01,1,two,3\n",
            "line 4, column 4: 'two' is not a number",
        ),
        "no_rate.csv": ("a_x,a_y,a_z\n1,2,3\n", "no frame rate"),
        "bad_units.csv": ("# frame_rate=100 units=furlong\na_x,a_y,a_z\n1,2,3\n", "unsupported length units"),
        "bad_rate.trc": (
            "PathFileType\t4\nDataRate\nabc\nFrame#\tTime\ta\n\t\tX1\tY1\tZ1\n",
            "invalid DataRate",
        ),
        "zero_frames.trc": (
            "PathFileType\t4\nDataRate\tUnits\n100\tmm\nFrame#\tTime\ta\n\t\tX1\tY1\tZ1\n",
            "contains no frames",
        ),
        "binary.csv": (bytes(range(256)) * 4, "expected columns"),
    }
    (tmp_path / "folder.c3d").mkdir()
    with pytest.raises(TakeFormatError, match="not a file"):
        load_take(tmp_path / "folder.c3d")
    for name, (content, expected) in cases.items():
        path = tmp_path / name
        if isinstance(content, bytes):
            path.write_bytes(content)
        elif content is not None:
            path.write_text(content)
        with pytest.raises(TakeFormatError, match=expected) as error:
            load_take(path)
        _assert_one_line(error, path)
        assert isinstance(error.value, InputError)


def test_save_take_errors_leave_existing_files_untouched(tmp_path: Path) -> None:
    target = tmp_path / "take.trc"
    target.write_text("previous content")
    bad_name = Take(["tab\tname"], np.ones((2, 1, 3)), frame_rate=100.0)
    with pytest.raises(TakeFormatError, match="tab or line break"):
        save_take(bad_name, target)
    with pytest.raises(TakeFormatError, match="cannot write file type '.tsv'"):
        save_take(_take(), tmp_path / "take.tsv")
    with pytest.raises(TakeFormatError, match="does not exist"):
        save_take(_take(), tmp_path / "missing" / "take.csv")
    with pytest.raises(TakeFormatError, match="nothing to write"):
        save_take(Take([], np.empty((0, 0, 3)), frame_rate=100.0), tmp_path / "take.csv")
    assert target.read_text() == "previous content"
    assert [path.name for path in tmp_path.iterdir()] == ["take.trc"]


def test_take_validation_and_properties() -> None:
    positions = np.zeros((4, 2, 3))
    positions[0, 0] = np.nan
    positions[1:3, 1] = np.nan
    take = Take(["a", "b"], positions, frame_rate=50.0, first_frame=11)
    assert (take.n_frames, take.n_markers, take.duration_s) == (4, 2, 0.08)
    assert take.missing_fraction == pytest.approx(3 / 8)
    np.testing.assert_allclose(take.missing_fraction_per_marker, [0.25, 0.5])
    bad = {
        "shape": dict(marker_names=["a"], marker_positions=np.zeros((4, 3)), frame_rate=50.0),
        "1 marker names for 2": dict(
            marker_names=["a"], marker_positions=np.zeros((4, 2, 3)), frame_rate=50.0
        ),
        "duplicate marker name 'a'": dict(
            marker_names=["a", "a"], marker_positions=np.zeros((4, 2, 3)), frame_rate=50.0
        ),
        "frame rate": dict(marker_names=["a"], marker_positions=np.zeros((4, 1, 3)), frame_rate=0.0),
        "first frame": dict(
            marker_names=["a"], marker_positions=np.zeros((4, 1, 3)), frame_rate=9.0, first_frame=-1
        ),
        "infinite": dict(marker_names=["a"], marker_positions=np.full((4, 1, 3), np.inf), frame_rate=9.0),
    }
    for expected, arguments in bad.items():
        with pytest.raises(TakeFormatError, match=expected):
            Take(**arguments)
