"""The take's named events (C3D EVENT group) and its trim range: on the timeline, added, removed, visited."""

from __future__ import annotations

from PySide6.QtWidgets import QDialog

from handmocap.app.gui.review.dialogs import EventDialog
from handmocap.app.gui.review.part import ReviewPart
from handmocap.core.errors import HandMocapError
from handmocap.core.review import AddEvent, Command, FrameSpan, RemoveEvent, TrimTake


class TakeEvents(ReviewPart):
    """Part of :class:`~app.gui.review.controller.ReviewController`: events and trim."""

    def _show_timeline_marks(self) -> None:
        """The events on the timeline (and in Review ▸ Go to event), the trim range shaded; the current frame
        kept inside the range."""
        review = self.review
        if review is None:
            self.timeline.set_events([])
            self.events_menu.clear()
            return
        marks = review.event_frames()
        self.timeline.set_events([(frame, event.name) for frame, event in marks])
        self.timeline.set_trim(*(review.trim or (None, None)))
        self.events_menu.clear()
        for frame, event in marks:
            item = self.events_menu.addAction(f"{event.name} — frame {event.frame_number}"
                                              + (f" ({event.context})" if event.context != "General" else ""))
            item.triggered.connect(lambda _checked=False, target=frame: self.app.set_frame(target))
        self.events_menu.setEnabled(bool(marks))
        self.app.set_frame(self.app.frame)          # clamped into the trim range

    def choose_event_to_add(self) -> None:
        """Ask for an event's name and side, and add it at the current frame."""
        review = self.review
        if review is None:
            return
        names = list(dict.fromkeys(event.name for event in reversed(review.events or [])))
        dialog = EventDialog(self.host, review.frame_number(self.app.frame), names)
        if dialog.exec() == QDialog.DialogCode.Accepted:
            self.add_event(*dialog.chosen())

    def add_event(self, name: str, context: str = "General") -> FrameSpan | None:
        """Name the current frame ``name`` (an undoable step)."""
        review = self.review
        if review is None:
            return None
        return self.run_edit(lambda: AddEvent(name, review.frame_number(self.app.frame), context))

    def remove_event_here(self) -> FrameSpan | None:
        """Remove the event at the current frame (the last one named, when there are several)."""
        review = self.review
        if review is None:
            return None
        number = review.frame_number(self.app.frame)
        here = [event for event in review.events or [] if event.frame_number == number]
        if not here:
            self.status_message.emit(f"No event at frame {number}", 5000)
            return None
        return self.run_edit(lambda: RemoveEvent(here[-1].name, number))

    def go_to_event(self, forward: bool = True) -> None:
        """Go to the next (or previous) event, wrapping around the take."""
        review = self.review
        found = None if review is None else review.next_event(self.app.frame, forward)
        if found is None:
            self.status_message.emit("This take has no event (Review ▸ Add event here…)", 5000)
            return
        self.app.set_frame(found[0])
        event = found[1]
        self.status_message.emit(f"Event '{event.name}' at frame {event.frame_number}", 5000)

    def trim_to_range(self) -> FrameSpan | None:
        """Trim the take to the range marked with I and O (an undoable step)."""
        def make() -> Command:
            selection = self.selection
            if selection.range_in is None or selection.range_out is None:
                raise HandMocapError("mark the range to keep first: I at its first frame, O at its last")
            start, stop = sorted((selection.range_in, selection.range_out))
            return TrimTake(start, stop + 1)
        return self.run_edit(make)

    def keep_whole_take(self) -> FrameSpan | None:
        """Undo the trim: every frame is shown, played and exported again (an undoable step)."""
        return self.run_edit(lambda: TrimTake(None, None))
