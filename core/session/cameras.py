"""Cameras of a session take: a calibrated camera and the frames it filmed, stored with the take.

A take entry's ``cameras`` list holds one item per camera::

    {"name": str, "camera": "takes/<id>/cameras/<name>.json", "media": absolute path,
     "media_relative": path relative to the session folder | null, "depth": absolute path | null,
     "depth_relative": ... | null, "depth_unit_mm": float | null}

The camera file lives inside the session folder (written through :mod:`core.session.files`, never through
a link); the media (a video, a folder of colour frames, a folder of 16-bit depth frames) is referenced like
a take's raw file: the session-relative path is tried first. Manifest changes go through
:meth:`Session.update` (under the session lock).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, replace
from pathlib import Path

from handmocap.core.camera.files import MAX_FILE_BYTES, camera_from_json, camera_to_json
from handmocap.core.camera.model import Camera
from handmocap.core.errors import InputError
from handmocap.core.io.documents import parse_document
from handmocap.core.session.files import make_folder, read_bytes, write_file
from handmocap.core.session.session import Session, _relative, _safe_name


@dataclass(frozen=True)
class TakeCamera:
    """A camera of a session take: ``camera``, its colour ``media`` (video or folder) and, for an RGB-D
    camera, the ``depth`` folder with its ``depth_unit_mm``; ``name`` is unique within the take."""

    name: str
    camera: Camera
    media: Path | None
    depth: Path | None = None
    depth_unit_mm: float | None = None


def camera_file(session: Session, take_id: str, name: str) -> Path:
    """Where the camera ``name`` of a take is kept in the session folder."""
    return session.take_folder(session.take(take_id).id) / "cameras" / f"{_safe_name(name)}.json"


def add_camera(session: Session, take_id: str, camera: Camera, media: str | os.PathLike[str] | None,
               depth: str | os.PathLike[str] | None = None, depth_unit_mm: float | None = None) -> TakeCamera:
    """Store ``camera`` with a take of ``session``, with its colour ``media`` and/or ``depth`` folder (at
    least one; depth needs ``depth_unit_mm``). The camera's name is made unique within the take."""
    session._check_writable_session()
    if media is None and depth is None:
        raise InputError("a camera needs a video, a folder of frames or a folder of depth frames")
    unit_mm: float | None = None
    if depth is not None:
        if depth_unit_mm is None or not depth_unit_mm > 0:
            raise InputError("depth frames need a depth unit in mm (e.g. 1 or 0.125)")
        unit_mm = float(depth_unit_mm)
    media_path = None if media is None else Path(media).expanduser().absolute()
    depth_path = None if depth is None else Path(depth).expanduser().absolute()
    for path in (media_path, depth_path):
        if path is not None and not path.exists():
            raise InputError(f"camera media {path} does not exist")
    entry_id = session.take(take_id).id
    names = {item["name"] for item in session.take(take_id).cameras}
    name, copy = camera.name or "camera", 1
    while name in names or _safe_name(name) in {_safe_name(other) for other in names}:
        copy += 1
        name = f"{camera.name} ({copy})"
    named = replace(camera, name=name)
    _write_camera(session, entry_id, named)
    item = {"name": name, "camera": str(camera_file(session, entry_id, name).relative_to(session.folder)),
            "media": "" if media_path is None else str(media_path),
            "media_relative": None if media_path is None else _relative(media_path, session.folder),
            "depth": None if depth_path is None else str(depth_path),
            "depth_relative": None if depth_path is None else _relative(depth_path, session.folder),
            "depth_unit_mm": unit_mm}
    session.update(lambda: session.take(entry_id).cameras.append(item))
    return TakeCamera(name, named, media_path, depth_path, unit_mm)


def save_take_camera(session: Session, take_id: str, camera: Camera) -> None:
    """Replace the stored camera of the same name (a new calibration, registration or clock offset)."""
    entry = session.take(take_id)
    if camera.name not in {item["name"] for item in entry.cameras}:
        raise InputError(f"take '{entry.name}' has no camera '{camera.name}'")
    session._check_writable_session()
    _write_camera(session, entry.id, camera)


def take_cameras(session: Session, take_id: str) -> list[TakeCamera]:
    """The cameras of a take, read from the session folder (InputError naming a damaged camera file)."""
    cameras = []
    for item in session.take(take_id).cameras:
        path = session.folder / item["camera"]
        try:
            data = parse_document(read_bytes(session.folder, path, MAX_FILE_BYTES), path.name, "camera file")
        except (OSError, InputError) as error:
            raise InputError(f"cannot read camera '{item['name']}' of take '{take_id}' from {path} "
                             f"({getattr(error, 'strerror', None) or error})") from None
        camera = camera_from_json(data, path.name)
        unit = item.get("depth_unit_mm")
        cameras.append(TakeCamera(item["name"], camera,
                                  _media(session, item.get("media") or None, item.get("media_relative")),
                                  _media(session, item.get("depth"), item.get("depth_relative")),
                                  float(unit) if isinstance(unit, int | float) else None))
    return cameras


def _media(session: Session, absolute: str | None, relative: object) -> Path | None:
    """The media path: session-relative when it exists there, else the absolute one (None when unset)."""
    if not absolute:
        return None
    if isinstance(relative, str):
        candidate = (session.folder / relative).resolve()
        if candidate.exists():
            return candidate
    return Path(absolute)


def _write_camera(session: Session, take_id: str, camera: Camera) -> None:
    path = camera_file(session, take_id, camera.name)
    try:
        make_folder(session.folder, path.parent)
        write_file(session.folder, path, (json.dumps(camera_to_json(camera), indent=1) + "\n").encode("utf-8"))
    except OSError as error:
        raise InputError(f"cannot save camera '{camera.name}' ({error.strerror or error})") from None
