"""The picture of a depth fit: the depth frame in grey (near is bright), the object that was fitted outlined in
cyan, the fitted hand's rendered silhouette filled in green (trusted) or red (not trusted) with its skeleton
(thumb red, index orange, middle yellow, ring blue, little magenta), the palm centre as a yellow cross, and the
verdict and residuals written on it. BGR uint8, no display."""

from __future__ import annotations

import cv2
import numpy as np

from handmocap.core.fusion.depth_fit import DepthFit
from handmocap.core.fusion.hand_render import Crop, HandRenderer
from handmocap.core.model.skeleton import N_JOINTS

#: skeleton colour per digit (BGR): thumb red, index orange, middle yellow, ring blue, little magenta
DIGIT_BGR = ((40, 40, 255), (0, 150, 255), (0, 230, 230), (255, 160, 40), (230, 60, 230))
TRUSTED_BGR = (60, 200, 60)
UNTRUSTED_BGR = (40, 40, 230)


def depth_image(depth: np.ndarray, near_mm: float | None = None, far_mm: float | None = None) -> np.ndarray:
    """Grey BGR picture of ``depth (H,W)`` mm: near bright, far dark, no depth black."""
    valid = depth > 0
    if not valid.any():
        return np.zeros(depth.shape + (3,), np.uint8)
    low = float(np.percentile(depth[valid], 1)) if near_mm is None else near_mm
    high = float(np.percentile(depth[valid], 99)) if far_mm is None else far_mm
    shade = 1.0 - np.clip((depth - low) / max(high - low, 1.0), 0.0, 1.0)
    grey = np.where(valid, 60 + 170 * shade, 0).astype(np.uint8)
    return cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR)


def _skeleton_segments(renderer: HandRenderer, theta: np.ndarray) -> list[np.ndarray]:
    """Image polylines (K,2) px of the wrist → each digit's joints → its tip."""
    model = renderer.model
    rotations, positions = model.chain.joint_transforms(theta)
    skeleton = model.skeleton
    lines = []
    for digit in range(5):
        joints = [1 + 3 * digit + k for k in range(3)]
        distal = joints[-1]
        local_tip = skeleton.rest_rotations[distal].T @ (skeleton.tip_positions[digit]
                                                         - skeleton.rest_positions[distal])
        tip = rotations[distal] @ local_tip + positions[distal]
        points = np.vstack([positions[[0] + joints], tip])
        lines.append(renderer.camera.project(points))
    assert positions.shape[0] == N_JOINTS
    return lines


def draw_depth_fit(depth: np.ndarray, renderer: HandRenderer, fit: DepthFit, title: str = "") -> np.ndarray:
    """The overlay (H,W,3) BGR uint8 of ``fit`` on ``depth (H,W)`` mm (see the module docstring)."""
    camera = renderer.camera
    image = depth_image(depth)
    colour = TRUSTED_BGR if fit.trusted else UNTRUSTED_BGR
    if fit.mask is not None:
        contours, _ = cv2.findContours(fit.mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        cv2.drawContours(image, contours, -1, (230, 200, 0), 1, cv2.LINE_AA)
    if fit.candidate is not None and np.isfinite(fit.theta).all():
        rendering = renderer.render(fit.theta, Crop(0, 0, camera.height, camera.width, 1), with_edges=False)
        silhouette = rendering.silhouette
        tint = np.zeros_like(image)
        tint[:] = colour
        image[silhouette] = (0.55 * image[silhouette] + 0.45 * tint[silhouette]).astype(np.uint8)
        contours, _ = cv2.findContours(silhouette.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        cv2.drawContours(image, contours, -1, colour, 1, cv2.LINE_AA)
        for digit, line in enumerate(_skeleton_segments(renderer, fit.theta)):
            if np.isfinite(line).all():
                points = np.round(line).astype(np.int32)
                cv2.polylines(image, [points], False, DIGIT_BGR[digit], 1, cv2.LINE_AA)
                for point in points[1:]:
                    cv2.circle(image, (int(point[0]), int(point[1])), 2, DIGIT_BGR[digit], -1, cv2.LINE_AA)
    if np.isfinite(fit.palm_uv).all():
        u, v = (int(round(value)) for value in fit.palm_uv)
        cv2.drawMarker(image, (u, v), (0, 230, 255), cv2.MARKER_CROSS, 14, 2)
    verdict = "trusted" if fit.trusted else "NOT trusted: " + "; ".join(fit.reasons)
    lines = [text for text in (title, verdict) if text]
    if np.isfinite(fit.depth_residual_mm):
        lines.append(f"depth {fit.depth_residual_mm:.1f} mm, missed {100 * fit.missed:.0f} %, outside "
                     f"{100 * fit.outside:.0f} %, palm ({fit.palm_uv[0]:.0f}, {fit.palm_uv[1]:.0f}) px "
                     f"at {fit.palm_depth_mm:.0f} mm")
    y = 18
    for text in lines:
        for chunk in _wrap(text, max(20, camera.width // 8)):
            cv2.putText(image, chunk, (8, y), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 3, cv2.LINE_AA)
            cv2.putText(image, chunk, (8, y), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                        colour if chunk.startswith(("trusted", "NOT")) else (255, 255, 255), 1, cv2.LINE_AA)
            y += 17
    return image


def _wrap(text: str, width: int) -> list[str]:
    words, lines, current = text.split(), [], ""
    for word in words:
        if current and len(current) + 1 + len(word) > width:
            lines.append(current)
            current = word
        else:
            current = f"{current} {word}".strip()
    if current:
        lines.append(current)
    return lines
