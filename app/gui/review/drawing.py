"""The review's drawing of one frame in the 3D view: labelled points, fills, solved hands, the trail."""

from __future__ import annotations

import numpy as np

from handmocap.app.gui.review.colours import label_colours, point_colours
from handmocap.app.gui.review.part import ReviewPart
from handmocap.core.model import marker_positions, skin_vertices

FILL_COLOUR = (0.45, 0.95, 0.55)
RIGID_SELECTION_COLOUR = (1.0, 1.0, 1.0)
TRAIL_FRAMES = 60                  # frames of trail on each side of the current frame



class FrameDrawing(ReviewPart):
    """Part of :class:`~app.gui.review.controller.ReviewController`: draws a frame of the review."""

    def draw_frame(self, frame: int) -> None:
        """Draw ``frame`` of the review when the take has labels or is raw: every raw point coloured by the
        label it holds (grey when unlabelled, dark red for ghosts), accepted fills as green dots, the solved
        hands with their effectors and residual lines, and the trail of the selected label."""
        document, review = self.document, self.review
        if document is None or review is None or not (document.has_labels() or document.is_raw):
            return
        viewport = self.viewport
        labels = review.assignment[frame]
        point_label = np.full(review.n_points, -1, dtype=np.int64)
        taken = labels >= 0
        point_label[labels[taken]] = np.flatnonzero(taken)
        colours = point_colours(review, frame)
        colours[self.selection.rigid_points] = RIGID_SELECTION_COLOUR
        palette = label_colours(review.n_labels)
        names = [review.label_names[label] if label >= 0 else f"*{column}"
                 for column, label in enumerate(point_label)]
        viewport.set_marker_names(names)
        viewport.set_marker_colours(colours)
        viewport.set_rigid_bodies(review.rigid_body_segments(frame))
        fills = review.provenance[frame] > 0
        fill_colours = palette[fills] * 0.5 + np.array(FILL_COLOUR) * 0.5
        viewport.set_loose_points(review.filled_positions[frame, fills], fill_colours)
        effectors, targets = [], []
        labelled = review.labelled_positions_in(frame, frame + 1)[0]
        for number, hand in enumerate(review.hands):
            theta = hand.joint_angles[frame]
            if not np.isfinite(theta).all():
                continue
            model = document.model_for(hand.side)
            viewport.update_hand_vertices(skin_vertices(model, theta), number)
            markers = document.marker_set_for(hand.side, hand.layout, [review.label_names[label]
                                                                        for label in hand.labels])
            if markers is not None and len(markers.names) == len(hand.labels):
                effectors.append(marker_positions(model, markers, theta))
                targets.append(labelled[hand.labels])
        if effectors:
            viewport.set_effectors(np.concatenate(effectors), np.concatenate(targets))
        else:
            viewport.set_effectors(None)
        self._draw_trail(frame)
        self.lanes.set_frame(frame)

    def _draw_trail(self, frame: int) -> None:
        review, label = self.review, self.selection.label
        if review is None or label < 0 or label >= review.n_labels:
            self.viewport.set_trails([])
            return
        first, last = max(0, frame - TRAIL_FRAMES), min(review.n_frames, frame + TRAIL_FRAMES + 1)
        trail = review.labelled_positions_in(first, last)[:, label]
        self.viewport.set_trails([trail], label_colours(review.n_labels)[[label]])

    def _set_hand_meshes(self) -> None:
        document = self.document
        if document is None or document.review is None:
            return
        meshes = []
        for hand in document.review.hands:
            model = document.model_for(hand.side)
            meshes.append((model.vertices, model.faces))
        if meshes:
            self.viewport.set_hand_meshes(meshes)
