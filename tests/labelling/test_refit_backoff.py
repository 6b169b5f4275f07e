"""A hand that stays degraded is not fitted afresh every ``hypothesis_frames`` frames to the end of the take: after
each fresh fit the wait doubles (up to MAX_RECHECK_BACKOFF times) until the hand fits as usual again (issue 25)."""

import numpy as np

import handmocap.core.labelling.scene as scene_module
from handmocap.core.labelling.models import SceneSettings
from handmocap.core.labelling.scene import label_scene
from handmocap.core.simulate import simulate_take

FRAMES = 3000


def test_a_degraded_hand_whose_fresh_fits_do_not_help_is_refitted_ever_less_often(monkeypatch):
    simulated = simulate_take(layout="dense", n_frames=FRAMES, seed=3, noise_mm=0.3, unlabelled=True)
    runs: dict[int, tuple[object, list[int]]] = {}
    original_refit, original_reinitialise = scene_module._Run._refit, scene_module._Run._reinitialise

    def never_better(self, frame, number):
        original_refit(self, frame, number)       # the fresh fit runs, but the labelling as found is kept
        return None

    def reinitialise(self, frame, number):
        labelled = int((self.assignment[frame, self.columns(number)] >= 0).sum())
        if labelled >= self.tracks[number].count // 2 + 1:          # degraded, not lost
            runs.setdefault(id(self), (self, []))[1].append(frame)
        original_reinitialise(self, frame, number)

    monkeypatch.setattr(scene_module, "DEGRADED_RATIO", 0.0)     # every frame of the hand is degraded
    monkeypatch.setattr(scene_module._Run, "_refit", never_better)
    monkeypatch.setattr(scene_module._Run, "_reinitialise", reinitialise)
    label_scene(simulated.take, "right", "dense", settings=SceneSettings(self_tuning=False, reappear_floor_mm=0.0))
    main = [frames for run, frames in runs.values() if run.make_track is not None and len(run.positions) == FRAMES]
    assert len(main) == 1
    waits = np.diff(main[0])
    hypothesis_frames = SceneSettings().hypothesis_frames
    assert len(waits) >= 4
    assert (waits[:3] >= hypothesis_frames * 2 ** np.arange(1, 4)).all(), waits
    assert len(main[0]) < FRAMES / hypothesis_frames / 4       # without the back-off: one every ~55 frames


def test_a_hypothesis_is_tracked_only_while_it_can_still_win(monkeypatch):
    """``window_cost`` with a bound: a hypothesis whose cost stays below it gets its exact cost; one that
    exceeds it stops being tracked early and reports a value above the bound (a lower bound of its cost), so
    the refit's choice is the same as with every hypothesis tracked to the end."""
    from handmocap.core.labelling.models import HandTracker
    from handmocap.core.model import load_layout, load_template, resolve_layout

    simulated = simulate_take(layout="dense", n_frames=200, seed=5, noise_mm=0.3)
    positions = np.asarray(simulated.take.marker_positions, dtype=float)
    settings = SceneSettings()
    model = load_template("right")
    markers = resolve_layout(model, load_layout("dense"))

    def track() -> HandTracker:
        return HandTracker("right", "right", model, markers, settings)

    theta = simulated.truth["joint_angles"][10]
    right = np.arange(len(markers.names))          # the simulated (labelled) take: column k is marker k
    wrong = right.copy()
    wrong[[3, 4, 5, 6]] = wrong[[6, 5, 4, 3]]                        # two fingers' markers exchanged
    tracked: list[int] = []
    original = scene_module._Run.track_frame
    monkeypatch.setattr(scene_module._Run, "track_frame",
                        lambda self, frame: (tracked.append(frame), original(self, frame))[1])
    exact_right = scene_module.window_cost(track(), positions, 10, right, theta, settings)
    exact_wrong = scene_module.window_cost(track(), positions, 10, wrong, theta, settings)
    assert exact_right < exact_wrong
    full = len(tracked)
    tracked.clear()
    assert scene_module.window_cost(track(), positions, 10, right, theta, settings, bound=exact_wrong) == exact_right
    assert len(tracked) == settings.hypothesis_frames
    tracked.clear()
    cut = scene_module.window_cost(track(), positions, 10, wrong, theta, settings, bound=exact_right)
    assert exact_right < cut <= exact_wrong
    assert len(tracked) < settings.hypothesis_frames
    assert full == 2 * settings.hypothesis_frames
