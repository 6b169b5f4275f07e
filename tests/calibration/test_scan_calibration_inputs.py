"""Scan calibration inputs: scan files, cleaning, synthetic scans, similarity/ICP alignment, landmark files."""

import json

import numpy as np
import pytest
from scipy.spatial import cKDTree

from handmocap.core.calibration.cleaning import clean_scan, skin_mask, statistical_outlier_mask
from handmocap.core.calibration.landmarks import landmarks_from_truth, load_landmarks, save_landmarks
from handmocap.core.calibration.rigid import rigid_icp, similarity_transform
from handmocap.core.calibration.scan import Scan, load_scan, save_ply
from handmocap.core.calibration.synthetic_scan import BACKGROUND, HAND, OUTLIER, synthetic_scan
from handmocap.core.errors import InputError
from handmocap.core.model import load_template
from handmocap.core.model.kinematics import rotation_from_vector
from handmocap.core.model.skeleton import N_PARAMS, HandProportions
from handmocap.core.model.template_mesh import LANDMARK_NAMES

SKIN = [[224, 172, 140], [198, 134, 66], [141, 85, 36], [255, 219, 172]]
NOT_SKIN = [[128, 128, 128], [40, 40, 40], [230, 230, 230], [40, 70, 150], [60, 180, 75], [90, 60, 20]]


@pytest.fixture(scope="module")
def scan_and_truth():
    return synthetic_scan(seed=3)


def _tetra_scan(normals: bool, colors: bool, faces: bool) -> Scan:
    points = np.array([[0.0, 0.0, 0.0], [80.0, 0.0, 0.0], [0.0, 90.0, 0.0], [0.0, 0.0, 100.0]])
    return Scan(points=points,
                normals=np.array([[-1.0, -1.0, -1.0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]) / [[3 ** 0.5], [1], [1], [1]]
                if normals else None,
                colors=np.array([[200, 150, 120], [10, 20, 30], [255, 0, 7], [1, 2, 3]], np.uint8) if colors else None,
                faces=np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]) if faces else None)


# --------------------------------------------------------------------------- files


@pytest.mark.parametrize("normals", [False, True])
@pytest.mark.parametrize("colors", [False, True])
@pytest.mark.parametrize("faces", [False, True])
def test_binary_ply_round_trip(tmp_path, normals, colors, faces):
    scan = _tetra_scan(normals, colors, faces)
    save_ply(scan, tmp_path / "scan.ply")
    loaded = load_scan(tmp_path / "scan.ply")
    np.testing.assert_allclose(loaded.points, scan.points, atol=1e-4)
    assert (loaded.colors is None) == (not colors)
    if colors:
        np.testing.assert_array_equal(loaded.colors, scan.colors)
    if faces:
        np.testing.assert_array_equal(loaded.faces, scan.faces)
    if normals:
        np.testing.assert_allclose(loaded.normals, scan.normals, atol=1e-6)
    elif faces:
        np.testing.assert_allclose(np.linalg.norm(loaded.normals, axis=1), 1.0)
        assert any("estimated" in note for note in loaded.notes)
    else:
        assert loaded.normals is None


def test_ascii_ply_with_normals_colours_and_a_quad(tmp_path):
    text = "\n".join([
        "ply", "format ascii 1.0", "comment test", "element vertex 4",
        "property float x", "property float y", "property float z",
        "property float nx", "property float ny", "property float nz",
        "property uchar red", "property uchar green", "property uchar blue",
        "element face 1", "property list uchar int vertex_indices", "end_header",
        "0 0 0 0 0 2 200 150 120", "100 0 0 0 0 1 200 150 120", "100 100 0 0 0 1 1 2 3",
        "0 100 0 0 0 1 4 5 6", "4 0 1 2 3", ""])
    (tmp_path / "scan.ply").write_text(text)
    scan = load_scan(tmp_path / "scan.ply")
    np.testing.assert_allclose(scan.points[2], [100, 100, 0])
    np.testing.assert_allclose(scan.normals, np.tile([0.0, 0.0, 1.0], (4, 1)))
    np.testing.assert_array_equal(scan.colors[3], [4, 5, 6])
    np.testing.assert_array_equal(scan.faces, [[0, 1, 2], [0, 2, 3]])


def test_obj_with_colours_normals_and_faces(tmp_path):
    text = "\n".join([
        "# test", "v 0 0 0 0.8 0.6 0.5", "v 100 0 0 0.8 0.6 0.5", "v 0 100 0 0.1 0.2 0.3", "v 0 0 100 1 1 1",
        "vn 0 0 -1", "vn 1 1 1", "vn -1 0 0", "vn 0 -1 0",
        "f 1//1 3//1 2//1", "f 1//4 2//4 4//4", "f 2//2 3//2 4//2", "f 1//3 4//3 3//3", ""])
    (tmp_path / "scan.obj").write_text(text)
    scan = load_scan(tmp_path / "scan.obj")
    assert scan.points.shape == (4, 3) and scan.faces.shape == (4, 3)
    np.testing.assert_array_equal(scan.colors[0], [204, 153, 128])
    np.testing.assert_allclose(scan.normals[2], [-1.0, 0.0, 0.0])   # last face using vertex 3 wins
    np.testing.assert_allclose(np.linalg.norm(scan.normals, axis=1), 1.0)


def test_obj_point_cloud_and_normals_from_faces(tmp_path):
    (tmp_path / "cloud.obj").write_text("v 0 0 0\nv 10 0 0\nv 0 10 0\nvn 0 0 1\nvn 0 0 1\nvn 0 0 1\n")
    cloud = load_scan(tmp_path / "cloud.obj")
    assert cloud.faces is None and cloud.colors is None
    np.testing.assert_allclose(cloud.normals, np.tile([0.0, 0.0, 1.0], (3, 1)))
    (tmp_path / "mesh.obj").write_text("v 0 0 0\nv 10 0 0\nv 0 10 0\nf 1 2 3\n")
    np.testing.assert_allclose(load_scan(tmp_path / "mesh.obj").normals, np.tile([0.0, 0.0, 1.0], (3, 1)))


def test_metres_are_converted_to_millimetres(tmp_path):
    scan = _tetra_scan(False, False, False)
    save_ply(Scan(points=scan.points / 1000.0), tmp_path / "metres.ply")
    loaded = load_scan(tmp_path / "metres.ply")
    np.testing.assert_allclose(loaded.points, scan.points, atol=1e-3)
    assert any("metres" in note for note in loaded.notes)
    save_ply(scan, tmp_path / "mm.ply")
    assert load_scan(tmp_path / "mm.ply").notes == []


@pytest.mark.parametrize("name, content", [
    ("empty.ply", b""),
    ("header.ply", b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"),
    ("format.ply", b"ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty float x\nend_header\n"),
    ("type.ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty quaternion x\nend_header\n1\n"),
    ("noxyz.ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n"),
    ("short.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                  b"property float z\nend_header\n1 2 3\n"),
    ("novertex.ply", b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
                     b"property float z\nend_header\n"),
    ("truncated.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\n"
                      b"property float y\nproperty float z\nend_header\n" + bytes(20)),
    ("nan.ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                b"property float z\nend_header\n1 nan 3\n"),
    ("badface.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                    b"0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"),
    ("empty.obj", b"# nothing\n"),
    ("letters.obj", b"v 1 2 x\n"),
    ("ragged.obj", b"v 1 2 3\nv 1 2\n"),
    ("face.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 a\n"),
    ("scan.stl", b"solid\n"),
])
def test_malformed_files_raise_input_error(tmp_path, name, content):
    (tmp_path / name).write_bytes(content)
    with pytest.raises(InputError) as error:
        load_scan(tmp_path / name)
    assert "\n" not in str(error.value)


def test_missing_file_raises_input_error(tmp_path):
    with pytest.raises(InputError, match="not found"):
        load_scan(tmp_path / "missing.ply")


# --------------------------------------------------------------------------- cleaning


def test_kovac_rule_on_known_colours():
    assert skin_mask(np.array(SKIN)).all()
    assert not skin_mask(np.array(NOT_SKIN)).any()


def test_strictness_is_monotonic():
    colors = np.random.default_rng(1).integers(0, 256, size=(50_000, 3))
    masks = [skin_mask(colors, strictness) for strictness in np.linspace(0.0, 1.0, 6)]
    counts = [int(mask.sum()) for mask in masks]
    assert counts[0] > counts[-1] > 0
    for looser, stricter in zip(masks, masks[1:], strict=False):
        assert not np.any(stricter & ~looser)
    with pytest.raises(InputError):
        skin_mask(colors, 1.5)


def test_statistical_outliers_are_removed():
    rng = np.random.default_rng(2)
    sphere = rng.normal(size=(20_000, 3))
    sphere = 50.0 * sphere / np.linalg.norm(sphere, axis=1, keepdims=True)
    planted = rng.uniform(-150.0, 150.0, size=(200, 3))
    planted = planted[np.abs(np.linalg.norm(planted, axis=1) - 50.0) > 15.0]
    outliers = statistical_outlier_mask(np.concatenate([sphere, planted]))
    assert outliers[len(sphere):].all()
    assert outliers[:len(sphere)].mean() < 0.01


def test_clean_scan_without_colours_and_without_skin():
    rng = np.random.default_rng(4)
    points = rng.normal(size=(2000, 3)) * 20.0
    cleaned, report = clean_scan(Scan(points=points))
    assert not report["colour_filter"] and report["non_skin_removed"] == 0
    assert report["kept_points"] == len(cleaned) == len(points) - report["outliers_removed"]
    grey = np.full((len(points), 3), 128, dtype=np.uint8)
    with pytest.raises(InputError, match="no skin points left after filtering"):
        clean_scan(Scan(points=points, colors=grey))


# --------------------------------------------------------------------------- synthetic scans


def test_synthetic_scan_has_the_requested_properties(scan_and_truth):
    scan, truth = scan_and_truth
    labels = truth["labels"]
    hand = labels == HAND
    assert 0.9 * 200_000 < hand.sum() <= 200_000
    assert abs((labels == OUTLIER).sum() - 0.01 * hand.sum()) <= 1
    assert (labels == BACKGROUND).sum() == 20_000
    assert scan.points.shape == scan.normals.shape == scan.colors.shape == (len(labels), 3)
    assert scan.colors.dtype == np.uint8
    np.testing.assert_allclose(np.linalg.norm(scan.normals, axis=1), 1.0)
    model = truth["model"]
    assert truth["vertices"].shape == model.vertices.shape
    assert truth["joints"].shape == (16, 3) and truth["landmarks"].shape == (20, 3)
    assert truth["theta"].shape == (N_PARAMS,)
    # noise: hand points lie close to the posed surface; holes: nothing near the hole centres
    distances, _ = cKDTree(truth["vertices"]).query(scan.points[hand])
    assert np.median(distances) < 2.0
    near_holes, _ = cKDTree(scan.points[hand]).query(truth["hole_centres"])
    assert np.all(near_holes > 5.0)
    assert scan.points[labels == BACKGROUND, 2].max() < truth["vertices"][:, 2].min()


def test_skin_filter_separates_hand_from_background(scan_and_truth):
    scan, truth = scan_and_truth
    skin = skin_mask(scan.colors, 0.5)
    assert skin[truth["labels"] == HAND].mean() >= 0.95
    assert (~skin[truth["labels"] == BACKGROUND]).mean() >= 0.95
    cleaned, report = clean_scan(scan)
    assert report["input_points"] == len(scan) and report["kept_points"] == len(cleaned)
    assert cleaned.points[:, 2].min() > truth["vertices"][:, 2].min() - 5.0


def test_synthetic_scan_of_a_reproportioned_hand():
    proportions = HandProportions().scaled(finger_scale=1.1, palm_width_scale=0.9)
    scan, truth = synthetic_scan(proportions, theta=np.zeros(N_PARAMS), n_points=5_000, background_points=500,
                                 seed=1)
    template = load_template()
    assert truth["model"] is not template
    assert np.ptp(truth["vertices"][:, 1]) > np.ptp(template.vertices[:, 1]) + 5.0
    np.testing.assert_allclose(truth["vertices"], truth["model"].vertices, atol=1e-9)
    np.testing.assert_allclose(truth["joints"], truth["model"].skeleton.rest_positions, atol=1e-9)


# --------------------------------------------------------------------------- alignment


def test_umeyama_recovers_a_known_similarity():
    rng = np.random.default_rng(5)
    source = rng.normal(size=(40, 3)) * 30.0
    rotation = rotation_from_vector(np.array([0.4, -1.1, 2.0]))
    target = 1.3 * source @ rotation.T + [10.0, -20.0, 5.0]
    scale, found_rotation, translation = similarity_transform(source, target)
    assert scale == pytest.approx(1.3, abs=1e-12)
    np.testing.assert_allclose(found_rotation, rotation, atol=1e-12)
    np.testing.assert_allclose(translation, [10.0, -20.0, 5.0], atol=1e-10)
    rigid_scale, _, _ = similarity_transform(source, target, with_scale=False)
    assert rigid_scale == 1.0
    weights = np.ones(len(source))
    weights[:5] = 0.0
    corrupted = target.copy()
    corrupted[:5] += 100.0
    np.testing.assert_allclose(similarity_transform(source, corrupted, weights)[1], rotation, atol=1e-12)


def test_umeyama_never_returns_a_reflection():
    source = np.random.default_rng(6).normal(size=(30, 3))
    mirrored = source * [-1.0, 1.0, 1.0]
    _, rotation, _ = similarity_transform(source, mirrored)
    assert np.linalg.det(rotation) == pytest.approx(1.0)
    with pytest.raises(InputError):
        similarity_transform(source[:2], mirrored[:2])


def test_icp_recovers_a_perturbed_template_pose():
    template = load_template()
    scan, _ = synthetic_scan(theta=np.zeros(N_PARAMS), seed=7)
    cleaned, _ = clean_scan(scan)
    perturbation = rotation_from_vector(np.array([0.08, -0.12, 0.1]))
    shift = np.array([6.0, -8.0, 5.0])
    # start from the template placed slightly wrong: undo a known similarity
    initial = (1 / 1.04, perturbation.T, -perturbation.T @ shift / 1.04)
    scale, rotation, translation, rms = rigid_icp(
        template.vertices, cleaned.points, template.vertex_normals, cleaned.normals, initial=initial,
        iterations=200, max_distance_mm=15.0)
    aligned = scale * template.vertices @ rotation.T + translation
    vertex_error = np.sqrt(np.mean(np.sum((aligned - template.vertices) ** 2, axis=1)))
    assert rms < 1.0
    assert vertex_error < 1.0
    assert scale == pytest.approx(1.0, abs=0.01)


# --------------------------------------------------------------------------- landmarks


def test_landmark_files(tmp_path, scan_and_truth):
    _, truth = scan_and_truth
    landmarks = landmarks_from_truth(truth)
    assert list(landmarks) == list(LANDMARK_NAMES)
    np.testing.assert_allclose(landmarks["index_tip"], truth["vertices"][truth["model"].landmarks["index_tip"]])
    landmarks["wrist"] = None
    save_landmarks(landmarks, tmp_path / "landmarks.json")
    assert [p.name for p in tmp_path.iterdir()] == ["landmarks.json"]
    loaded = load_landmarks(tmp_path / "landmarks.json")
    assert loaded["wrist"] is None
    np.testing.assert_allclose(loaded["thumb_tip"], landmarks["thumb_tip"])

    in_metres = {"units": "m", "landmarks": {name: list(landmarks[name] / 1000.0) for name in LANDMARK_NAMES[:6]}}
    (tmp_path / "metres.json").write_text(json.dumps(in_metres))
    np.testing.assert_allclose(load_landmarks(tmp_path / "metres.json")["thumb_tip"], landmarks["thumb_tip"])


@pytest.mark.parametrize("content, message", [
    ({"units": "mm", "landmarks": {"pinky_tip": [0, 0, 0]}}, "unknown landmark names pinky_tip"),
    ({"units": "mm", "landmarks": {name: [0, 0, 0] for name in LANDMARK_NAMES[:5]}}, "only 5 landmarks"),
    ({"units": "mm", "landmarks": {name: [0, 0] for name in LANDMARK_NAMES}}, "three finite numbers"),
    ({"units": "inch", "landmarks": {}}, "unsupported units"),
    ({"points": []}, "'landmarks' object"),
])
def test_invalid_landmark_files(tmp_path, content, message):
    (tmp_path / "bad.json").write_text(json.dumps(content))
    with pytest.raises(InputError, match=message):
        load_landmarks(tmp_path / "bad.json")
    (tmp_path / "broken.json").write_text("{")
    with pytest.raises(InputError, match="not a valid JSON"):
        load_landmarks(tmp_path / "broken.json")
