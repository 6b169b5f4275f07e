"""Scan calibration: mean value coordinates, non-rigid fit, the whole pipeline, its bad inputs, the report."""

import json

import numpy as np
import pytest

from handmocap.core.calibration.landmarks import landmarks_from_truth, save_landmarks
from handmocap.core.calibration.mean_value import mean_value_coordinates
from handmocap.core.calibration.nonrigid import FitSchedule, best_rotations, cotangent_laplacian, fit_nonrigid
from handmocap.core.calibration.pipeline import (
    CalibrationResult,
    calibrate_scan,
    check_landmarks,
    prepare_scan,
    unpose_vertices,
)
from handmocap.core.calibration.report import closest_points_on_triangles, find_swapped_pairs, point_to_mesh_distances
from handmocap.core.calibration.scan import Scan, save_ply
from handmocap.core.calibration.synthetic_scan import synthetic_scan
from handmocap.core.errors import CancelledError, InputError
from handmocap.core.model import HandModel, load_template, skin_vertices
from handmocap.core.model.kinematics import rotation_from_vector
from handmocap.core.model.skeleton import N_PARAMS
from handmocap.core.model.template_mesh import LANDMARK_NAMES

FAST = FitSchedule(reg_factor=0.1, inner_iterations=2)


def _icosphere(subdivisions: int = 3, radius: float = 50.0) -> tuple[np.ndarray, np.ndarray]:
    """A closed sphere mesh (vertices mm, outward counter-clockwise faces)."""
    t = (1 + 5 ** 0.5) / 2
    vertices = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
                [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    faces = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
             [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11],
             [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    vertices = [np.array(v, float) / np.linalg.norm(v) for v in vertices]
    for _ in range(subdivisions):
        cache: dict[tuple[int, int], int] = {}
        new_faces = []

        def middle(a: int, b: int, cache: dict[tuple[int, int], int] = cache) -> int:
            key = (min(a, b), max(a, b))
            if key not in cache:
                point = vertices[a] + vertices[b]
                vertices.append(point / np.linalg.norm(point))
                cache[key] = len(vertices) - 1
            return cache[key]

        for a, b, c in faces:
            ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
            new_faces += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        faces = new_faces
    return np.array(vertices) * radius, np.array(faces)


# --------------------------------------------------------------------------- building blocks


def test_mean_value_coordinates_reproduce_points_and_affine_maps():
    vertices, faces = _icosphere(2)
    points = np.array([[0.0, 0.0, 0.0], [10.0, -20.0, 5.0], [30.0, 30.0, -10.0]])
    coordinates = mean_value_coordinates(vertices, faces, points)
    np.testing.assert_allclose(coordinates.sum(axis=1), 1.0, atol=1e-9)
    np.testing.assert_allclose(coordinates @ vertices, points, atol=1e-6)
    affine = np.array([[1.2, 0.1, 0.0], [0.0, 0.8, 0.2], [0.1, 0.0, 1.1]])
    moved = vertices @ affine.T + [5.0, -3.0, 2.0]
    np.testing.assert_allclose(coordinates @ moved, points @ affine.T + [5.0, -3.0, 2.0], atol=1e-6)
    # a point on the surface gets (barycentric) coordinates on its own triangle
    on_surface = vertices[faces[0]].mean(axis=0)
    weights = mean_value_coordinates(vertices, faces, on_surface[None])[0]
    np.testing.assert_allclose(weights @ vertices, on_surface, atol=1e-6)


def test_best_rotations_recover_a_rotation_and_scale():
    vertices, faces = _icosphere(1)
    _, rows, cols, weights = cotangent_laplacian(vertices, faces)
    rotation = rotation_from_vector(np.array([0.3, -0.2, 0.5]))
    similar = best_rotations(vertices, 1.2 * vertices @ rotation.T, rows, cols, weights)
    np.testing.assert_allclose(similar, np.broadcast_to(1.2 * rotation, similar.shape), atol=1e-9)
    rigid = best_rotations(vertices, 1.2 * vertices @ rotation.T, rows, cols, weights, with_scale=False)
    np.testing.assert_allclose(rigid, np.broadcast_to(rotation, rigid.shape), atol=1e-9)


def test_closest_points_on_triangles_cover_every_region():
    a, b, c = np.zeros(3), np.array([10.0, 0.0, 0.0]), np.array([0.0, 10.0, 0.0])
    queries = np.array([[2.0, 2.0, 5.0], [-3.0, -3.0, 1.0], [15.0, -1.0, 0.0], [5.0, -4.0, 2.0], [8.0, 8.0, 0.0],
                        [-2.0, 5.0, 0.0], [0.0, 14.0, 3.0]])
    expected = np.array([[2.0, 2.0, 0.0], [0, 0, 0], [10, 0, 0], [5, 0, 0], [5, 5, 0], [0, 5, 0], [0, 10, 0]])
    n = len(queries)
    result = closest_points_on_triangles(queries, np.tile(a, (n, 1)), np.tile(b, (n, 1)), np.tile(c, (n, 1)))
    np.testing.assert_allclose(result, expected, atol=1e-9)


def test_nonrigid_fit_takes_a_sphere_to_an_ellipsoid_with_a_hole():
    vertices, faces = _icosphere(3)
    radii = np.array([60.0, 42.0, 50.0])
    rng = np.random.default_rng(0)
    directions = rng.normal(size=(20000, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    points = directions * radii
    normals = points / radii ** 2
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    keep = np.linalg.norm(points - [0.0, 0.0, 50.0], axis=1) > 15.0          # a hole on top
    points, normals = points[keep], normals[keep]
    axes = np.vstack([np.eye(3), -np.eye(3)])
    landmark_vertices = np.array([np.argmax(vertices @ axis) for axis in axes])
    landmark_targets = axes * radii[np.argmax(np.abs(axes), axis=1)][:, None]
    seen: list[np.ndarray] = []
    fit = fit_nonrigid(vertices, faces, landmark_vertices, landmark_targets, points, normals,
                       schedule=FAST, on_iteration=seen.append)
    assert len(seen) == fit.iterations == len(FAST.steps())
    on_ellipsoid = np.linalg.norm(fit.vertices / radii, axis=1)
    # the vertices sit on the ellipsoid (|x/r| = 1), including over the hole
    assert np.abs(on_ellipsoid - 1.0).mean() < 0.01
    assert np.abs(on_ellipsoid - 1.0).max() < 0.05
    assert fit.landmark_rms_mm[-1] < 1.0 < fit.landmark_rms_mm[0] + 10.0


def test_nonrigid_fit_puts_a_point_inside_a_triangle_onto_its_landmark():
    vertices, faces = _icosphere(2)
    corners = faces[:4]
    weights = np.array([[0.2, 0.3, 0.5], [0.6, 0.2, 0.2], [1 / 3, 1 / 3, 1 / 3], [0.1, 0.1, 0.8]])
    start = np.einsum("lk,lka->la", weights, vertices[corners])
    targets = start * 1.1 + [2.0, -1.0, 0.5]               # the points move; the vertices near them follow
    fit = fit_nonrigid(vertices, faces, corners, targets, vertices * 1.1, schedule=FAST, landmark_weights=weights)
    reached = np.einsum("lk,lka->la", weights, fit.vertices[corners])
    assert np.linalg.norm(reached - targets, axis=1).max() < 0.5
    assert fit.landmark_rms_mm[-1] < 0.5
    # the same corners read as vertex landmarks give another fit (the weights are used)
    plain = fit_nonrigid(vertices, faces, corners[:, 0], targets, vertices * 1.1, schedule=FAST)
    assert np.linalg.norm(plain.vertices[corners[:, 0]] - targets, axis=1).max() < 0.5
    assert np.linalg.norm(np.einsum("lk,lka->la", weights, plain.vertices[corners]) - targets, axis=1).max() > 1.0


def test_anatomical_landmarks_refine_the_template_vertices():
    from handmocap.core.calibration.align import LANDMARK_REFINE_MM, anatomical_landmarks, anatomical_ray

    template = load_template()
    corners, weights = anatomical_landmarks(template, LANDMARK_NAMES)
    assert np.allclose(weights.sum(axis=1), 1.0) and (weights >= -1e-9).all()
    points = np.einsum("lk,lka->la", weights, template.vertices[corners])
    stored = template.vertices[[template.landmarks[name] for name in LANDMARK_NAMES]]
    shift = np.linalg.norm(points - stored, axis=1)
    assert shift.max() <= LANDMARK_REFINE_MM and shift.max() > 0.5      # the rounding to vertices is removed
    for name, point in zip(LANDMARK_NAMES, points, strict=True):
        origin, direction = anatomical_ray(template, name)
        offset = point - origin
        assert np.linalg.norm(offset - (offset @ direction) * direction) < 1e-6   # on the defining ray
        assert offset @ direction > 0
    # the truth landmarks of a synthetic scan are those points on the posed subject
    _, truth = synthetic_scan(n_points=2000, holes=0, background_points=10, seed=1)
    subject = truth["model"]
    corners, weights = anatomical_landmarks(subject, LANDMARK_NAMES)
    expected = np.einsum("lk,lka->la", weights, truth["vertices"][corners])
    assert np.allclose(truth["landmark_points"], expected)
    assert np.linalg.norm(truth["landmark_points"] - truth["landmarks"], axis=1).max() <= LANDMARK_REFINE_MM


def test_fit_can_be_cancelled():
    vertices, faces = _icosphere(1)
    with pytest.raises(CancelledError):
        fit_nonrigid(vertices, faces, np.array([0, 1, 2]), vertices[[0, 1, 2]], vertices, cancelled=lambda: True)


def test_swapped_pairs_are_found():
    model_points = np.array([[0.0, 0, 0], [20.0, 0, 0], [0, 30.0, 0], [40.0, 40, 0]])
    targets = model_points.copy()
    targets[[1, 2]] = targets[[2, 1]]
    pairs = find_swapped_pairs(["a", "b", "c", "d"], model_points, targets)
    assert [(a, b) for a, b, _, _ in pairs] == [("b", "c")]
    assert find_swapped_pairs(["a", "b", "c", "d"], model_points, model_points + 1.0) == []


def test_unposing_inverts_skinning():
    model = load_template()
    theta = np.zeros(N_PARAMS)
    theta[0:3], theta[3:6] = [10.0, -5.0, 3.0], [0.2, 0.1, -0.3]
    theta[6:] = np.random.default_rng(1).normal(0.0, 0.2, N_PARAMS - 6)
    np.testing.assert_allclose(unpose_vertices(model, theta, skin_vertices(model, theta)), model.vertices, atol=1e-8)


# --------------------------------------------------------------------------- the whole pipeline


@pytest.fixture(scope="module")
def moved_scan():
    """A 40k-point scan of the template, moved by a known similarity, with its landmarks."""
    scan, truth = synthetic_scan(n_points=40_000, background_points=4000, seed=5)
    rotation = rotation_from_vector(np.array([0.1, -0.2, 0.4]))
    scale, shift = 1.06, np.array([120.0, -40.0, 900.0])

    def move(points: np.ndarray) -> np.ndarray:
        return scale * points @ rotation.T + shift

    moved = Scan(move(scan.points), scan.normals @ rotation.T, scan.colors)
    landmarks = {name: move(position) for name, position in landmarks_from_truth(truth).items()}
    return moved, landmarks, truth, move


@pytest.fixture(scope="module")
def calibrated(moved_scan):
    scan, landmarks, truth, move = moved_scan
    fractions: list[float] = []
    iterations: list[int] = []
    result = calibrate_scan(scan, landmarks, schedule=FAST, progress=fractions.append,
                            on_iteration=lambda vertices: iterations.append(len(vertices)))
    return result, fractions, iterations


def test_pipeline_recovers_the_moved_hand(moved_scan, calibrated):
    scan, landmarks, truth, move = moved_scan
    result, fractions, iterations = calibrated
    assert isinstance(result, CalibrationResult)
    assert result.alignment.scale == pytest.approx(1.06, abs=0.02)
    true_vertices = move(truth["vertices"])
    surface = point_to_mesh_distances(result.fitted_vertices, true_vertices, truth["model"].faces)
    assert surface.mean() < 1.0 and surface.max() < 5.0
    joints = np.linalg.norm(result.joints - move(truth["joints"]), axis=1)
    assert joints.max() < 2.5
    # the model is ready to animate: posed at the fitted theta it lies on the fitted surface
    posed = skin_vertices(result.model, result.theta)
    assert np.linalg.norm(posed - result.fitted_vertices, axis=1).mean() < 1.0
    assert result.model.hand_length == pytest.approx(1.06 * load_template().hand_length, rel=0.05)
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    assert len(iterations) > 10 and set(iterations) == {len(load_template().vertices)}


def test_report_and_saved_model(calibrated, tmp_path):
    result = calibrated[0]
    report = result.report.to_json()
    assert set(report["landmark_residuals_mm"]) == set(LANDMARK_NAMES)
    assert report["landmark_rms_mm"] < 1.0
    assert report["scan_to_model_mm"]["mean"] < 1.0 < report["scan_to_model_mm"]["max"] + 1.0
    assert result.report.vertex_distance.shape == (len(result.model.vertices),)
    assert any("skin filter removed" in note for note in report["notes"])
    result.save(tmp_path / "subject.npz", tmp_path / "report.json")
    loaded = HandModel.load(tmp_path / "subject.npz")
    np.testing.assert_allclose(loaded.skeleton.rest_positions, result.model.skeleton.rest_positions)
    assert loaded.landmarks == load_template().landmarks
    assert json.loads((tmp_path / "report.json").read_text())["landmark_rms_mm"] == report["landmark_rms_mm"]
    np.testing.assert_allclose(loaded.skeleton.rest_positions[0], 0.0, atol=1e-9)


def test_unsupported_area_is_reported(moved_scan):
    scan, landmarks, truth, move = moved_scan
    tip = landmarks["index_tip"]
    far = np.linalg.norm(scan.points - tip, axis=1) > 25.0                 # cut away the index fingertip
    result = calibrate_scan(scan.subset(far), landmarks, schedule=FitSchedule(reg_factor=0.05))
    assert any("no scan support" in warning and "index" in warning for warning in result.report.warnings)


# --------------------------------------------------------------------------- bad input


def test_too_few_landmarks(moved_scan):
    scan, landmarks, _, _ = moved_scan
    few = {name: landmarks[name] for name in LANDMARK_NAMES[:4]}
    with pytest.raises(InputError, match="at least"):
        calibrate_scan(scan, few)


def test_mirrored_landmarks_name_the_hand_side(moved_scan):
    scan, landmarks, _, _ = moved_scan
    mirror = np.array([-1.0, 1.0, 1.0])
    mirrored = {name: value * mirror for name, value in landmarks.items()}
    with pytest.raises(InputError, match="left hand"):
        check_landmarks(load_template(), mirrored, scan.points * mirror)


def test_swapped_landmarks_are_refused(moved_scan):
    scan, landmarks, _, _ = moved_scan
    swapped = dict(landmarks)
    swapped["index_tip"], swapped["ring_tip"] = landmarks["ring_tip"], landmarks["index_tip"]
    with pytest.raises(InputError, match="index_tip and ring_tip look swapped"):
        calibrate_scan(scan, swapped)


def test_landmarks_off_the_scan_are_refused(moved_scan):
    scan, landmarks, _, _ = moved_scan
    with pytest.raises(InputError, match="from the scan"):
        calibrate_scan(scan, {name: value + 200.0 for name, value in landmarks.items()})


def test_no_skin_points():
    points = np.random.default_rng(0).uniform(0, 100, size=(5000, 3))
    scan = Scan(points, colors=np.full((5000, 3), 90, dtype=np.uint8))
    with pytest.raises(InputError, match="no skin"):
        prepare_scan(scan)


def test_metres_and_huge_scans_are_converted_and_subsampled(moved_scan):
    scan, _, _, _ = moved_scan
    in_metres = Scan(scan.points / 1000.0, scan.normals, scan.colors)
    prepared, notes = prepare_scan(in_metres, max_points=20_000)
    assert any("metres" in note for note in notes)
    assert any("using a random 20,000" in note for note in notes)
    assert len(prepared) <= 20_000
    assert np.ptp(prepared.points, axis=0).max() > 100.0


def test_cancel_stops_the_pipeline(moved_scan, cancel_after):
    scan, landmarks, _, _ = moved_scan
    with pytest.raises(CancelledError):
        calibrate_scan(scan, landmarks, cancelled=cancel_after(3))


def test_scan_without_colours_and_with_inverted_or_missing_normals(moved_scan):
    scan, landmarks, truth, move = moved_scan
    hand = truth["labels"] == 0
    true_vertices = move(truth["vertices"])
    for normals, expected in ((-scan.normals[hand], "flipped"), (None, "estimated")):
        bare = Scan(scan.points[hand], normals)
        result = calibrate_scan(bare, landmarks, schedule=FitSchedule(reg_factor=0.05))
        assert any(expected in note for note in result.report.notes)
        surface = point_to_mesh_distances(result.fitted_vertices, true_vertices, truth["model"].faces)
        assert surface.mean() < 1.0


def test_calibrate_from_files(tmp_path, moved_scan):
    scan, landmarks, _, _ = moved_scan
    save_ply(scan, tmp_path / "scan.ply")
    save_landmarks(landmarks, tmp_path / "landmarks.json")
    result = calibrate_scan(tmp_path / "scan.ply", tmp_path / "landmarks.json", schedule=FitSchedule(reg_factor=0.05))
    assert result.model.name == "calibrated scan"
    assert result.report.to_json()["landmark_rms_mm"] < 1.5


def test_marker_alignment_error_sees_a_wrong_hand_size():
    from handmocap.core.calibration.align import scaled_model
    from handmocap.core.evaluation.calibration import marker_alignment_error

    template = load_template()
    subject = scaled_model(template, 1.12)
    residuals = marker_alignment_error(subject, {"own": subject, "template": template}, frames=40)
    assert residuals["own"] < 1.0
    assert residuals["template"] > residuals["own"] + 1.0
