"""The text exports labs make (Vicon Nexus, OptiTrack Motive, NOKOV, any CSV of axis columns): names, rate,
units to mm, missing samples, frame numbers; the rate a file lacks comes from the caller; hostile variants fail
with one line naming the file. The fixtures copy the header structure of real public exports (fixtures/README)."""

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from handmocap.core.errors import InputError
from handmocap.core.evaluation.data import SHARED_DATA
from handmocap.core.io import (
    READ_SUFFIXES,
    TAKE_FILE_FILTER,
    TAKE_FORMATS,
    FrameRateMissingError,
    TakeFormatError,
    is_marker_label,
    load_take,
    looks_unlabelled,
    save_take,
    take_format,
)

FIXTURES = Path(__file__).parent / "fixtures"
GUITAR = SHARED_DATA / "guitar" / "nokov_guitarist_arpeggio.csv"


def _one_line(error: pytest.ExceptionInfo, path: Path) -> str:
    message = str(error.value)
    assert "\n" not in message and message.startswith(f"{path.name}: "), message
    assert isinstance(error.value, InputError)
    return message


def test_every_format_is_registered_once_for_the_loader_and_the_file_dialog():
    assert set(READ_SUFFIXES) == {".c3d", ".tsv", ".trc", ".csv", ".txt"}
    for fmt in TAKE_FORMATS:
        assert fmt.name in TAKE_FILE_FILTER
    assert TAKE_FILE_FILTER.startswith("Motion capture takes (*.c3d *.tsv *.trc *.csv *.txt)")
    names = {path.name: take_format(path).name for path in FIXTURES.glob("*.csv")}
    assert names == {"vicon_nexus.csv": "Vicon Nexus CSV/TXT", "motive_1.21.csv": "OptiTrack Motive CSV",
                     "motive_1.23.csv": "OptiTrack Motive CSV", "motive_1.25_skeleton.csv": "OptiTrack Motive CSV",
                     "nokov.csv": "NOKOV CSV"}


# ------------------------------------------------------------------------------------------ Vicon Nexus
def test_vicon_nexus_trajectories_block_between_other_blocks():
    take = load_take(FIXTURES / "vicon_nexus.csv")
    assert take.vendor == "Vicon" and take.frame_rate == 100.0 and not take.frame_rate_given
    assert take.marker_names == ["Pianist:RTHM1", "Pianist:RIDX3", "Pianist:RWRA"]   # Subject:Marker as given
    assert take.n_frames == 4 and take.first_frame == 12                              # Devices, Model Outputs left
    np.testing.assert_allclose(take.marker_positions[0, 0], [412.305, -88.214, 903.117])
    assert np.isnan(take.marker_positions[0, 2]).all()                                # empty cells
    assert np.isnan(take.marker_positions[2, 1]).all()                                # exactly 0,0,0
    np.testing.assert_allclose(take.marker_positions[3, 2], [371.38, -120.52, 862.04])


def test_vicon_nexus_txt_tab_separated_and_metres(tmp_path):
    text = (FIXTURES / "vicon_nexus.csv").read_text()
    block = text[text.index("Trajectories"):text.index("Model Outputs")].rstrip().rsplit("\n", 1)[0]
    block = block.replace(",mm", ",m").replace("412.305,-88.214,903.117", "0.412305,-0.088214,0.903117")
    path = tmp_path / "trial01.txt"
    path.write_text("\n".join(line.replace(",", "\t") for line in ["", ""] + block.splitlines()) + "\n")
    take = load_take(path)
    assert take_format(path).name == "Vicon Nexus CSV/TXT"
    np.testing.assert_allclose(take.marker_positions[0, 0], [412.305, -88.214, 903.117])
    assert take.source_units == "m" and take.n_frames == 4


# --------------------------------------------------------------------------------------------- Motive
def test_motive_1_23_markers_in_mm_z_up_without_rigid_body_poses():
    take = load_take(FIXTURES / "motive_1.23.csv")
    assert take.vendor == "OptiTrack" and take.frame_rate == 120.0 and take.first_frame == 0
    # the Rigid Body Marker and the Marker of the same name both kept; the rigid body's pose is no marker
    assert take.marker_names == ["wrist_plate:Marker1", "wrist_plate:Marker1_2", "thumb_tip", "Unlabeled 1003"]
    # metres to mm; Motive's Y up (x, y, z) to our Z up (x, -z, y)
    np.testing.assert_allclose(take.marker_positions[0, 2], [180.4, 210.6, 1002.1])
    assert np.isnan(take.marker_positions[0, 3]).all() and np.isnan(take.marker_positions[2, 1]).all()
    assert np.isnan(take.marker_positions[3, 2]).all()                                # exactly 0,0,0
    assert [is_marker_label(name) for name in take.marker_names] == [True, True, True, False]


def test_motive_1_21_without_label_cells_uses_the_export_rate():
    take = load_take(FIXTURES / "motive_1.21.csv")
    assert take.frame_rate == 60.0 and take.n_frames == 3 and take.source_units == "Millimeters"
    assert take.marker_names == ["Rigid Body 1_1", "Unlabeled:108", "Rigid Body 1:Marker1"]
    np.testing.assert_allclose(take.marker_positions[0, 1], [-610.34, -2411.902, 702.115])
    assert np.isnan(take.marker_positions[1, 1]).all()
    assert not is_marker_label("Unlabeled:108")


def test_motive_1_25_parent_row_bone_markers_and_centimetres():
    take = load_take(FIXTURES / "motive_1.25_skeleton.csv")
    assert take.marker_names == ["Actor:RHandOut", "Unlabeled 1000", "Unlabeled 1001"]
    assert take.frame_rate == 240.0 and take.first_frame == 88210
    np.testing.assert_allclose(take.marker_positions[1, 2], [600.0, -2800.0, 520.0])
    assert np.isnan(take.marker_positions[0, 2]).all()


# ---------------------------------------------------------------------------------------------- NOKOV
def test_nokov_has_no_rate_and_reads_with_the_given_one():
    path = FIXTURES / "nokov.csv"
    with pytest.raises(FrameRateMissingError) as error:
        load_take(path)
    assert _one_line(error, path) == "nokov.csv: the file has no frame rate; give it with --rate HZ"
    take = load_take(path, frame_rate=120)
    assert take.vendor == "NOKOV" and take.frame_rate == 120.0 and take.frame_rate_given
    assert take.marker_names == ["Marker1", "L-A1", "R-Wan-nei"] and take.first_frame == 1
    assert np.isnan(take.marker_positions[1, 1]).all() and np.isnan(take.marker_positions[2, 2]).all()
    np.testing.assert_allclose(take.marker_positions[0, 2], [302.174563, -133.902115, 845.310774])
    assert not looks_unlabelled(take.marker_names)


@pytest.mark.skipif(not GUITAR.exists(), reason=f"{GUITAR} is absent")
def test_the_real_guitar_take_reads_at_the_given_rate_and_keeps_its_labels():
    with pytest.raises(FrameRateMissingError) as error:
        load_take(GUITAR)
    _one_line(error, GUITAR)
    take = load_take(GUITAR, frame_rate=120.0)
    assert take.vendor == "NOKOV" and take.frame_rate == 120.0 and take.n_markers == 42
    assert take.n_frames == 2968 and take.duration_s == pytest.approx(2968 / 120)
    assert take.marker_names[:5] == ["Marker1", "Marker2", "Marker3", "Marker4", "L-A1"]
    assert "R-Wan-nei" in take.marker_names and all(is_marker_label(name) for name in take.marker_names)
    assert 0.0 < take.missing_fraction < 0.2
    assert np.nanmax(np.abs(take.marker_positions)) < 5000      # mm


# ------------------------------------------------------------------------------------ any axis CSV
@pytest.mark.parametrize("columns", [
    "frame,time,thumb_tip_x,thumb_tip_y,thumb_tip_z,wrist_x,wrist_y,wrist_z",
    "Frame,Time (s),thumb_tip-X,thumb_tip-Y,thumb_tip-Z,wrist-X,wrist-Y,wrist-Z",
    "Frame#,Time (Seconds),thumb_tip.X,thumb_tip.Y,thumb_tip.Z,wrist.X,wrist.Y,wrist.Z",
    "frame_number,time_s,thumb_tip X,thumb_tip Y,thumb_tip Z,wrist X,wrist Y,wrist Z",
])
def test_csv_of_axis_columns_with_frame_and_time(tmp_path, columns):
    path = tmp_path / "take.csv"
    path.write_text(f"{columns}\n7,0.00,1,2,3,4,5,6\n8,0.02,1.5,2.5,3.5,,,\n9,0.04,0,0,0,4,5,6\n")
    take = load_take(path)
    assert take.marker_names == ["thumb_tip", "wrist"] and take.frame_rate == pytest.approx(50.0)
    assert take.first_frame == 7 and take.n_frames == 3
    assert np.isnan(take.marker_positions[1, 1]).all() and np.isnan(take.marker_positions[2, 0]).all()


def test_csv_time_in_milliseconds_tabs_and_the_rate_setting(tmp_path):
    path = tmp_path / "take.txt"
    path.write_text("Time (ms)\ta_x\ta_y\ta_z\n0\t1\t2\t3\n5\t1\t2\t3\n10\t1\t2\t3\n")
    assert load_take(path).frame_rate == pytest.approx(200.0)
    path = tmp_path / "take.csv"
    path.write_text("# frame_rate=250\nframe,time,a_x,a_y,a_z\n1,0,1,2,3\n2,0.01,1,2,3\n")
    assert load_take(path).frame_rate == 250.0                     # the setting before the time column


def test_our_own_csv_still_reads_back(tmp_path):
    take = load_take(FIXTURES / "nokov.csv", 120.0)
    save_take(take, tmp_path / "ours.csv")
    back = load_take(tmp_path / "ours.csv")
    assert back.vendor == "handmocap" and back.frame_rate == 120.0 and not back.frame_rate_given
    assert back.marker_names == take.marker_names
    np.testing.assert_allclose(back.marker_positions, take.marker_positions, atol=1e-6)


# ------------------------------------------------------------------------------------------- the rate
@pytest.mark.parametrize("name", ["vicon_nexus.csv", "motive_1.23.csv"])
def test_a_given_rate_overrides_the_files(name):
    take = load_take(FIXTURES / name, frame_rate=250)
    assert take.frame_rate == 250.0 and take.frame_rate_given


def test_a_given_rate_overrides_tsv_trc_and_c3d(tmp_path):
    take = load_take(FIXTURES / "nokov.csv", 120.0)
    for suffix in (".trc", ".c3d"):
        save_take(take, tmp_path / f"t{suffix}")
        assert load_take(tmp_path / f"t{suffix}").frame_rate == pytest.approx(120.0)
        assert load_take(tmp_path / f"t{suffix}", frame_rate=90.0).frame_rate == 90.0
    tsv = tmp_path / "no_rate.tsv"
    tsv.write_text("FREQUENCY\tEXT\nMARKER_NAMES\ta\n1\t2\t3\n")
    with pytest.raises(FrameRateMissingError, match="FREQUENCY"):
        load_take(tsv)
    assert load_take(tsv, 100.0).frame_rate == 100.0


@pytest.mark.parametrize("rate", [0, -5, math.nan, math.inf, "fast"])
def test_a_given_rate_must_be_a_positive_number(rate):
    path = FIXTURES / "nokov.csv"
    with pytest.raises(TakeFormatError, match="positive number of Hz") as error:
        load_take(path, frame_rate=rate)
    _one_line(error, path)


# ------------------------------------------------------------------------------------------- hostile
VICON_HEAD = "Trajectories\n100\n,,S:a,,,S:b,,\nFrame,Sub Frame,X,Y,Z,X,Y,Z\n,,mm,mm,mm,mm,mm,mm\n"
MOTIVE_HEAD = ("Format Version,1.23,Take Name,t,Capture Frame Rate,120,Export Frame Rate,120,Length Units,Meters\n\n"
               ",Type,Marker,Marker,Marker\n,Name,a,a,a\n,ID,1,1,1\n,,Position,Position,Position\n")


@pytest.mark.parametrize("name, content, expected", [
    ("vicon_cut.csv", "Trajectories\n100\n,,S:a,,,\n", "ends before its data"),
    ("vicon_axes.csv", "Trajectories\n100\n,,S:a,,,\nFrame,Sub Frame,X,Y\n,,mm,mm\n1,0,1,2\n",
     "expected 'Frame,Sub Frame,X,Y,Z"),
    ("vicon_no_rate.csv", "Devices\n1000\n,,FP\nFrame,Sub Frame,Fx\n,,N\n1,0,1\n", "no Trajectories block"),
    ("vicon_rate.csv", VICON_HEAD.replace("100", "abc", 1) + "1,0,1,2,3,4,5,6\n", "give it with --rate"),
    ("vicon_text.csv", VICON_HEAD + "1,0,1,2,three,4,5,6\n", "'three' is not a number"),
    ("vicon_units.csv", VICON_HEAD.replace(",mm,mm,mm,mm,mm,mm", ",in,in,in,in,in,in") + "1,0,1,2,3,4,5,6\n",
     "unsupported length units"),
    ("vicon_empty.csv", VICON_HEAD, "contains no frames"),
    ("motive_cut.csv", MOTIVE_HEAD, "ends before its 'Frame"),
    ("motive_bodies.csv", MOTIVE_HEAD.replace("Marker", "Rigid Body") + "Frame,Time (Seconds),X,Y,Z\n0,0,1,2,3\n",
     "no marker positions"),
    ("motive_header.csv", "Format Version,1.23\n" + ",,x\n" * 20, "no 'Frame,Time"),
    ("motive_rows.csv", "Format Version,1.23,Export Frame Rate,120\n,,Position\nFrame,Time,X,Y,Z\n0,0,1,2,3\n",
     "1 header rows"),
    ("motive_units.csv", MOTIVE_HEAD.replace("Meters", "Furlongs") + "Frame,Time (Seconds),X,Y,Z\n0,0,1,2,3\n",
     "unsupported length units"),
    ("motive_rate.csv", MOTIVE_HEAD.replace("Export Frame Rate,120", "Export Frame Rate,0").replace(
        "Capture Frame Rate,120", "Capture Frame Rate,0") + "Frame,Time (Seconds),X,Y,Z\n0,0,1,2,3\n",
     "Export Frame Rate"),
    ("nokov_count.csv", "a-X,a-Y,a-Z,b-X\n1,2,3,4\n", "expected columns"),
    ("nokov_order.csv", "a-Y,a-X,a-Z\n1,2,3\n", "of one marker in that order"),
    ("axis_quote.csv", 'a_x,"a_y\n1,2\n', "expected columns"),
    ("garbage.txt", "\x00\x01binary\xff\n" * 40, "expected columns"),
])
def test_hostile_exports_fail_with_one_line(tmp_path, name, content, expected):
    path = tmp_path / name
    path.write_text(content)
    with pytest.raises(TakeFormatError, match=expected) as error:
        load_take(path, frame_rate=None)
    _one_line(error, path)


def test_ragged_rows_are_padded_or_cut(tmp_path):
    path = tmp_path / "ragged.csv"
    path.write_text(VICON_HEAD + "1,0,1,2,3\n2,0,1,2,3,4,5,6,7,8,9\n3,0\n")
    take = load_take(path)
    assert take.n_frames == 3 and np.isnan(take.marker_positions[0, 1]).all()
    np.testing.assert_allclose(take.marker_positions[1, 1], [4, 5, 6])
    assert np.isnan(take.marker_positions[2]).all()
    nokov = tmp_path / "ragged_nokov.csv"
    nokov.write_text("a-X,a-Y,a-Z\n1,2\n1,2,3,4,5\n")
    take = load_take(nokov, frame_rate=100)
    assert np.isnan(take.marker_positions[0, 0, 2]) and take.marker_positions[1, 0, 2] == 3


def test_a_vicon_export_named_txt_or_a_copy_named_csv_is_read_by_content(tmp_path):
    for name in ("trial.txt", "trial.csv"):
        shutil.copy(FIXTURES / "vicon_nexus.csv", tmp_path / name)
        assert load_take(tmp_path / name).marker_names[0] == "Pianist:RTHM1"
