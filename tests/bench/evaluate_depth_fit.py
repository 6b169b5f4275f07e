"""The single depth-frame fit on the real SR305 frames of ``../shared/data/rgbd`` (issue 27): the README's table
(per frame: palm centre, residuals, the open fingers' largest flexion, trusted, time), the same frames with a
body or a chair moved nearer than the hand, the fits forced onto every other hand-sized object (all must be
flagged), and a picture of the eight overlays. Run:
``.venv/bin/python tests/bench/evaluate_depth_fit.py [MONTAGE.png]``."""

from __future__ import annotations

import sys
import time

import cv2
import numpy as np

from handmocap.core.evaluation.data import RGBD_FRAMES
from handmocap.core.evaluation.depth_distractors import body_nearer, chair_nearer
from handmocap.core.fusion.depth_fit import DepthFitter
from handmocap.core.fusion.depth_overlay import draw_depth_fit
from handmocap.core.fusion.depth_track import parse_intrinsics, read_depth_image
from handmocap.core.fusion.hand_segment import find_hands

FOLDER = RGBD_FRAMES / "sr305_open_right_hand"
INTRINSICS = "476.007,476.007,313.683,242.755"


def _nearer_body(depth: np.ndarray) -> np.ndarray:
    return body_nearer(depth, 560.0)


def main() -> int:
    if not FOLDER.is_dir():
        print(f"{FOLDER} is absent")
        return 1
    fitter = DepthFitter(parse_intrinsics(INTRINSICS, (640, 480)))
    print("| frame | palm (px) | depth residual | uncovered / outside | largest finger flexion | scale | trusted | "
          "time |")
    print("|---|---|---|---|---|---|---|---|")
    tiles, flagged, forced = [], 0, 0
    for path in sorted(FOLDER.glob("*.png")):
        depth = read_depth_image(path, 0.125)
        started = time.perf_counter()
        fit = fitter.fit(depth)
        seconds = time.perf_counter() - started
        flexion = np.abs(np.degrees(fit.theta[6:].reshape(5, 4)[1:, 1:])).max()
        print(f"| {path.stem} | ({fit.palm_uv[0]:.0f}, {fit.palm_uv[1]:.0f}) | {fit.depth_residual_mm:.2f} mm | "
              f"{100 * fit.missed:.0f} % / {100 * fit.outside:.0f} % | {flexion:.0f}° | {fit.scale:.2f} | "
              f"{'yes' if fit.trusted else 'no: ' + '; '.join(fit.reasons)} | {seconds:.1f} s |")
        overlay = draw_depth_fit(depth, fitter.renderer_for(fit), fit, path.name)
        left, top, right, bottom = fit.box
        centre = np.array([(left + right) // 2, (top + bottom) // 2])
        x0, y0 = (int(v) for v in np.clip(centre - 150, 0, [640 - 300, 480 - 300]))
        tile = np.ascontiguousarray(overlay[y0:y0 + 300, x0:x0 + 300])
        cv2.putText(tile, path.stem, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (0, 0, 0), 4, cv2.LINE_AA)
        cv2.putText(tile, path.stem, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (255, 255, 255), 1, cv2.LINE_AA)
        tiles.append(tile)
        for candidate in find_hands(depth, fitter.camera)[1:4]:
            other = fitter.for_scale(fitter.estimate_scale(candidate)).fit_candidate(depth, candidate)
            forced += 1
            flagged += not other.trusted
    print(f"fits forced onto the other hand-sized objects: {flagged} of {forced} flagged as not trusted")
    for name, change in (("070", _nearer_body), ("110", _nearer_body), ("030", chair_nearer),
                         ("150", chair_nearer)):
        depth = change(read_depth_image(FOLDER / f"{name}.png", 0.125))
        fit = fitter.fit(depth)
        nearest = float(np.percentile(depth[depth > 0], 1))
        print(f"{name} with a {change.__name__[8:]} at {nearest:.0f} mm, nearer than the hand: palm "
              f"({fit.palm_uv[0]:.0f}, {fit.palm_uv[1]:.0f}) px, trusted {fit.trusted}")
    if len(sys.argv) > 1:
        montage = np.vstack([np.hstack(tiles[:4]), np.hstack(tiles[4:8])])
        cv2.imwrite(sys.argv[1], montage)
        print(f"wrote {sys.argv[1]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
