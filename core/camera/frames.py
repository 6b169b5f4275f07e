"""Frame sources: videos (``cv2.VideoCapture``: MP4, AVI, ...), folders of PNG/JPG colour frames and
folders of 16-bit PNG depth frames with a depth unit, all with timestamps and random access.

A source keeps the most recently used decoded frames within a memory budget in bytes
(:data:`FRAME_MEMORY_BUDGET` by default; LRU), so scrubbing back and forth near the current frame decodes
nothing. Sizes are checked before any decode (the image header, the video's reported size): a stream whose
decoded frame would take more than half the budget is refused when it is opened, so that a hostile header
(or 16384×16384 frames of a few kB each) cannot ask for huge allocations; a file OpenCV cannot decode, or
one it runs out of memory on, gives one :class:`InputError` line naming it.
"""

from __future__ import annotations

import re
import struct
from abc import ABC, abstractmethod
from collections import OrderedDict
from pathlib import Path

import cv2
import numpy as np

from handmocap.core.camera.model import MAX_IMAGE_SIDE
from handmocap.core.errors import InputError

#: bytes of decoded frames a source keeps (640×480 colour: 0.9 MB a frame); a decoded frame may take half
FRAME_MEMORY_BUDGET = 256 * 1024 * 1024
#: most frames a source may hold (a day at 120 Hz)
MAX_FRAMES = 10_000_000
#: largest image file read (bytes)
MAX_IMAGE_BYTES = 256 * 1024 * 1024
#: a forward jump of at most this many frames is decoded sequentially rather than by a seek
SEQUENTIAL_GAP = 8
COLOUR_SUFFIXES = (".png", ".jpg", ".jpeg")
DEFAULT_FRAME_RATE = 30.0


class FrameSource(ABC):
    """Frames ``0..count-1`` of one camera stream: colour ``(H,W,3) uint8`` BGR or depth ``(H,W) float32``
    mm (0 = no depth); frame ``k`` at :meth:`time` ``k / frame_rate`` s unless timestamps were given."""

    kind = "colour"
    #: bytes a decoded pixel takes while it is decoded and kept (BGR uint8)
    bytes_per_pixel = 3

    def __init__(self, name: str, count: int, size: tuple[int, int], frame_rate: float,
                 timestamps: np.ndarray | None = None, memory_budget: int | None = None) -> None:
        if not 0 < count <= MAX_FRAMES:
            raise InputError(f"{name}: {count} frames is outside 1..{MAX_FRAMES}")
        check_size(size, name)
        self.memory_budget = int(FRAME_MEMORY_BUDGET if memory_budget is None else memory_budget)
        frame_bytes = size[0] * size[1] * self.bytes_per_pixel
        if 2 * frame_bytes > self.memory_budget:
            raise InputError(f"{name}: a {size[0]}×{size[1]} px {self.kind} frame takes {frame_bytes / 2**20:.0f} MB "
                             f"decoded, more than half the frame memory budget of "
                             f"{self.memory_budget / 2**20:.0f} MB")
        if not (np.isfinite(frame_rate) and 0.1 <= frame_rate <= 10_000):
            raise InputError(f"{name}: frame rate {frame_rate} Hz is outside 0.1..10000")
        if timestamps is not None:
            timestamps = np.asarray(timestamps, dtype=float)
            if timestamps.shape != (count,) or not np.isfinite(timestamps).all() or (np.diff(timestamps) <= 0).any():
                raise InputError(f"{name}: timestamps must be {count} increasing finite seconds")
        self.name, self.count, self.size, self.frame_rate = name, count, size, float(frame_rate)
        self.timestamps = np.arange(count) / self.frame_rate if timestamps is None else timestamps
        self._cache: OrderedDict[int, np.ndarray] = OrderedDict()
        self._cached_bytes = 0

    def __len__(self) -> int:
        return self.count

    def time(self, index: int) -> float:
        """Timestamp of frame ``index`` in s."""
        return float(self.timestamps[index])

    def index_at(self, time_s: float) -> int:
        """The frame nearest to time ``time_s`` (s), clamped to the stream."""
        index = int(np.searchsorted(self.timestamps, time_s))
        if index >= self.count:
            return self.count - 1
        if index > 0 and time_s - self.timestamps[index - 1] <= self.timestamps[index] - time_s:
            return index - 1
        return index

    def frame(self, index: int) -> np.ndarray:
        """Decoded frame ``index`` (read-only array; cached)."""
        index = int(index)
        if not 0 <= index < self.count:
            raise InputError(f"{self.name}: frame {index} is outside 0..{self.count - 1}")
        cached = self._cache.get(index)
        if cached is not None:
            self._cache.move_to_end(index)
            return cached
        try:
            image = self._decode(index)
        except cv2.error as error:   # e.g. OpenCV's own allocation limits
            raise InputError(f"{self.name}: OpenCV cannot decode frame {index} "
                             f"({str(error).strip().splitlines()[-1][:120]})") from None
        except MemoryError:
            raise InputError(f"{self.name}: not enough memory to decode frame {index}") from None
        image.setflags(write=False)
        while self._cache and self._cached_bytes + image.nbytes > self.memory_budget:
            _, dropped = self._cache.popitem(last=False)
            self._cached_bytes -= dropped.nbytes
        if image.nbytes <= self.memory_budget:
            self._cache[index] = image
            self._cached_bytes += image.nbytes
        return image

    @abstractmethod
    def _decode(self, index: int) -> np.ndarray:
        """Frame ``index`` decoded from the file (no cache)."""

    def close(self) -> None:
        self._cache.clear()
        self._cached_bytes = 0

    def __enter__(self) -> FrameSource:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()


def check_size(size: tuple[int, int], name: str) -> None:
    """:class:`InputError` unless ``size`` (width, height) px is within 1..:data:`MAX_IMAGE_SIDE`."""
    width, height = size
    if not (0 < width <= MAX_IMAGE_SIDE and 0 < height <= MAX_IMAGE_SIDE):
        raise InputError(f"{name}: image size {width}×{height} px is outside 1..{MAX_IMAGE_SIDE}")


class VideoFrames(FrameSource):
    """A video file read through ``cv2.VideoCapture`` (FFmpeg backend)."""

    def __init__(self, path: str | Path, frame_rate: float | None = None, memory_budget: int | None = None) -> None:
        path = Path(path)
        if not path.is_file():
            raise InputError(f"video {path} does not exist or is not a file")
        capture = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
        if not capture.isOpened():
            capture.release()
            raise InputError(f"{path.name}: OpenCV cannot decode this video")
        self._capture = capture
        try:
            size = (int(capture.get(cv2.CAP_PROP_FRAME_WIDTH)), int(capture.get(cv2.CAP_PROP_FRAME_HEIGHT)))
            reported = capture.get(cv2.CAP_PROP_FRAME_COUNT)
            count = int(reported) if np.isfinite(reported) else 0
            rate = frame_rate or capture.get(cv2.CAP_PROP_FPS)
            rate = rate if np.isfinite(rate) and rate > 0 else DEFAULT_FRAME_RATE
            super().__init__(path.name, count, size, rate, memory_budget=memory_budget)
            self._next = 0
            self.frame(0)
        except InputError:
            capture.release()
            raise

    def _decode(self, index: int) -> np.ndarray:
        gap = index - self._next
        if gap < 0 or gap > SEQUENTIAL_GAP:
            self._capture.set(cv2.CAP_PROP_POS_FRAMES, index)
        else:
            for _ in range(gap):
                self._capture.grab()
        ok, image = self._capture.read()
        if not ok or image is None:
            self._next = -1
            raise InputError(f"{self.name}: OpenCV cannot decode frame {index}")
        if image.shape[:2] != (self.size[1], self.size[0]):
            raise InputError(f"{self.name}: frame {index} is {image.shape[1]}×{image.shape[0]} px, "
                             f"not {self.size[0]}×{self.size[1]}")
        self._next = index + 1
        return image if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)

    def close(self) -> None:
        super().close()
        self._capture.release()


class ImageFolderFrames(FrameSource):
    """A folder of colour frames (PNG/JPG), in natural name order (``frame_2`` before ``frame_10``)."""

    def __init__(self, folder: str | Path, frame_rate: float = DEFAULT_FRAME_RATE,
                 timestamps: np.ndarray | None = None, suffixes: tuple[str, ...] = COLOUR_SUFFIXES,
                 memory_budget: int | None = None) -> None:
        folder = Path(folder)
        if not folder.is_dir():
            raise InputError(f"frame folder {folder} does not exist or is not a folder")
        self.paths = sorted((p for p in folder.iterdir() if p.suffix.lower() in suffixes and p.is_file()),
                            key=_natural_key)
        if not self.paths:
            raise InputError(f"{folder}: no {'/'.join(s[1:].upper() for s in suffixes)} frames")
        super().__init__(folder.name, len(self.paths), image_file_size(self.paths[0]), frame_rate, timestamps,
                         memory_budget)
        self.frame(0)

    def _read(self, index: int, flags: int) -> np.ndarray:
        path = self.paths[index]
        size = image_file_size(path)
        if size != self.size:
            raise InputError(f"{path.name}: {size[0]}×{size[1]} px, but the first frame is "
                             f"{self.size[0]}×{self.size[1]}")
        try:
            data = np.fromfile(path, dtype=np.uint8)
        except OSError as error:
            raise InputError(f"cannot read {path} ({error.strerror or error})") from None
        image = cv2.imdecode(data, flags)
        if image is None:
            raise InputError(f"{path.name}: OpenCV cannot decode this image")
        return image

    def _decode(self, index: int) -> np.ndarray:
        return self._read(index, cv2.IMREAD_COLOR)


class DepthFolderFrames(ImageFolderFrames):
    """A folder of 16-bit PNG depth frames; a value ``v`` is ``v * unit_mm`` mm (0 = no depth)."""

    kind = "depth"
    bytes_per_pixel = 6   # the 16-bit PNG decoded, then its float32 millimetres

    def __init__(self, folder: str | Path, unit_mm: float, frame_rate: float = DEFAULT_FRAME_RATE,
                 timestamps: np.ndarray | None = None, memory_budget: int | None = None) -> None:
        if not (np.isfinite(unit_mm) and 0 < unit_mm <= 100):
            raise InputError(f"depth unit must be within 0..100 mm, got {unit_mm}")
        self.unit_mm = float(unit_mm)
        super().__init__(folder, frame_rate, timestamps, suffixes=(".png",), memory_budget=memory_budget)

    def _decode(self, index: int) -> np.ndarray:
        image = self._read(index, cv2.IMREAD_UNCHANGED)
        if image.dtype != np.uint16 or image.ndim != 2:
            raise InputError(f"{self.paths[index].name}: a depth frame must be a 16-bit one-channel PNG, "
                             f"got {image.dtype} with {1 if image.ndim == 2 else image.shape[2]} channels")
        return image.astype(np.float32) * np.float32(self.unit_mm)


def open_frames(path: str | Path, depth_unit_mm: float | None = None,
                frame_rate: float | None = None, memory_budget: int | None = None) -> FrameSource:
    """A video file, or a folder of colour frames, or (with ``depth_unit_mm``) a folder of depth frames;
    ``memory_budget``: bytes of decoded frames it keeps (default :data:`FRAME_MEMORY_BUDGET`)."""
    path = Path(path)
    if path.is_dir():
        rate = frame_rate or DEFAULT_FRAME_RATE
        if depth_unit_mm is not None:
            return DepthFolderFrames(path, depth_unit_mm, rate, memory_budget=memory_budget)
        return ImageFolderFrames(path, rate, memory_budget=memory_budget)
    if depth_unit_mm is not None:
        raise InputError(f"{path}: depth frames must be a folder of 16-bit PNG files")
    return VideoFrames(path, frame_rate, memory_budget)


def _natural_key(path: Path) -> list:
    return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", path.name)]


def image_file_size(path: Path) -> tuple[int, int]:
    """(width, height) px from a PNG or JPEG header, checked against the limits before any decode."""
    try:
        file_size = path.stat().st_size
        with open(path, "rb") as stream:
            head = stream.read(512 * 1024)
    except OSError as error:
        raise InputError(f"cannot read {path}: {error.strerror or error}") from None
    if file_size > MAX_IMAGE_BYTES:
        raise InputError(f"{path.name}: {file_size} bytes is too large for a frame (limit {MAX_IMAGE_BYTES})")
    size = _png_size(head) if head.startswith(b"\x89PNG\r\n\x1a\n") else _jpeg_size(head)
    if size is None:
        raise InputError(f"{path.name}: not a PNG or JPEG image OpenCV can decode")
    check_size(size, path.name)
    return size


def _png_size(head: bytes) -> tuple[int, int] | None:
    if len(head) < 24 or head[12:16] != b"IHDR":
        return None
    width, height = struct.unpack(">II", head[16:24])
    return width, height


def _jpeg_size(head: bytes) -> tuple[int, int] | None:
    """Size from the first start-of-frame segment of a JPEG (within the first 512 kB)."""
    if not head.startswith(b"\xff\xd8"):
        return None
    position = 2
    while position + 9 <= len(head):
        if head[position] != 0xFF:
            return None
        marker = head[position + 1]
        if marker == 0xFF:
            position += 1
            continue
        length = struct.unpack(">H", head[position + 2:position + 4])[0]
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            height, width = struct.unpack(">HH", head[position + 5:position + 9])
            return width, height
        position += 2 + length
    return None
