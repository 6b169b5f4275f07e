"""C3D reading (every sample file, compared with ezc3d and `c3d`), writing and malformed input."""

import subprocess
import sys
import warnings
from pathlib import Path

import c3d
import ezc3d
import numpy as np
import pytest

from handmocap.core.evaluation.data import VENDOR_C3D
from handmocap.core.io import Take, TakeFormatError, load_take, save_take
from handmocap.core.io.take import mm_per_unit, unique_marker_names

C3D_FOLDER = VENDOR_C3D
SAMPLES = sorted(C3D_FOLDER.glob("*.c3d")) if C3D_FOLDER.is_dir() else []
SAMPLE_PARAMS = [pytest.param(path, id=path.stem) for path in SAMPLES] or [
    pytest.param(None, marks=pytest.mark.skip(reason=f"{C3D_FOLDER} is absent"))
]

# Sample files expected to fail, with the reason. None: every sample loads, the malformed ones
# through the recoveries listed in RECOVERED.
EXPECTED_FAILURES: dict[str, str] = {}
RECOVERED = {
    "sample_13__golfswing": "POINT:DATA_START is 0 (header pointer used); ezc3d rejects ANALOG:OFFSET",
    "sample_16__basketball": "every residual is -1 although coordinates are present; no POINT:UNITS (metres)",
    "sample_18__bad_parameter_section": "parameter section runs into the data; stops at EVENT:LABELS",
    "sample_20__phasespace_sample": "empty parameter section: header only, unnamed points named *1..*40",
}


def _load_sample(path: Path) -> Take:
    if path.stem in EXPECTED_FAILURES:
        with pytest.raises(TakeFormatError) as error:
            load_take(path)
        _assert_one_line(error.value, path)
        pytest.skip(f"expected failure: {EXPECTED_FAILURES[path.stem]} ({error.value})")
    return load_take(path)


def _assert_one_line(error: Exception, path: Path) -> None:
    message = str(error)
    assert "\n" not in message and message.startswith(f"{path.name}: "), message


@pytest.mark.parametrize("path", SAMPLE_PARAMS)
def test_sample_loads_with_plausible_content(path: Path) -> None:
    take = _load_sample(path)
    assert take.n_frames > 0 and take.n_markers > 0
    assert np.isfinite(take.frame_rate) and take.frame_rate > 0
    assert take.marker_positions.dtype == np.float64
    assert len(set(take.marker_names)) == take.n_markers
    assert take.first_frame >= 0
    assert 0.0 <= take.missing_fraction < 0.5
    valid = take.marker_positions[np.isfinite(take.marker_positions)]
    assert np.abs(valid).max() < 20_000  # mm: inside a 20 m room
    assert np.percentile(np.abs(valid), 99) > 100  # mm: not metres read as millimetres


def test_recovered_and_vendor_details() -> None:
    if not SAMPLES:
        pytest.skip(f"{C3D_FOLDER} is absent")
    takes = {path.stem: load_take(path) for path in SAMPLES}
    assert set(RECOVERED) <= set(takes)
    assert takes["sample_00__Motion_Analysis_Corporation__Walk1"].vendor == "Motion Analysis"
    assert takes["sample_37__ART-Human_hands_real_no6dof"].vendor == "ART"
    assert takes["sample_16__basketball"].source_units == "m"
    assert takes["sample_16__basketball"].missing_fraction == 0.0
    assert takes["sample_20__phasespace_sample"].marker_names[:2] == ["*1", "*2"]
    assert takes["sample_18__bad_parameter_section"].marker_names[:2] == ["P1", "P2"]
    assert takes["sample_13__golfswing"].frame_rate == pytest.approx(107.52688)
    # One recording stored as Intel int, Intel float, MIPS int and DEC float must read the same.
    reference = takes["sample_01__Eb015pi"]
    for stem in ("sample_01__Eb015pr", "sample_01__Eb015si", "sample_01__Eb015vr"):
        other = takes[stem]
        assert other.marker_names == reference.marker_names
        np.testing.assert_allclose(other.marker_positions, reference.marker_positions, atol=1e-3)
    np.testing.assert_allclose(
        takes["sample_02__sgi_real"].marker_positions, takes["sample_02__dec_int"].marker_positions, atol=1e-3
    )


def _compare_with_reference(take: Take, labels: list[str], xyz: np.ndarray, invalid: np.ndarray) -> None:
    """`xyz` (F, M, 3) in file units and `invalid` (F, M) from another reader, against `take`."""
    assert xyz.shape == take.marker_positions.shape
    if labels:  # made unique as the reader does (sample_00 has two RKNE)
        assert unique_marker_names(labels[: take.n_markers]) == take.marker_names
    xyz = xyz * mm_per_unit(take.source_units, None)
    ours_missing = take.missing_mask
    zero = (xyz == 0).all(axis=2)
    if not invalid.all():  # a file with every sample flagged is read from its coordinates (see RECOVERED)
        np.testing.assert_array_equal(ours_missing, invalid | zero)
    both = ~ours_missing & ~invalid
    np.testing.assert_allclose(take.marker_positions[both], xyz[both], rtol=1e-6, atol=1e-3)


# ezc3d reads the sample in a child process: it can abort on malformed files, this process must not.
_EZC3D_READ = """
import sys
import ezc3d
import numpy as np
c3d = ezc3d.c3d(sys.argv[1])
point = c3d["parameters"]["POINT"]
labels = list(point["LABELS"]["value"])
index = 2
while f"LABELS{index}" in point:
    labels += point[f"LABELS{index}"]["value"]
    index += 1
np.savez(sys.argv[2], points=c3d["data"]["points"], labels=np.array(labels, dtype=str),
         rate=point["RATE"]["value"][0], first_frame=c3d["header"]["points"]["first_frame"])
"""


@pytest.mark.parametrize("path", SAMPLE_PARAMS)
def test_sample_matches_ezc3d(path: Path, tmp_path: Path) -> None:
    take = _load_sample(path)
    output = tmp_path / "ezc3d.npz"
    result = subprocess.run(
        [sys.executable, "-c", _EZC3D_READ, str(path), str(output)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    if result.returncode != 0:
        reason = (result.stderr.strip().splitlines() or [f"exit code {result.returncode}"])[-1]
        pytest.skip(f"ezc3d cannot read it: {reason}")
    with np.load(output) as reference:
        xyz = reference["points"][:3].transpose(2, 1, 0)
        labels = list(reference["labels"])
        rate = float(reference["rate"])
        first_frame = int(reference["first_frame"])
    if xyz.size == 0:
        pytest.skip("ezc3d reads no points: it takes the point count from the (empty) parameter section")
    _compare_with_reference(take, labels, np.nan_to_num(xyz), np.isnan(xyz).any(axis=2))
    assert take.frame_rate == pytest.approx(rate, rel=1e-6)
    assert take.first_frame == first_frame + 1


@pytest.mark.parametrize("path", SAMPLE_PARAMS)
def test_sample_matches_c3d_package(path: Path) -> None:
    take = _load_sample(path)
    try:
        with warnings.catch_warnings(), path.open("rb") as handle:
            warnings.simplefilter("ignore")
            reader = c3d.Reader(handle)
            points = np.array([frame_points for _, frame_points, _ in reader.read_frames()])
            first_frame, rate = reader.first_frame, reader.point_rate
    except Exception as error:  # the c3d package raises many types
        pytest.skip(f"the c3d package cannot read it: {error}")
    labels = [] if reader.get("POINT:LABELS") is None else list(reader.point_labels)
    _compare_with_reference(take, labels, points[..., :3].astype(np.float64), points[..., 3] < 0)
    assert take.frame_rate == pytest.approx(rate, rel=1e-6)
    assert take.first_frame == first_frame


@pytest.mark.parametrize("path", SAMPLE_PARAMS)
def test_sample_round_trip_keeps_everything(path: Path, tmp_path: Path) -> None:
    take = _load_sample(path)
    save_take(take, tmp_path / "copy.c3d")
    copy = load_take(tmp_path / "copy.c3d")
    assert copy.marker_names == take.marker_names
    assert copy.frame_rate == take.frame_rate
    assert copy.first_frame == take.first_frame
    assert copy.vendor == "handmocap"
    np.testing.assert_array_equal(copy.missing_mask, take.missing_mask)
    np.testing.assert_allclose(copy.marker_positions, take.marker_positions, rtol=1e-6, atol=1e-3)
    for group, parameters in take.parameters.items():
        for name, value in parameters.items():
            if (group, name) in {
                ("TRIAL", "ACTUAL_START_FIELD"),
                ("TRIAL", "ACTUAL_END_FIELD"),
                ("MANUFACTURER", "COMPANY"),
                ("MANUFACTURER", "SOFTWARE"),
            }:
                continue
            copied = copy.parameters[group][name]
            if isinstance(value, str | list):
                assert copied == value, (group, name)
            else:
                np.testing.assert_allclose(copied, value, rtol=1e-6, err_msg=f"{group}:{name}")


def _synthetic_take(n_frames: int, n_markers: int, first_frame: int = 1, name_length: int = 8) -> Take:
    rng = np.random.default_rng(1)
    positions = rng.uniform(-1500.0, 1500.0, (n_frames, n_markers, 3))
    positions[rng.random((n_frames, n_markers)) < 0.05] = np.nan
    names = [f"m{index:03d}_".ljust(name_length, "x") for index in range(n_markers)]
    return Take(names, positions, frame_rate=240.0, first_frame=first_frame)


def test_written_c3d_reads_back_identically_with_ezc3d_and_c3d(tmp_path: Path) -> None:
    take = _synthetic_take(n_frames=40, n_markers=300, first_frame=101, name_length=45)  # > 255, > 30 chars
    take.parameters = {
        "HANDMOCAP": {
            "VERSION": "0.1.0",
            "IDS": np.array([1, 2, 3]),
            "GAIN": 2.5,
            "NAMES": ["left", "right"],
            "MATRIX": np.arange(6.0).reshape(2, 3),
        }
    }
    path = tmp_path / "take.c3d"
    save_take(take, path)

    ours = load_take(path)
    assert ours.marker_names == take.marker_names
    assert (ours.frame_rate, ours.first_frame) == (240.0, 101)
    np.testing.assert_array_equal(ours.missing_mask, take.missing_mask)
    np.testing.assert_allclose(ours.marker_positions, take.marker_positions, rtol=1e-6, atol=1e-3)
    assert ours.parameters["HANDMOCAP"]["VERSION"] == "0.1.0"
    assert ours.parameters["HANDMOCAP"]["NAMES"] == ["left", "right"]
    assert ours.parameters["HANDMOCAP"]["GAIN"] == 2.5
    np.testing.assert_array_equal(ours.parameters["HANDMOCAP"]["IDS"], [1, 2, 3])
    np.testing.assert_array_equal(ours.parameters["HANDMOCAP"]["MATRIX"], np.arange(6.0).reshape(2, 3))

    with_ezc3d = ezc3d.c3d(str(path))
    point = with_ezc3d["parameters"]["POINT"]
    assert list(point["LABELS"]["value"]) + list(point["LABELS2"]["value"]) == take.marker_names
    assert point["RATE"]["value"][0] == 240.0
    assert with_ezc3d["header"]["points"]["first_frame"] + 1 == 101
    xyz = with_ezc3d["data"]["points"][:3].transpose(2, 1, 0)
    np.testing.assert_array_equal(np.isnan(xyz), np.isnan(take.marker_positions))
    np.testing.assert_allclose(xyz, take.marker_positions, rtol=1e-6, atol=1e-3)

    with warnings.catch_warnings(), path.open("rb") as handle:
        warnings.simplefilter("ignore")
        reader = c3d.Reader(handle)
        labels = list(reader.point_labels) + list(reader.get("POINT:LABELS2").string_array)
        assert [label.strip() for label in labels] == take.marker_names
        assert (reader.point_rate, reader.first_frame) == (240.0, 101)
        points = np.array([frame_points for _, frame_points, _ in reader.read_frames()])
    np.testing.assert_array_equal(points[..., 3] == -1, take.missing_mask)
    valid = ~take.missing_mask
    np.testing.assert_allclose(points[..., :3][valid], take.marker_positions[valid], rtol=1e-6, atol=1e-3)


@pytest.mark.parametrize("first_frame", [0, 1, 70_000])
def test_first_frame_numbers_round_trip(tmp_path: Path, first_frame: int) -> None:
    take = _synthetic_take(n_frames=5, n_markers=2, first_frame=first_frame)
    save_take(take, tmp_path / "take.c3d")
    assert load_take(tmp_path / "take.c3d").first_frame == first_frame
    if first_frame <= 0xFFFF:  # c3d 0.6 decodes the high word of ACTUAL_START_FIELD as x 65535, not 65536
        with warnings.catch_warnings(), (tmp_path / "take.c3d").open("rb") as handle:
            warnings.simplefilter("ignore")
            assert c3d.Reader(handle).first_frame == first_frame


def test_more_than_65535_frames(tmp_path: Path) -> None:
    take = _synthetic_take(n_frames=70_000, n_markers=2)
    save_take(take, tmp_path / "long.c3d")
    copy = load_take(tmp_path / "long.c3d")
    assert copy.n_frames == 70_000
    np.testing.assert_allclose(copy.marker_positions, take.marker_positions, rtol=1e-6, atol=1e-3)
    with warnings.catch_warnings(), (tmp_path / "long.c3d").open("rb") as handle:
        warnings.simplefilter("ignore")
        reader = c3d.Reader(handle)
        assert reader.last_frame - reader.first_frame + 1 == 70_000
    # ezc3d 1.7.2 reads only the first 65535 frames of any file (it ignores TRIAL:ACTUAL_END_FIELD).


@pytest.mark.parametrize(("units", "factor"), [("m", 1000.0), ("cm", 10.0), ("mm", 1.0)])
def test_point_units_are_converted_to_mm(tmp_path: Path, units: str, factor: float) -> None:
    writer = ezc3d.c3d()
    writer["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    writer["parameters"]["POINT"]["LABELS"]["value"] = ["a", "b"]
    writer["parameters"]["POINT"]["UNITS"]["value"] = [units]
    points = np.ones((4, 2, 3))
    points[:3] = np.array([1.25, -0.5, 2.0])[:, np.newaxis, np.newaxis]
    writer["data"]["points"] = points
    writer.write(str(tmp_path / "units.c3d"))
    take = load_take(tmp_path / "units.c3d")
    assert take.source_units == units
    np.testing.assert_allclose(take.marker_positions[0, 0], np.array([1.25, -0.5, 2.0]) * factor)


def _one_frame_c3d(tmp_path: Path) -> bytes:
    """A one-frame, one-marker C3D written by the `c3d` package (no TRIAL group)."""
    writer = c3d.Writer(point_rate=100.0)
    writer.add_frames([(np.array([[10.0, 20.0, 30.0, 0.0, 0.0]], dtype=np.float32), np.zeros((0, 0)))])
    writer.set_point_labels(["a"])
    with warnings.catch_warnings(), (tmp_path / "one.c3d").open("wb") as handle:
        warnings.simplefilter("ignore")
        writer.write(handle)
    take = load_take(tmp_path / "one.c3d")
    assert take.marker_names == ["a"] and take.marker_positions.tolist() == [[[10.0, 20.0, 30.0]]]
    return (tmp_path / "one.c3d").read_bytes()


def test_malformed_c3d_files_raise_one_line_errors(tmp_path: Path) -> None:
    good = _one_frame_c3d(tmp_path)
    data_start = (good[16] - 1) * 512  # header word 9: first block of the data section
    zero_frames = bytearray(good)
    zero_frames[8:10] = bytes(2)  # header last frame 0 < first frame 1
    end_field = good.index(b"ACTUAL_END_FIELD") + len(b"ACTUAL_END_FIELD") + 5  # offset, type, 1 dim, size
    zero_frames[end_field : end_field + 4] = bytes(4)  # TRIAL:ACTUAL_END_FIELD 0
    text = b"This is a plain text file, renamed to .c3d by mistake.\n" * 20
    cases = {
        "empty.c3d": (b"", "file is empty"),
        "text.c3d": (text, "not a C3D file"),
        "header_only.c3d": (good[:512], "truncated"),
        "truncated.c3d": (good[: data_start + 8], "truncated"),
        "zero_frames.c3d": (bytes(zero_frames), "contains no frames"),
    }
    for name, (content, expected) in cases.items():
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(TakeFormatError, match=expected) as error:
            load_take(path)
        _assert_one_line(error.value, path)


@pytest.mark.parametrize("path", SAMPLE_PARAMS)
def test_damaged_c3d_files_never_crash(path: Path, tmp_path: Path) -> None:
    """Truncations every 128 bytes and random damage to header and parameters: load or TakeFormatError."""
    source = np.frombuffer(path.read_bytes(), np.uint8)
    rng = np.random.default_rng(0)
    variants = [source[:size].tobytes() for size in range(0, min(source.size, 8192), 128)]
    for _ in range(100):
        damaged = source.copy()
        damaged[rng.integers(0, min(source.size, 6144), 8)] = rng.integers(0, 256, 8)
        variants.append(damaged.tobytes())
    damaged_path = tmp_path / "damaged.c3d"
    for content in variants:
        damaged_path.write_bytes(content)
        try:
            take = load_take(damaged_path)
        except TakeFormatError as error:
            _assert_one_line(error, damaged_path)
        else:
            assert take.n_frames > 0 and take.n_markers > 0


def test_c3d_writer_rejects_what_c3d_cannot_hold(tmp_path: Path) -> None:
    take = _synthetic_take(n_frames=3, n_markers=2)
    take.parameters = {"POINT": {"X_SCREEN": "+X"}}
    with pytest.raises(TakeFormatError, match="POINT"):
        save_take(take, tmp_path / "take.c3d")
    take.parameters = {"MY GROUP": {"X": 1}}
    with pytest.raises(TakeFormatError, match="not a C3D name"):
        save_take(take, tmp_path / "take.c3d")
    take.parameters = {"HANDMOCAP": {"X": {"nested": 1}}}
    with pytest.raises(TakeFormatError, match="cannot store"):
        save_take(take, tmp_path / "take.c3d")
    long_names = Take(["x" * 200, "y"], np.zeros((3, 2, 3)), frame_rate=100.0)
    with pytest.raises(TakeFormatError, match="longer than"):
        save_take(long_names, tmp_path / "take.c3d")
    assert list(tmp_path.iterdir()) == []
