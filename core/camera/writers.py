"""Writing camera streams: a video through ``cv2.VideoWriter`` and folders of 16-bit depth PNGs, each file
through the durable write path (temporary file, then rename)."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import cv2
import numpy as np

from handmocap.core.camera.frames import VideoFrames
from handmocap.core.errors import InputError
from handmocap.core.io.durable import durable_path, write_atomic

#: codec per video suffix: Motion-JPEG in AVI (every frame a key frame: fast random access), MPEG-4 in MP4
CODECS = {".avi": "MJPG", ".mp4": "mp4v"}


def write_video(path: str | Path, frames: Iterable[np.ndarray], frame_rate: float, size: tuple[int, int]) -> int:
    """Write BGR ``frames`` of ``size`` (w, h) px at ``frame_rate`` Hz to ``path`` (.avi or .mp4); the file
    is checked to open again before it replaces ``path``. Returns the number of frames."""
    path = Path(path)
    codec = CODECS.get(path.suffix.lower())
    if codec is None:
        raise InputError(f"{path.name}: videos are written as {' or '.join(CODECS)}")
    count = 0
    with durable_path(path, verify=_verify_video) as temporary:
        writer = cv2.VideoWriter(str(temporary), cv2.CAP_FFMPEG, cv2.VideoWriter.fourcc(*codec), frame_rate, size)
        if not writer.isOpened():
            raise InputError(f"{path.name}: OpenCV cannot write {codec} video here")
        try:
            for frame in frames:
                writer.write(np.ascontiguousarray(frame))
                count += 1
        finally:
            writer.release()
    return count


def _verify_video(path: Path) -> None:
    VideoFrames(path).close()


def write_depth_frames(folder: str | Path, frames: Iterable[np.ndarray], unit_mm: float) -> int:
    """Write depth ``frames`` ``(H,W)`` mm (0 = none) as ``depth_00000.png``... 16-bit PNGs in ``unit_mm``
    units into the existing ``folder``. Returns the number of frames."""
    count = 0
    for count, frame in enumerate(frames, start=1):
        values = np.clip(np.round(frame / unit_mm), 0, 65535).astype(np.uint16)
        ok, data = cv2.imencode(".png", values)
        if not ok:
            raise InputError(f"cannot encode depth frame {count - 1} as PNG")
        write_atomic(Path(folder) / f"depth_{count - 1:05d}.png", data.tobytes())
    return count
