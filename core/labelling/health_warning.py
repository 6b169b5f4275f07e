"""One doubt an automatic labelling has about its result (:class:`HealthWarning`) and the kinds of doubt."""

from __future__ import annotations

from dataclasses import asdict, dataclass

#: kinds of :class:`HealthWarning`, with what each means (shown as a tooltip in the review)
WARNING_KINDS = {
    "low_labelled_share": "a model labels a small share of its markers over these frames",
    "many_ghosts": "many points were rejected as ghosts, more than the noise estimate explains",
    "side_uncertain": "left and right fit this hand almost equally well: check the side",
    "reinitialised": "a model was re-initialised here: its labels before and after may differ",
    "high_residual": "the fit is much worse here than over the rest of the take",
    "no_hand": "no hand was found in the take",
    "noisy_take": "the markers are noisier than a well-calibrated system gives",
    "whole_take_doubt": "the lab template's distances cannot tell this hand's labelling from a whole-take "
                        "alternative (fingers cycled, tip and middle exchanged, hands exchanged)",
    "whole_take_identity": "the hand was relabelled for the whole take: the lab template's distances fit the "
                           "alternative clearly better",
}


@dataclass(frozen=True)
class HealthWarning:
    """One doubt about a labelling: ``kind`` (a key of :data:`WARNING_KINDS`), the ``model`` it is about
    ("" for the whole scene), 0-based frames ``first_frame..last_frame`` inclusive, and a one-line
    ``message`` for the operator."""

    kind: str
    model: str
    first_frame: int
    last_frame: int
    message: str

    def as_dict(self) -> dict:
        return asdict(self)

    @staticmethod
    def from_dict(values: dict) -> HealthWarning:
        return HealthWarning(str(values["kind"]), str(values["model"]), int(values["first_frame"]),
                             int(values["last_frame"]), str(values["message"]))
