"""Solve ▸ Fuse with RGB-D: markers + RGB-D fusion (:func:`core.fusion.fuse_take`) of the shown take in the review.

Enabled when the shown take has labels and its shown camera is registered and has depth frames. The fusion
runs on a worker (progress in the status bar, Cancel stops it and changes nothing); its joint angles at every
mocap frame become one undoable, journalled step like the IK solve (a :class:`~core.review.SetSolve` of the
hand, with the markers' residuals at the fused pose, after a :class:`~core.review.DefineHand` when the review has
no hand of the layout's labels yet). A result is dropped when the review was edited while it ran.

While that step is done (not undone), the camera dock shows the fusion's per-RGB-D-frame energy terms under the
video (:class:`widgets.energy_strip.EnergyStrip`). The dock's Silhouette toggle outlines the solved hand as the
camera sees it (rendered by :class:`core.fusion.hand_render.HandRenderer`, the model the fusion fits); a finished
fusion turns it on.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np
from PySide6.QtCore import QObject, Signal
from PySide6.QtWidgets import QWidget

from handmocap.app.gui.actions import make_action
from handmocap.app.gui.application import (
    Application,
    CurrentDocumentChanged,
    DocumentClosed,
    FrameChanged,
    Job,
    JobsChanged,
)
from handmocap.app.gui.camera_controller import CameraController
from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.workers import TaskRunner
from handmocap.core.camera.frames import open_frames
from handmocap.core.camera.model import Camera
from handmocap.core.errors import HandMocapError, InputError
from handmocap.core.fusion import FusionResult, FusionSettings, RGBDFrames, fuse_take
from handmocap.core.fusion.energy import TERMS
from handmocap.core.fusion.hand_render import HandRenderer, crop_around
from handmocap.core.model import HandModel, load_layout, marker_columns, marker_positions, resolve_layout
from handmocap.core.review import Command, CompoundCommand, DefineHand, SetSolve
from handmocap.core.review.events import ReviewChanged

JOB_NAME = "fusion"
#: samples of the silhouette crop's longer side: at most a 2-4 px step on a 640×480 camera, smooth enough to draw
OUTLINE_SAMPLES = 240


def silhouette_outlines(renderer: HandRenderer, theta: np.ndarray) -> list[np.ndarray]:
    """Outer contours ``[(N,2), ...]`` in (distorted) image px of the hand at ``theta (26,)`` as
    ``renderer``'s camera sees it (empty when the hand is not in front of the camera)."""
    camera = renderer.camera
    pixels = renderer.pixels(theta)
    if not np.isfinite(pixels).all(axis=1).any():
        return []
    crop = crop_around(pixels, camera, margin=0.05, max_side=OUTLINE_SAMPLES)
    silhouette = renderer.render(theta, crop, with_edges=False).silhouette.astype(np.uint8)
    contours, _ = cv2.findContours(silhouette, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    (fx, fy), (cx, cy) = camera.focal, camera.principal_point
    outlines = []
    for contour in contours:
        samples = contour.reshape(-1, 2).astype(float)
        ideal = np.column_stack([crop.left + crop.stride * samples[:, 0], crop.top + crop.stride * samples[:, 1]])
        rays = np.column_stack([(ideal[:, 0] - cx) / fx, (ideal[:, 1] - cy) / fy, np.ones(len(ideal))])
        outlines.append(camera.project_camera_points(rays))
    return outlines


def fused_residuals(model: HandModel, layout_name: str, take, joint_angles: np.ndarray) -> np.ndarray:
    """Distance ``(F, M)`` mm of each layout marker of the fused pose from its label in ``take`` (NaN where
    unseen or not labelled); ``take``'s marker names are the review's labels."""
    layout = load_layout(layout_name)
    markers = resolve_layout(model, layout)
    columns = marker_columns(take.marker_names, layout.names)
    measured = np.full((len(joint_angles), len(columns), 3), np.nan)
    measured[:, columns >= 0] = take.marker_positions[:, columns[columns >= 0]]
    residuals = np.full((len(joint_angles), len(columns)), np.nan)
    for frame, theta in enumerate(joint_angles):
        if np.isfinite(theta).all():
            residuals[frame] = np.linalg.norm(marker_positions(model, markers, theta) - measured[frame], axis=1)
    return residuals


class FusionController(QObject):
    """Solve ▸ Fuse with RGB-D, the energy strip and the silhouette outline (module docstring). The window
    places :attr:`fuse_action` and shows :attr:`progress_started` / :attr:`progressed` / :attr:`progress_ended`
    like a review job's."""

    status_message = Signal(str, int)
    error_raised = Signal(str, str)
    progress_started = Signal(str)
    progressed = Signal(float)
    progress_ended = Signal()

    def __init__(self, app: Application, host: QWidget, cameras: CameraController,
                 settings: FusionSettings | None = None) -> None:
        super().__init__(host)
        self.app, self.cameras = app, cameras
        self.settings = settings or FusionSettings()
        self.runner = TaskRunner(self)
        self.runner.progressed.connect(lambda _request, fraction: self.progressed.emit(fraction))
        self.runner.succeeded.connect(self._succeeded)
        self.runner.failed.connect(self._failed)
        self.runner.cancelled.connect(self._cancelled)
        self.runner.busy_changed.connect(self._busy_changed)
        self.fuse_action = make_action(host, "Fuse with &RGB-D", self.fuse)
        self.fuse_action.setToolTip("Solve the shown take with its markers and its RGB-D camera (Zhao et al. 2012)")
        self.results: dict[TakeDocument, tuple[Command, FusionResult]] = {}
        self._running: tuple[TakeDocument, int, str, str] | None = None   # document, review version, side, layout
        self._renderers: dict[tuple[int, int], HandRenderer] = {}
        self.strip = cameras.view.energy_strip
        self.strip.frame_clicked.connect(app.set_frame)
        cameras.outline_provider = self.outlines
        cameras.cameras_loaded.connect(lambda _count: self.refresh())
        cameras.view.camera_chosen.connect(lambda _index: self.update_enabled())
        app.add_listener(self._follow)
        self.update_enabled()

    @property
    def document(self) -> TakeDocument | None:
        return self.app.document

    def _follow(self, event: object) -> None:
        if isinstance(event, FrameChanged):
            self.strip.set_frame(event.frame)
            self.update_enabled()       # a camera registered or re-timed in the dock announces nothing else
        elif isinstance(event, DocumentClosed):
            self.results.pop(event.document, None)
        elif isinstance(event, CurrentDocumentChanged | ReviewChanged):
            self.refresh()
        elif isinstance(event, JobsChanged):
            self.update_enabled()

    def refresh(self) -> None:
        self.show_energy()
        self.update_enabled()

    def unavailable(self) -> str | None:
        """Why the shown take cannot be fused now (None: it can)."""
        document, taken = self.document, self.cameras.camera
        if document is None:
            return "open a take first"
        if self.app.is_busy():
            return "wait for the running job to end (or cancel it)"
        if document.review is None or not document.review.n_labels:
            return "the take has no labels yet (auto-label it first)"
        if not document.layout_name:
            return "no marker layout matches the take's labels"
        if taken is None or taken.depth is None or taken.depth_unit_mm is None:
            return "the shown take has no RGB-D camera (File ▸ Add camera… with a depth folder)"
        if not taken.camera.registered:
            return f"camera '{taken.name}' is not registered to the mocap space"
        return None

    def update_enabled(self) -> None:
        reason = self.unavailable()
        self.fuse_action.setEnabled(reason is None)
        self.fuse_action.setStatusTip("" if reason is None else f"Fuse with RGB-D: {reason}")

    # ------------------------------------------------------------------------------------- fusion
    def fuse(self) -> None:
        """Fuse the shown take with its shown RGB-D camera on the worker."""
        reason = self.unavailable()
        if reason is not None:
            self.error_raised.emit("Cannot fuse with RGB-D", reason)
            return
        document, taken = self.document, self.cameras.camera
        review = None if document is None else document.review
        if (document is None or review is None or not document.layout_name or taken is None
                or taken.depth is None or taken.depth_unit_mm is None):
            return      # (unavailable() said so)
        depth_path, depth_unit_mm = taken.depth, taken.depth_unit_mm
        side, layout_name, settings = document.side, document.layout_name, self.settings
        if side not in ("right", "left"):  # "both": the fusion fits one hand, the first of the take
            side = review.hands[0].side if review.hands else "right"
        take = review.labelled_take()
        model = document.model_for(side)

        def task(progress: Callable[[float], None], cancelled: Callable[[], bool]) -> tuple[FusionResult, np.ndarray]:
            depth = open_frames(depth_path, depth_unit_mm=depth_unit_mm)
            colour = open_frames(taken.media) if taken.media is not None else None
            try:
                if depth.size != taken.camera.size:
                    raise InputError(f"the depth frames are {depth.size[0]}×{depth.size[1]} px but camera "
                                     f"'{taken.name}' is {taken.camera.width}×{taken.camera.height}")
                if colour is not None and (len(colour) != len(depth) or colour.size != depth.size):
                    colour.close()     # colour frames that are not the depth frames' instants: depth alone
                    colour = None
                result = fuse_take(take, taken.camera, RGBDFrames(depth, colour), settings, progress, cancelled,
                                   layout=layout_name, model=model)
            finally:
                depth.close()
                if colour is not None:
                    colour.close()
            return result, fused_residuals(model, layout_name, take, result.joint_angles)

        self._running = (document, review.version, side, layout_name)
        self.runner.start(task)
        self.app.job_started(JOB_NAME, Job("fusion", document, self.runner.cancel))
        self.progress_started.emit("Fusing with RGB-D… %p %")
        self.status_message.emit(f"Fusing {document.title} with camera '{taken.name}'…", 0)

    def cancel(self) -> None:
        self.runner.cancel()

    def _busy_changed(self, busy: bool) -> None:
        if not busy:
            self.app.job_ended(JOB_NAME)
            self.progress_ended.emit()
            self.update_enabled()

    def _succeeded(self, _request: int, outcome: tuple[FusionResult, np.ndarray]) -> None:
        running, self._running = self._running, None
        if running is None:
            return
        document, version, side, layout_name = running
        result, residuals = outcome
        if document not in self.app.documents or document.review is None:
            return
        if document.review.version != version:
            self.error_raised.emit("Fusion not applied", f"{document.title} was edited while the fusion ran; "
                                   "fuse again")
            return
        review = document.review
        names = [name.lower() for name in load_layout(layout_name).names]
        number = next((index for index, hand in enumerate(review.hands)
                       if hand.side == side and [review.label_names[label].lower() for label in hand.labels] == names),
                      None)
        steps: list[Command] = []
        if number is None:
            steps.append(DefineHand(side, side, load_layout(layout_name).names, layout_name))
            number = len(review.hands)
        steps.append(SetSolve(number, 0, result.joint_angles, residuals))
        command = CompoundCommand(steps, f"RGB-D fusion of the {side} hand ({len(result.rgbd_frames)} RGB-D frames)")
        try:
            document.push(command)
        except HandMocapError as error:
            self.error_raised.emit("Fusion not applied", f"{document.title}: {error}")
            return
        self.results[document] = (command, result)
        self.cameras.view.silhouette_box.setChecked(True)
        self.show_energy()
        self.status_message.emit(f"{document.title}: fused {len(result.rgbd_frames)} RGB-D frames "
                                 f"({result.seconds_per_rgbd_frame:.2f} s each, {result.optimiser})", 15000)

    def _failed(self, _request: int, message: str) -> None:
        document = self._running[0] if self._running else None
        self._running = None
        self.error_raised.emit("Fusion failed", f"{document.title if document else 'take'}: {message}")

    def _cancelled(self, _request: int) -> None:
        document = self._running[0] if self._running else None
        self._running = None
        if document is not None:
            self.status_message.emit(f"{document.title}: fusion cancelled; the take is unchanged", 8000)

    # ----------------------------------------------------------------------------------- showing
    def fused_result(self, document: TakeDocument | None) -> FusionResult | None:
        """The fusion whose step is done (not undone) in ``document``'s review, else None."""
        if document is None or document not in self.results:
            return None
        command, result = self.results[document]
        if document.stack is None:
            return None
        return result if command in document.stack.commands[:document.stack.index] else None

    def show_energy(self) -> None:
        """Show the shown take's fusion energy terms under the video (hidden without a done fusion)."""
        document = self.document
        result = self.fused_result(document)
        if document is None or result is None:
            self.strip.hide()
            return
        self.strip.set_terms(TERMS, result.rgbd_mocap_frames, result.energy_terms, document.take.n_frames)
        self.strip.set_frame(self.app.frame)
        self.strip.show()

    def outlines(self, document: TakeDocument, camera: Camera, frame: int) -> list[np.ndarray]:
        """Silhouette outlines (image px) of the solved hands of ``document`` at mocap ``frame`` seen by ``camera``."""
        review = document.review
        if review is not None and document.has_solved_hands():
            hands = [(hand.side, hand.joint_angles[frame]) for hand in review.hands]
        elif document.result is not None:
            hands = [(document.result.hand_side, document.result.joint_angles[frame])]
        else:
            return []
        outlines = []
        for side, theta in hands:
            if np.isfinite(theta).all():
                outlines += silhouette_outlines(self.renderer(document.model_for(side), camera), theta)
        return outlines

    def renderer(self, model: HandModel, camera: Camera) -> HandRenderer:
        """A renderer of ``model`` into ``camera`` (kept for the last few pairs)."""
        key = (id(model), id(camera))
        if key not in self._renderers:
            if len(self._renderers) >= 4:
                self._renderers.pop(next(iter(self._renderers)))
            self._renderers[key] = HandRenderer(model, camera)
        return self._renderers[key]

    def close(self) -> None:
        self.runner.stop()
