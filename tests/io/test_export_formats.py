"""Export formats other tools import, each written and read back: TRC as OpenSim's reader parses it, BVH
in a Y-up frame and other units, glTF with the hand's animation (structure checked here, and by the Khronos
validator when node and gltf-validator are installed), C3D residual words as the C3D standard defines them,
and the labelled points as CSV."""

from __future__ import annotations

import base64
import json
import shutil
import subprocess
import warnings
from pathlib import Path

import c3d
import ezc3d
import numpy as np
import pytest

from handmocap.core.errors import InputError
from handmocap.core.io import Take, load_take
from handmocap.core.io.axes import Y_UP
from handmocap.core.io.c3d_writer import write_c3d_points
from handmocap.core.io.labelled_c3d import read_labelled_c3d, write_labelled_c3d
from handmocap.core.io.trc import read_trc, write_trc
from handmocap.core.model import load_template
from handmocap.core.model.bvh import _axis_rotation, read_bvh, write_bvh
from handmocap.core.model.gltf import HandAnimation, save_gltf_hand
from handmocap.core.model.hand_model import skin_vertices
from handmocap.core.review import AcceptFills, GapFill, ReviewTake
from handmocap.core.review.export import export_points_csv, export_review
from handmocap.core.review.synthetic import synthetic_labelling
from handmocap.core.simulate.motion import simulate_joint_angles

FRAMES = 60
OPENSIM_KEYS = ["DataRate", "CameraRate", "NumFrames", "NumMarkers", "Units", "OrigDataRate", "OrigDataStartFrame",
                "OrigNumFrames"]


def _take(frames: int = FRAMES, markers: int = 4) -> Take:
    rng = np.random.default_rng(3)
    positions = rng.uniform(-400.0, 900.0, (frames, markers, 3))
    positions[5:9, -1] = np.nan     # the last marker missing: the row's last cells are empty
    positions[20, 0] = np.nan
    return Take([f"M{i} tip" for i in range(markers)], positions, frame_rate=120.0, first_frame=7)


def _opensim_tokens(line: str) -> list[str]:
    """OpenSim's FileAdapter::tokenize on tab/CR: one token per delimiter (empty ones kept), then the rest
    of the line only when it is not empty."""
    tokens, start = [], 0
    for index, character in enumerate(line):
        if character in "\t\r":
            tokens.append(line[start:index].strip())
            start = index + 1
    if start < len(line):
        tokens.append(line[start:].strip())
    return tokens


def _opensim_read(path: Path) -> tuple[dict[str, str], list[str], np.ndarray, np.ndarray]:
    """The checks and parse of OpenSim's TRCFileAdapter::extendRead: metadata, names, times, (F, M, 3)."""
    lines = path.read_text().split("\n")
    assert lines[0].split()[0] == "PathFileType"
    keys = [key for key in _opensim_tokens(lines[1]) if key]
    assert keys == OPENSIM_KEYS
    values = [value for value in _opensim_tokens(lines[2]) if value]
    assert len(values) == len(keys)
    meta = dict(zip(keys, values, strict=True))
    count = int(meta["NumMarkers"])
    labels = [label for label in _opensim_tokens(lines[3]) if label]
    assert len(labels) == count + 2 and labels[:2] == ["Frame#", "Time"]
    xyz = [label for label in _opensim_tokens(lines[4]) if label]
    assert xyz == [f"{axis}{i}" for i in range(1, count + 1) for axis in "XYZ"]
    row = 5
    while not lines[row] or not _opensim_tokens(lines[row])[0]:
        row += 1
    times, frames = [], []
    while row < len(lines) and lines[row]:
        cells = _opensim_tokens(lines[row])
        assert len(cells) == 2 + 3 * count, f"row {row + 1}: {len(cells)} cells"
        times.append(float(cells[1]))
        frames.append([[float(cells[c + k]) if all(cells[c:c + 3]) else np.nan for k in range(3)]
                       for c in range(2, 2 + 3 * count, 3)])
        row += 1
    assert len(frames) == int(meta["NumFrames"])
    return meta, labels[2:], np.array(times), np.array(frames)


def test_trc_reads_in_opensims_reader_and_ours(tmp_path: Path) -> None:
    take = _take()
    path = tmp_path / "markers.trc"
    write_trc(take, path, units="m", up="y")
    meta, names, times, positions = _opensim_read(path)
    assert meta["Units"] == "m" and float(meta["DataRate"]) == 120.0 and meta["OrigDataStartFrame"] == "7"
    assert names == take.marker_names
    np.testing.assert_allclose(times, np.arange(FRAMES) / 120.0, atol=1e-6)
    expected = take.marker_positions @ Y_UP.T / 1000.0
    np.testing.assert_array_equal(np.isnan(positions), np.isnan(expected))
    np.testing.assert_allclose(positions, expected, atol=1e-6, equal_nan=True)
    assert np.isnan(positions[5:9, -1]).all()
    # our reader: back to mm; the Y-up frame turned back gives the recorded coordinates
    ours = read_trc(path)
    assert ours.first_frame == 7 and ours.marker_names == take.marker_names and ours.source_units == "m"
    np.testing.assert_allclose(ours.marker_positions @ Y_UP, take.marker_positions, atol=1e-3, equal_nan=True)
    write_trc(take, path, units="cm")
    np.testing.assert_allclose(read_trc(path).marker_positions, take.marker_positions, atol=1e-4, equal_nan=True)
    with pytest.raises(InputError, match="units"):
        write_trc(take, path, units="inch")
    with pytest.raises(InputError, match="up axis"):
        write_trc(take, path, up="x")


def _local_rotations(motion, joint: int) -> np.ndarray:
    """Rotations ``(F, 3, 3)`` of a BVH joint's Z-X-Y channels."""
    values = motion.joint_values(joint)[:, -3:]
    names = motion.channels[joint][-3:]
    assert [name[0] for name in names] == ["Z", "X", "Y"]
    rotation = np.tile(np.eye(3), (motion.n_frames, 1, 1))
    for index, name in enumerate(names):
        rotation = rotation @ _axis_rotation(name[0], np.radians(values[:, index]))
    return rotation


def test_bvh_in_metres_and_y_up_recovers_offsets_angles_and_positions(tmp_path: Path) -> None:
    model = load_template("right")
    angles = simulate_joint_angles(40, 2, "mixed", 100.0)
    lab, blender = tmp_path / "lab.bvh", tmp_path / "blender.bvh"
    write_bvh(lab, model.skeleton, angles, 100.0)
    write_bvh(blender, model.skeleton, angles, 100.0, units="m", up="y")
    recorded, converted = read_bvh(lab), read_bvh(blender)
    assert converted.channels[0] == ["Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"]
    # offsets: the same bones, turned into the Y-up frame and in metres
    np.testing.assert_allclose(converted.offsets * 1000.0 @ Y_UP, recorded.offsets, atol=1e-3)
    for joint, end in recorded.end_sites.items():
        np.testing.assert_allclose(converted.end_sites[joint] * 1000.0 @ Y_UP, end, atol=1e-3)
    # joint angles: each joint's rotation turned back is the lab-frame rotation (within the 6 decimals written)
    for joint in range(16):
        back = Y_UP.T @ _local_rotations(converted, joint) @ Y_UP
        np.testing.assert_allclose(back, _local_rotations(recorded, joint), atol=1e-5)
    # positions by forward kinematics of the file: the model's joints, turned into Y up, in metres
    expected = np.array([model.chain.joint_transforms(theta)[1] for theta in angles])
    np.testing.assert_allclose(converted.world_positions() * 1000.0, expected @ Y_UP.T, atol=2e-3)
    # Y up: the hand's rest fingers (+Y in the lab's rest frame) point along -Z; the lab's Z is the file's Y
    assert np.allclose(Y_UP @ [0.0, 0.0, 1.0], [0.0, 1.0, 0.0])


def _document(path: Path) -> tuple[dict, bytes]:
    document = json.loads(path.read_text())
    uri = document["buffers"][0]["uri"]
    return document, base64.b64decode(uri.split(",", 1)[1])


def _accessor(document: dict, data: bytes, index: int) -> np.ndarray:
    accessor = document["accessors"][index]
    view = document["bufferViews"][accessor["bufferView"]]
    dtype = {5126: "<f4", 5123: "<u2", 5125: "<u4"}[accessor["componentType"]]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[accessor["type"]]
    values = np.frombuffer(data, dtype=dtype, count=accessor["count"] * width,
                           offset=view["byteOffset"] + accessor.get("byteOffset", 0))
    return values.reshape(accessor["count"], width) if width > 1 else values


def _quaternion_matrix(q: np.ndarray) -> np.ndarray:
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _animated_gltf(tmp_path: Path, name: str = "hand.gltf") -> tuple[Path, np.ndarray]:
    model = load_template("right")
    angles = simulate_joint_angles(50, 5, "mixed", 100.0)
    angles[:, :3] += [120.0, -40.0, 900.0]
    angles[10:13] = np.nan          # unsolved frames hold the nearest solved one
    path = tmp_path / name
    save_gltf_hand(model, path, HandAnimation(angles, 100.0))
    return path, angles


def test_gltf_structure_follows_the_specification(tmp_path: Path) -> None:
    path, angles = _animated_gltf(tmp_path)
    document, data = _document(path)
    primitive = document["meshes"][0]["primitives"][0]
    attributes = primitive["attributes"]
    positions = _accessor(document, data, attributes["POSITION"])
    position_accessor = document["accessors"][attributes["POSITION"]]
    np.testing.assert_array_equal(position_accessor["min"], positions.min(axis=0))
    np.testing.assert_array_equal(position_accessor["max"], positions.max(axis=0))
    weights = _accessor(document, data, attributes["WEIGHTS_0"])
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=2e-7)
    joints_accessor = document["accessors"][attributes["JOINTS_0"]]
    assert joints_accessor["componentType"] in (5121, 5123)   # unsigned byte or short (glTF 2.0, 3.7.3.1)
    joints = _accessor(document, data, attributes["JOINTS_0"])
    skin = document["skins"][0]
    assert joints.max() < len(skin["joints"]) and (joints[weights == 0] == 0).all()
    # inverse bind matrices: the inverse of each joint node's world matrix in the rest pose
    nodes = document["nodes"]
    inverse_bind = _accessor(document, data, skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
    parents = {child: index for index, node in enumerate(nodes) for child in node.get("children", [])}

    def rest_world(index: int) -> np.ndarray:
        node = nodes[index]
        local = np.eye(4)
        local[:3, :3] = _quaternion_matrix(node["rotation"])
        local[:3, 3] = node["translation"]
        return local if index not in parents else rest_world(parents[index]) @ local

    for slot, node in enumerate(skin["joints"]):
        np.testing.assert_allclose(inverse_bind[slot] @ rest_world(node), np.eye(4), atol=1e-5)
    # alignment: every bufferView and accessor starts on 4 bytes; buffer length covers them
    for view in document["bufferViews"]:
        assert view["byteOffset"] % 4 == 0 and view["byteOffset"] + view["byteLength"] <= len(data)
        assert "byteStride" not in view or view["byteStride"] % 4 == 0
    assert document["buffers"][0]["byteLength"] == len(data) and len(data) % 4 == 0
    # nothing unused: every accessor and bufferView is referenced
    animation = document["animations"][0]
    used = set(attributes.values()) | {primitive["indices"], skin["inverseBindMatrices"]}
    used |= {sampler[key] for sampler in animation["samplers"] for key in ("input", "output")}
    assert used == set(range(len(document["accessors"])))
    assert {accessor["bufferView"] for accessor in document["accessors"]} == set(range(len(document["bufferViews"])))
    # animation: translation of the wrist, one rotation sampler per joint, times in seconds, strictly increasing
    targets = sorted((channel["target"]["node"], channel["target"]["path"]) for channel in animation["channels"])
    assert targets == sorted([(0, "translation")] + [(joint, "rotation") for joint in range(16)])
    times = _accessor(document, data, animation["samplers"][0]["input"])
    assert (np.diff(times) > 0).all() and times[0] == 0.0
    np.testing.assert_allclose(times, np.arange(len(angles)) / 100.0, atol=1e-6)
    time_accessor = document["accessors"][animation["samplers"][0]["input"]]
    assert time_accessor["min"] == [float(times.min())] and time_accessor["max"] == [float(times.max())]
    for sampler in animation["samplers"][1:]:
        rotations = _accessor(document, data, sampler["output"])
        np.testing.assert_allclose(np.linalg.norm(rotations, axis=1), 1.0, atol=1e-6)
        assert (np.einsum("fk,fk->f", rotations[1:], rotations[:-1]) >= 0).all()  # the short way round


def test_gltf_animation_skins_the_hand_like_the_model_in_metres_y_up(tmp_path: Path) -> None:
    path, angles = _animated_gltf(tmp_path)
    document, data = _document(path)
    model = load_template("right")
    nodes = document["nodes"]
    animation = document["animations"][0]
    parents = {child: index for index, node in enumerate(nodes) for child in node.get("children", [])}
    skin = document["skins"][0]
    inverse_bind = _accessor(document, data, skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
    outputs = {(channel["target"]["node"], channel["target"]["path"]):
               _accessor(document, data, animation["samplers"][channel["sampler"]]["output"])
               for channel in animation["channels"]}
    attributes = document["meshes"][0]["primitives"][0]["attributes"]
    vertices = _accessor(document, data, attributes["POSITION"]).astype(np.float64)
    joints = _accessor(document, data, attributes["JOINTS_0"])
    weights = _accessor(document, data, attributes["WEIGHTS_0"]).astype(np.float64)
    for frame, theta in ((0, angles[0]), (11, angles[9]), (37, angles[37])):
        def world(index: int, frame: int = frame) -> np.ndarray:
            node = nodes[index]
            local = np.eye(4)
            rotation = outputs.get((index, "rotation"))
            local[:3, :3] = _quaternion_matrix(rotation[frame] if rotation is not None else node["rotation"])
            translation = outputs.get((index, "translation"))
            local[:3, 3] = translation[frame] if translation is not None else node["translation"]
            return local if index not in parents else world(parents[index], frame) @ local

        matrices = np.array([world(node) @ inverse_bind[slot] for slot, node in enumerate(skin["joints"])])
        homogeneous = np.concatenate([vertices, np.ones((len(vertices), 1))], axis=1)
        posed = np.einsum("vk,vkab,vb->va", weights, matrices[joints], homogeneous)[:, :3]
        expected = skin_vertices(model, theta) @ Y_UP.T / 1000.0
        assert np.abs(posed - expected).max() < 1e-5, f"frame {frame}"


def _validator_script() -> str | None:
    """A node script running the Khronos glTF validator (npm gltf-validator), or None when not installed."""
    node, npm = shutil.which("node"), shutil.which("npm")
    if node is None or npm is None:
        return None
    root = subprocess.run([npm, "root", "-g"], capture_output=True, text=True, timeout=60).stdout.strip()
    if not (Path(root) / "gltf-validator").is_dir():
        return None
    return (f"const v = require({json.dumps(str(Path(root) / 'gltf-validator'))});"
            "const data = new Uint8Array(require('fs').readFileSync(process.argv[1]));"
            "v.validateBytes(data, {maxIssues: 0}).then(r => console.log(JSON.stringify(r.issues)))"
            ".catch(e => { console.error(String(e)); process.exit(1); });")


@pytest.mark.parametrize("name", ["hand.glb", "hand.gltf"])
def test_gltf_is_clean_under_the_khronos_validator(tmp_path: Path, name: str) -> None:
    script = _validator_script()
    if script is None:
        pytest.skip("the Khronos glTF validator is not installed (npm install -g gltf-validator)")
    path, _ = _animated_gltf(tmp_path, name)
    static = tmp_path / f"static{path.suffix}"
    save_gltf_hand(load_template("left"), static)
    for target in (path, static):
        result = subprocess.run(["node", "-e", script, str(target)], capture_output=True, text=True, timeout=120)
        assert result.returncode == 0, result.stderr
        issues = json.loads(result.stdout)
        assert (issues["numErrors"], issues["numWarnings"], issues["numInfos"]) == (0, 0, 0), issues["messages"][:5]


def _c3d_package_residuals(path: Path) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with path.open("rb") as handle:
            return np.array([points[:, 3] for _, points, _ in c3d.Reader(handle).read_frames()])


def test_c3d_residual_words_as_the_standard_defines_them(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    positions = rng.uniform(-800.0, 800.0, (30, 3, 3))
    positions[4:7, 1] = np.nan                           # missing
    provenance = np.zeros((30, 3), dtype=np.int8)
    provenance[4:7, 1] = -1
    provenance[10:14, 2] = 6                             # a PCA fill
    residuals = rng.uniform(0.2, 3.0, (30, 3))
    residuals[20:25, 0] = np.nan                         # measured, residual not known
    path = tmp_path / "labelled.c3d"
    write_labelled_c3d(path, ["a", "b", "c"], positions, provenance, 100.0, residuals_mm=residuals)
    scale = abs(float(ezc3d.c3d(str(path))["parameters"]["POINT"]["SCALE"]["value"][0]))
    largest = np.nanmax(np.abs(positions))
    assert scale == pytest.approx(largest / 32000.0, rel=1e-6)   # POINT:SCALE from the largest coordinate
    words = _c3d_package_residuals(path)                   # residual byte x |POINT:SCALE|, -1 invalid
    assert (words[4:7, 1] == -1).all()
    assert (words[10:14, 2] == 0).all()                    # filled: "processed, not the measured value"
    measured = (provenance == 0) & np.isfinite(residuals)
    np.testing.assert_allclose(words[measured], np.maximum(residuals[measured], scale), atol=scale / 2 + 1e-6)
    np.testing.assert_allclose(words[20:25, 0], scale, rtol=1e-6)   # unknown: the smallest measured value
    assert (words[(provenance == 0)] > 0).all()
    # ezc3d: the same samples are valid / invalid
    data = ezc3d.c3d(str(path))["data"]
    assert np.isnan(data["points"][0, 1, 4:7]).all() and np.isfinite(data["points"][:3, 2, 10:14]).all()
    assert (data["meta_points"]["residuals"][0, 1, 4:7] < 0).all()
    # our reader: the provenance codes keep the fill method, the measured residuals come back
    labelled = read_labelled_c3d(path)
    assert (labelled.provenance[10:14, 2] == 6).all() and (labelled.provenance[4:7, 1] == -1).all()
    np.testing.assert_allclose(labelled.residuals_mm[measured], np.maximum(residuals[measured], scale),
                               atol=scale / 2 + 1e-6)
    assert np.isnan(labelled.residuals_mm[10:14, 2]).all() and np.isnan(labelled.residuals_mm[20:25, 0]).all()
    np.testing.assert_allclose(load_take(path).marker_positions, positions, rtol=1e-6, atol=1e-3)


def test_c3d_residuals_clip_to_a_byte_and_raw_points_count_as_measured(tmp_path: Path) -> None:
    positions = np.full((4, 2, 3), 100.0)
    path = tmp_path / "raw.c3d"
    write_c3d_points(path, ["p", "q"], [positions], 100.0, 1, {}, [np.array([[1e6, np.nan]] * 4)])
    words = _c3d_package_residuals(path)
    scale = 100.0 / 32000.0
    np.testing.assert_allclose(words[:, 0], 255 * scale, rtol=1e-5)
    np.testing.assert_allclose(words[:, 1], scale, rtol=1e-5)


def test_review_exports_points_with_and_without_fills(tmp_path: Path) -> None:
    take, result, truth = synthetic_labelling(frames=FRAMES, labels=4, ghosts=1, seed=2)
    review = ReviewTake.from_labelling(take, result, layout="test")
    gap = np.flatnonzero(review.provenance[:, 1] == -1)
    if not len(gap):
        review.assignment[20:24, 1] = -1
        review.provenance[20:24, 1] = -1
        review.__post_init__()
        gap = np.arange(20, 24)
    AcceptFills([GapFill("M1", int(gap[0]), "spline", truth[gap[0]:gap[0] + 1, 1])]).do(review)
    path = tmp_path / "points.csv"
    export_points_csv(review, path)
    back = load_take(path)
    assert back.marker_names == review.label_names and back.first_frame == take.first_frame
    np.testing.assert_allclose(back.marker_positions, review.labelled_positions(), atol=1e-5, equal_nan=True)
    export_review(review, tmp_path / "measured.trc", "trc", fills=False)
    measured = load_take(tmp_path / "measured.trc")
    assert np.isnan(measured.marker_positions[gap[0], 1]).all()
    np.testing.assert_allclose(measured.marker_positions, review.measured_positions(), atol=1e-5, equal_nan=True)
    export_review(review, tmp_path / "nofill.c3d", "c3d", fills=False)
    assert (read_labelled_c3d(tmp_path / "nofill.c3d").provenance[:, :4] <= 0).all()
    for bad, match in ((dict(units="m"), "always in mm"), (dict(hand="left"), "--hand")):
        with pytest.raises(InputError, match=match):
            export_review(review, tmp_path / "x.c3d", "c3d", **bad)
    with pytest.raises(InputError, match="metres and Y up"):
        export_review(review, tmp_path / "x.glb", "gltf", up="z")
    with pytest.raises(InputError, match="must end in"):
        export_review(review, tmp_path / "x.txt", "trc")
    with pytest.raises(InputError, match="no left hand"):
        export_review(review, tmp_path / "x.bvh", "bvh", hand="left", model=load_template("left"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["measured.trc", "nofill.c3d", "points.csv"]
