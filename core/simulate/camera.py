"""Synthetic cameras with ground truth: colour and depth images of a simulated take seen by a virtual
camera, a calibration object of markers, and board images for intrinsic calibration.

Colour: the skinned template mesh shaded in a skin colour over a background (a floor and a wall), the
markers as bright anti-aliased discs where the z-buffer shows them, blur and sensor noise. Depth (camera
z, mm): the same scene with Kinect-like noise (σ = 1.5 mm × (z / 1 m)²), quantisation to the sensor's
disparity step (2.5 mm × (z / 1 m)²), holes at depth edges and scattered dropouts. The camera runs at
30 Hz against the mocap's 100–120 Hz with a known clock (offset, rate ratio). Board images warp a
ChArUco or chessboard image through the homography of a random board pose, then blur and noise.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from handmocap.core.camera.intrinsics import BoardSpec, board_image
from handmocap.core.camera.model import Camera, CameraClock
from handmocap.core.camera.render import distort_image, render_mesh, shade
from handmocap.core.errors import InputError
from handmocap.core.model import load_template, skin_vertices
from handmocap.core.simulate.motion import WORKSPACE_CENTRE
from handmocap.core.simulate.take import SimulatedTake, simulate_take

SKIN_BGR = (150.0, 175.0, 225.0)
MARKER_BGR = (252.0, 252.0, 252.0)
#: radius (mm) of the hand markers (6 mm spheres) and of the calibration object's markers (14 mm)
MARKER_RADIUS = 3.0
OBJECT_MARKER_RADIUS = 7.0
#: markers of the calibration object in its own frame (mm): an asymmetric L with a raised marker
CALIBRATION_OBJECT = np.array([[0.0, 0.0, 0.0], [180.0, 0.0, 0.0], [110.0, 0.0, 0.0], [0.0, 140.0, 0.0],
                               [0.0, 60.0, 0.0], [60.0, 50.0, 45.0]])
DEPTH_NOISE_MM = 1.5
DEPTH_STEP_MM = 2.5
#: a pixel whose 3×3 neighbourhood spans more depth than this (mm) is an edge pixel; half of them are holes
DEPTH_EDGE_MM = 25.0
DEPTH_DROPOUT = 0.01
COLOUR_NOISE = 2.0


def look_at(eye: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(rotation (3,3), translation (3,) mm)`` of a camera at ``eye`` looking at ``target`` (mocap, Z up),
    image rows pointing down."""
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    rotation = np.vstack([right, down, forward])
    return rotation, -rotation @ eye


def random_camera(seed: int, size: tuple[int, int] = (640, 480), distance: float = 800.0,
                  distortion: bool = True, clock: CameraClock | None = None) -> Camera:
    """A plausible 640×480 camera (f 540–620 px, principal point within 10 px of the centre, mild lens
    distortion) looking at the workspace from ``distance`` mm, 30–60° above the horizontal."""
    rng = np.random.default_rng([seed, 14])
    focal = rng.uniform(540.0, 620.0)
    matrix = np.array([[focal * rng.uniform(0.995, 1.005), 0.0, size[0] / 2 + rng.uniform(-10, 10)],
                       [0.0, focal, size[1] / 2 + rng.uniform(-10, 10)], [0.0, 0.0, 1.0]])
    coefficients = np.zeros(5)
    if distortion:
        coefficients[:4] = [rng.uniform(-0.15, 0.05), rng.uniform(-0.05, 0.1), rng.uniform(-1e-3, 1e-3),
                            rng.uniform(-1e-3, 1e-3)]
    azimuth, elevation = rng.uniform(0, 2 * np.pi), np.radians(rng.uniform(30, 60))
    eye = WORKSPACE_CENTRE + distance * np.array([np.cos(azimuth) * np.cos(elevation),
                                                  np.sin(azimuth) * np.cos(elevation), np.sin(elevation)])
    rotation, translation = look_at(eye, WORKSPACE_CENTRE + rng.uniform(-30, 30, 3))
    return Camera(matrix, coefficients, size, rotation, translation, clock or CameraClock(), True, f"simulated {seed}")


def background(camera: Camera, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The ideal (undistorted) background: ``(colour (H,W,3) float32, depth (H,W) float32 mm, inf = none)``:
    the floor (z = 0) in a checked grey, beyond 3 m nothing."""
    columns, rows = np.meshgrid(np.arange(camera.width), np.arange(camera.height))
    (fx, fy), (cx, cy) = camera.focal, camera.principal_point
    rays = np.stack([(columns - cx) / fx, (rows - cy) / fy, np.ones(columns.shape)], axis=-1) @ camera.rotation
    centre = camera.centre
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = np.where(rays[..., 2] < 0, -centre[2] / rays[..., 2], np.inf)
    depth[depth > 3000.0] = np.inf
    floor = centre + rays * np.where(np.isfinite(depth), depth, 0.0)[..., None]
    checks = ((np.floor(floor[..., 0] / 250.0) + np.floor(floor[..., 1] / 250.0)) % 2)
    grey = np.where(np.isfinite(depth), 70.0 + 20.0 * checks, 45.0 + 15.0 * rows / camera.height)
    tint = rng.uniform(0.85, 1.15, 3)
    return (grey[..., None] * tint).astype(np.float32), depth.astype(np.float32)


def _draw_markers(camera: Camera, colour: np.ndarray, depth: np.ndarray, markers: np.ndarray,
                  radius: float) -> np.ndarray:
    """Draw the markers ``(M,3)`` mocap mm (NaN = absent) visible in the z-buffer ``depth`` as bright
    anti-aliased discs into ``colour`` and as sphere caps into ``depth`` (both ideal images, in place);
    returns the visible mask ``(M,)``."""
    points = camera.to_camera(markers)
    (fx, fy), (cx, cy) = camera.focal, camera.principal_point
    visible = np.zeros(len(points), dtype=bool)
    for index, (x, y, z) in enumerate(points):
        if not (np.isfinite(z) and z > 50.0):
            continue
        u, v, disc = fx * x / z + cx, fy * y / z + cy, fx * radius / z
        row, column = int(round(v)), int(round(u))
        if not (0 <= row < camera.height and 0 <= column < camera.width) or z - radius > depth[row, column] + 1.0:
            continue
        visible[index] = True
        reach = int(np.ceil(disc + 2))
        top, bottom = max(row - reach, 0), min(row + reach + 1, camera.height)
        left, right = max(column - reach, 0), min(column + reach + 1, camera.width)
        rows, columns = np.mgrid[top:bottom, left:right]
        distance = np.hypot(columns - u, rows - v)
        coverage = np.clip(disc + 0.5 - distance, 0.0, 1.0)[..., None]
        patch = colour[top:bottom, left:right]
        patch[:] = patch * (1 - coverage) + coverage * np.asarray(MARKER_BGR, dtype=np.float32)
        cap = z - radius * np.sqrt(np.clip(1.0 - (distance / disc) ** 2, 0.0, 1.0))
        inside = (distance < disc) & (cap < depth[top:bottom, left:right])
        depth[top:bottom, left:right][inside] = cap[inside]
    return visible


def finish_colour(camera: Camera, ideal: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Lens distortion, optical blur and sensor noise of an ideal colour image → ``(H,W,3) uint8``."""
    image: np.ndarray = cv2.GaussianBlur(distort_image(ideal, camera), (0, 0), 0.6)
    image = image + rng.normal(0.0, COLOUR_NOISE, image.shape).astype(np.float32)
    return np.clip(np.round(image), 0, 255).astype(np.uint8)


def finish_depth(camera: Camera, ideal: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Kinect-like depth (mm, 0 = no depth) of an ideal depth image (inf = nothing): noise, quantisation,
    holes at edges and dropouts, then lens distortion."""
    depth = distort_image(np.where(np.isfinite(ideal), ideal, 0.0).astype(np.float32), camera, cv2.INTER_NEAREST)
    valid = depth > 0
    scale = (depth / 1000.0) ** 2
    noisy = depth + rng.normal(0.0, 1.0, depth.shape) * DEPTH_NOISE_MM * scale
    step = np.maximum(DEPTH_STEP_MM * scale, 1e-3)
    noisy = np.round(noisy / step) * step
    kernel = np.ones((3, 3), np.uint8)
    filled = np.where(valid, depth, 0.0).astype(np.float32)
    spread = cv2.dilate(filled, kernel) - cv2.erode(np.where(valid, depth, 1e9).astype(np.float32), kernel)
    edge = valid & (spread > DEPTH_EDGE_MM)
    holes = (edge & (rng.random(depth.shape) < 0.5)) | (rng.random(depth.shape) < DEPTH_DROPOUT)
    return np.where(valid & ~holes, noisy, 0.0).astype(np.float32)


@dataclass
class SimulatedCameraTake:
    """A simulated take, the truth camera that filmed it and a renderer of its camera frames.

    ``camera_times (K,)`` s: timestamps of the camera frames (``frame_rate`` Hz); camera frame ``k`` shows
    the hand at mocap time ``camera.clock.mocap_time(camera_times[k])``."""

    simulated: SimulatedTake
    camera: Camera
    camera_times: np.ndarray
    frame_rate: float
    seed: int

    def pose_at(self, mocap_time: float) -> tuple[np.ndarray, np.ndarray]:
        """``(joint angles (26,), marker positions (M,3) mm)`` at ``mocap_time`` s, interpolated linearly."""
        take = self.simulated.take
        position = float(np.clip(mocap_time * take.frame_rate, 0, take.n_frames - 1))
        low = int(np.floor(position))
        high, weight = min(low + 1, take.n_frames - 1), position - low
        truth = self.simulated.truth
        theta = (1 - weight) * truth["joint_angles"][low] + weight * truth["joint_angles"][high]
        markers = (1 - weight) * truth["marker_positions"][low] + weight * truth["marker_positions"][high]
        return theta, markers

    def render(self, index: int, with_depth: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """Camera frame ``index``: ``(colour (H,W,3) uint8 BGR, depth (H,W) float32 mm or None)``."""
        rng = np.random.default_rng([self.seed, 15, index])
        theta, markers = self.pose_at(float(self.camera.clock.mocap_time(self.camera_times[index])))
        return render_scene(self.camera, skin_vertices(load_template(), theta), load_template().faces, markers,
                            MARKER_RADIUS, rng, with_depth)


def render_scene(camera: Camera, vertices: np.ndarray | None, faces: np.ndarray | None, markers: np.ndarray,
                 radius: float, rng: np.random.Generator, with_depth: bool = True
                 ) -> tuple[np.ndarray, np.ndarray | None]:
    """Colour ``(H,W,3) uint8`` and depth ``(H,W) float32`` mm (or None) of a mesh (optional) with markers
    ``(M,3)`` mocap mm of ``radius`` mm over the background."""
    colour, depth = (array.copy() for array in _scene_background(camera))
    if vertices is not None:
        if faces is None:
            raise InputError("a rendered mesh needs its faces")
        mesh_depth, face_index = render_mesh(camera, vertices, faces)
        skin, mask = shade(camera, vertices, faces, face_index, SKIN_BGR)
        colour[mask] = skin[mask]
        depth = np.minimum(depth, mesh_depth)
    _draw_markers(camera, colour, depth, markers, radius)
    return finish_colour(camera, colour, rng), finish_depth(camera, depth, rng) if with_depth else None


@lru_cache(maxsize=2)
def _scene_background(camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """:func:`background` of :func:`render_scene`: the same for every frame a camera renders (read-only)."""
    colour, depth = background(camera, np.random.default_rng(0))
    colour.setflags(write=False)
    depth.setflags(write=False)
    return colour, depth


def simulate_camera_take(seed: int = 0, n_frames: int = 400, mocap_rate: float = 100.0,
                         camera_rate: float = 30.0, offset_s: float | None = None, rate_ratio: float = 1.0,
                         layout: str = "dense", camera: Camera | None = None) -> SimulatedCameraTake:
    """A simulated take of ``n_frames`` mocap frames at ``mocap_rate`` Hz filmed at ``camera_rate`` Hz by
    ``camera`` (default :func:`random_camera` of ``seed``) whose clock has ``offset_s`` (default a random
    0.05–0.4 s) and ``rate_ratio``; camera frames cover the mocap time span."""
    rng = np.random.default_rng([seed, 16])
    offset = float(rng.uniform(0.05, 0.4)) if offset_s is None else float(offset_s)
    clock = CameraClock(offset, rate_ratio)
    camera = random_camera(seed, clock=clock) if camera is None else camera.with_clock(clock)
    simulated = simulate_take(layout=layout, n_frames=n_frames, seed=seed, frame_rate=mocap_rate)
    duration = (n_frames - 1) / mocap_rate
    last = float(clock.camera_time(duration))
    first = max(0.0, float(clock.camera_time(0.0)))
    times = np.arange(int(np.ceil(first * camera_rate)), int(np.floor(last * camera_rate)) + 1) / camera_rate
    return SimulatedCameraTake(simulated, camera, times, camera_rate, seed)


@dataclass
class CalibrationObjectViews:
    """Frames of the calibration object: ``markers (N,6,3)`` mocap mm, ``colour`` and ``depth`` images."""

    markers: np.ndarray
    colour: list[np.ndarray]
    depth: list[np.ndarray]


def calibration_object_views(camera: Camera, n_views: int = 8, seed: int = 0,
                             mocap_noise_mm: float = 0.2) -> CalibrationObjectViews:
    """The calibration object (:data:`CALIBRATION_OBJECT`) held still in ``n_views`` random poses within
    ±200 mm of the workspace centre, seen by ``camera``; marker positions carry mocap noise."""
    rng = np.random.default_rng([seed, 17])
    markers, colours, depths = [], [], []
    for _ in range(n_views):
        rotation = Rotation.from_rotvec(rng.normal(0, 0.5, 3)).as_matrix()
        centre = WORKSPACE_CENTRE + rng.uniform(-200, 200, 3) * [1, 1, 0.5]
        positions = (CALIBRATION_OBJECT - CALIBRATION_OBJECT.mean(axis=0)) @ rotation.T + centre
        colour, depth = render_scene(camera, None, None, positions, OBJECT_MARKER_RADIUS, rng)
        assert depth is not None  # rendered with depth
        markers.append(positions + rng.normal(0, mocap_noise_mm, positions.shape))
        colours.append(colour)
        depths.append(depth)
    return CalibrationObjectViews(np.array(markers), colours, depths)


@dataclass
class BoardViews:
    """Board images and the true board poses: ``rotations (N,3,3)``, ``translations (N,3)`` mm mapping board
    points (mm, board frame of OpenCV's board object points) to camera points."""

    images: list[np.ndarray]
    rotations: np.ndarray
    translations: np.ndarray


def board_views(camera: Camera, spec: BoardSpec, n_views: int = 12, seed: int = 0,
                distance: tuple[float, float] = (350.0, 700.0), max_tilt_deg: float = 45.0) -> BoardViews:
    """``n_views`` images (BGR uint8) of the board ``spec`` held at random poses fully inside the image."""
    rng = np.random.default_rng([seed, 18])
    pixels_per_square = 48
    image, margin = board_image(spec, pixels_per_square)
    scale = spec.square_mm / pixels_per_square
    to_board = np.array([[scale, 0, (0.5 - margin) * scale], [0, scale, (0.5 - margin) * scale], [0, 0, 1.0]])
    source = cv2.GaussianBlur(image.astype(np.float32), (0, 0), 1.0)
    width_mm, height_mm = spec.squares[0] * spec.square_mm, spec.squares[1] * spec.square_mm
    outline = np.array([[0, 0, 0], [width_mm, 0, 0], [0, height_mm, 0], [width_mm, height_mm, 0.0]])
    images: list[np.ndarray] = []
    rotations: list[np.ndarray] = []
    translations: list[np.ndarray] = []
    ideal_camera = Camera(camera.matrix, np.zeros(5), camera.size)
    while len(images) < n_views:
        tilt = Rotation.from_rotvec(_random_axis(rng) * np.radians(rng.uniform(5, max_tilt_deg)))
        spin = Rotation.from_rotvec([0, 0, np.radians(rng.uniform(-30, 30))])
        rotation = (tilt * spin).as_matrix()
        depth = rng.uniform(*distance)
        target = np.array([rng.uniform(0.15, 0.85) * camera.width, rng.uniform(0.15, 0.85) * camera.height])
        ray = camera.rays(target)[0]
        translation = ray * depth - rotation @ np.array([width_mm / 2, height_mm / 2, 0])
        corners = camera.project_camera_points(outline @ rotation.T + translation)
        if not (np.isfinite(corners).all() and (corners >= 5).all() and (corners[:, 0] < camera.width - 5).all()
                and (corners[:, 1] < camera.height - 5).all()):
            continue
        homography = camera.matrix @ np.column_stack([rotation[:, 0], rotation[:, 1], translation]) @ to_board
        ideal, _ = background(ideal_camera, rng)
        grey = cv2.cvtColor(ideal, cv2.COLOR_BGR2GRAY)
        warped = cv2.warpPerspective(source, homography, camera.size, flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_CONSTANT, borderValue=-1)
        view = np.where(warped >= 0, warped * 0.8 + 20.0, grey).astype(np.float32)
        images.append(finish_colour(camera, cv2.cvtColor(view, cv2.COLOR_GRAY2BGR), rng))
        rotations.append(rotation)
        translations.append(translation)
    return BoardViews(images, np.array(rotations), np.array(translations))


def _random_axis(rng: np.random.Generator) -> np.ndarray:
    axis = rng.normal(size=3)
    axis[2] *= 0.3
    return axis / np.linalg.norm(axis)

