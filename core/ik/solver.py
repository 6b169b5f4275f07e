"""Marker-driven IK of a whole take: full, subspace and layered (subspace, then full with soft prior).

The subspace size defaults to one principal component per finger marker (2 to 6).
Damping scale: residuals are in mm and posture parameters in rad, so ``posture_damping`` is in
mm/rad: a value of 2 costs a 1 rad step as much as a 2 mm marker error. It slows steps, it does not
bias the converged solution (the damping acts on the update δθ, not on θ).
The soft PCA prior (thesis §6.4.4) weighs √ω₄ = ``prior_weight`` mm/rad per off-subspace radian;
in layered IK it holds only the digits whose three segments are not all observed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from handmocap.core.errors import CancelledError, InputError
from handmocap.core.ik.kernel import frame_energy_kernel, solve_frame_kernel
from handmocap.core.io.durable import durable_stream, verify_zip
from handmocap.core.model import HandModel, MarkerLayout, MarkerSet, marker_columns, marker_positions, resolve_layout
from handmocap.core.model.joint_angles import write_joint_angles_csv
from handmocap.core.model.kinematics import ANCESTOR, vector_from_rotation
from handmocap.core.model.skeleton import N_PARAMS, PARAM_NAMES, default_joint_limits
from handmocap.core.prior import load_default_prior

METHODS = ("layered", "subspace", "full")
LOST_TRACK_MM = 30.0
HISTORY_FRAMES = 3        # solutions kept: two for the linear prediction, one more for replace_last


@dataclass(frozen=True)
class IKSettings:
    """Tuning of the per-frame solver (units in the module docstring)."""

    method: str = "layered"
    subspace_dims: int | None = None
    posture_damping: float = 2.0
    prior_weight: float = 10.0
    prior_mean_ratio: float = 0.1
    max_iterations: int = 10
    tolerance: float = 1e-6
    predict: bool = True


@dataclass
class IKResult:
    """Per-frame IK output. ``joint_angles (F,26)`` rad/mm, ``residuals_mm (F,M)`` (NaN unobserved),
    ``effector_positions (F,M,3)`` mm, ``marker_names (M,)`` in layout order, ``hand_side`` of the model."""

    joint_angles: np.ndarray
    residuals_mm: np.ndarray
    effector_positions: np.ndarray
    marker_names: list[str]
    method: str
    frame_rate: float = 100.0
    first_frame: int = 1
    hand_side: str = "right"

    @property
    def mean_residual_mm(self) -> float:
        return float(np.nanmean(self.residuals_mm)) if np.isfinite(self.residuals_mm).any() else float("nan")

    def save(self, path: str | Path) -> None:
        """Write ``.npz`` through :mod:`core.io.durable` (WriteError naming the file on failure)."""
        with durable_stream(path, verify=verify_zip) as stream:
            np.savez_compressed(stream, joint_angles=self.joint_angles, residuals_mm=self.residuals_mm,
                                effector_positions=self.effector_positions,
                                marker_names=np.array(self.marker_names), method=self.method,
                                frame_rate=self.frame_rate, first_frame=self.first_frame, hand_side=self.hand_side,
                                param_names=np.array(PARAM_NAMES))

    def save_csv(self, path: str | Path) -> None:
        """Joint angles as CSV (see :func:`core.model.joint_angles.write_joint_angles_csv`)."""
        write_joint_angles_csv(path, [("", self.joint_angles)], self.first_frame, self.frame_rate)


def kabsch(source: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation (3,3) and translation (3,) that best map ``source (N,3)`` onto ``target (N,3)``."""
    source_centre, target_centre = source.mean(axis=0), target.mean(axis=0)
    covariance = (source - source_centre).T @ (target - target_centre)
    u, _, vt = np.linalg.svd(covariance)
    sign = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    rotation = vt.T @ np.diag([1.0, 1.0, sign]) @ u.T
    return rotation, target_centre - rotation @ source_centre


class IKSolver:
    """Solves frames of one marker set on one model, warm-starting from the previous frames."""

    def __init__(self, model: HandModel, markers: MarkerSet, prior=None, settings: IKSettings | None = None):
        self.settings = settings or IKSettings()
        if self.settings.method not in METHODS:
            raise InputError(f"unknown IK method '{self.settings.method}' (use {', '.join(METHODS)})")
        if self.settings.method != "full" and prior is None:
            prior = load_default_prior()
        self.model, self.markers, self.prior = model, markers, prior
        lower, upper = default_joint_limits()
        if prior is not None:
            lower = np.maximum(lower, np.concatenate([lower[:6], prior.angle_lower]))
            upper = np.minimum(upper, np.concatenate([upper[:6], prior.angle_upper]))
        self.angle_lower, self.angle_upper = lower[6:].copy(), upper[6:].copy()
        self._lower, self._upper = lower, upper
        self._marker_digit_segment = self._digit_segments(markers)
        self._prior_weight_cache: dict[bytes, np.ndarray] = {}
        self._setup_spaces()
        self.reset()

    @staticmethod
    def _digit_segments(markers: MarkerSet) -> np.ndarray:
        """Joint (1..15) that carries each marker most, -1 for the palm/wrist, (M,)."""
        dominant = markers.influence_joints[np.arange(len(markers.names)),
                                            markers.influence_weights.argmax(axis=1)]
        return np.where(dominant > 0, dominant, -1)

    def _setup_spaces(self) -> None:
        settings = self.settings
        self._full_space = (np.eye(20), np.zeros(20), self.angle_lower, self.angle_upper)
        no_prior = np.zeros(20)
        self._zero_prior = (np.zeros((20, 20)), np.zeros(20), no_prior)
        if self.prior is None:
            return
        dims = min(settings.subspace_dims or self.automatic_subspace_dims(),
                   self.prior.components.shape[1])
        basis = np.ascontiguousarray(self.prior.components[:, :dims])
        margin = 0.25 * (self.prior.alpha_upper[:dims] - self.prior.alpha_lower[:dims])
        self._subspace = (basis, self.prior.mean.copy(), self.prior.alpha_lower[:dims] - margin,
                          self.prior.alpha_upper[:dims] + margin)
        inverse_sigma_sq = 1.0 / np.maximum(self.prior.stddev[:dims], 1e-6) ** 2
        shrink = 1.0 / (settings.prior_mean_ratio * inverse_sigma_sq + 1.0)
        self._prior_matrix = np.ascontiguousarray(np.eye(20) - basis @ np.diag(shrink) @ basis.T)

    def automatic_subspace_dims(self) -> int:
        """Subspace size matched to the layout: one PC per marker on a finger, 2 to 6 (journal: l is
        the control variable for the number of markers k; 3–6 PCs cover 90 % of hand motion)."""
        return int(np.clip((self._marker_digit_segment > 0).sum(), 2, 6))

    def reset(self) -> None:
        """Forget the previous frames (the next frame is initialised from scratch)."""
        self._history: list[np.ndarray] = []
        self._global_free = True

    def _prior_weights(self, observed: np.ndarray) -> np.ndarray:
        """√ω₄ on the four parameters of every digit whose three segments are not all observed (cached
        per observation pattern)."""
        key = observed.tobytes()
        weights = self._prior_weight_cache.get(key)
        if weights is None:
            weights = np.zeros(20)
            seen = set(self._marker_digit_segment[observed].tolist())
            for digit in range(5):
                if not all(1 + 3 * digit + segment in seen for segment in range(3)):
                    weights[4 * digit:4 * digit + 4] = self.settings.prior_weight
            self._prior_weight_cache[key] = weights
        return weights

    def refine(self, start: np.ndarray, targets: np.ndarray, observed: np.ndarray
               ) -> tuple[np.ndarray, float, np.ndarray]:
        """The refinement step of layered IK alone, warm-started: full IK from ``start (26,)`` with the
        soft posture prior on the digits not fully observed, global pose free. ``targets (M,3)`` mm
        (finite; read where ``observed (M,)``). Returns θ (26,), the energy and the effectors (M,3) mm."""
        self._global_free = True
        prior = (self._prior_matrix, self.prior.mean, self._prior_weights(observed))
        return self._run("full", start, targets, observed, prior)

    def solve_from_alignment(self, targets: np.ndarray, observed: np.ndarray
                             ) -> tuple[np.ndarray, float, np.ndarray]:
        """This solver's method from a rigid alignment of the mean posture to the targets (no warm
        start), global pose free; arguments and result as :meth:`refine`."""
        self._global_free = True
        return self._solve_from(self.initial_pose(targets, observed), targets, observed)

    def initial_pose(self, targets: np.ndarray, observed: np.ndarray) -> np.ndarray:
        """Global pose by rigid alignment of the markers at the mean posture to the observed targets."""
        theta = np.zeros(N_PARAMS)
        theta[6:] = np.clip(self.prior.mean if self.prior is not None else 0.0, self.angle_lower,
                            self.angle_upper)
        model_points = marker_positions(self.model, self.markers, theta)[observed]
        observed_targets = targets[observed]
        if len(observed_targets) >= 3:
            rotation, translation = kabsch(model_points, observed_targets)
            theta[3:6] = vector_from_rotation(rotation)
            theta[0:3] = translation
        else:
            theta[0:3] = observed_targets.mean(axis=0) - model_points.mean(axis=0)
        return theta

    def _run(self, space_name: str, start: np.ndarray, targets: np.ndarray, observed: np.ndarray,
             prior: tuple[np.ndarray, np.ndarray, np.ndarray]) -> tuple[np.ndarray, float, np.ndarray]:
        basis, centre, lower, upper = self._subspace if space_name == "subspace" else self._full_space
        chain = self.model.chain
        return solve_frame_kernel(
            start, targets, observed, chain.relative_rest, chain.offsets, chain.abduction_sign, ANCESTOR,
            self.markers.influence_joints, self.markers.influence_weights, self.markers.local_points,
            basis, centre, lower, upper, self.settings.posture_damping, prior[0], prior[1],
            prior[2], self.angle_lower, self.angle_upper, self.settings.max_iterations,
            self.settings.tolerance, self._global_free)

    def _solve_from(self, start: np.ndarray, targets: np.ndarray,
                    observed: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
        method = self.settings.method
        if method == "full":
            return self._run("full", start, targets, observed, self._zero_prior)
        solution = self._run("subspace", start, targets, observed, self._zero_prior)
        if method == "subspace":
            return solution
        prior = (self._prior_matrix, self.prior.mean, self._prior_weights(observed))
        # refine from the subspace solution, or from the warm-start prediction when that is better
        refine_start = solution[0]
        if self._history and self._energy(start, targets, observed, prior) < self._energy(
                refine_start, targets, observed, prior):
            refine_start = start
        return self._run("full", refine_start, targets, observed, prior)

    def _energy(self, theta: np.ndarray, targets: np.ndarray, observed: np.ndarray,
                prior: tuple[np.ndarray, np.ndarray, np.ndarray]) -> float:
        chain = self.model.chain
        return frame_energy_kernel(np.clip(theta, self._lower, self._upper), targets, observed,
                                   chain.relative_rest, chain.offsets, chain.abduction_sign,
                                   self.markers.influence_joints, self.markers.influence_weights,
                                   self.markers.local_points, prior[0], prior[1], prior[2])

    def solve_frame(self, targets: np.ndarray, global_pose: np.ndarray | None = None,
                    replace_last: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Joint angles (26,) and effector positions (M,3) mm for one frame of targets (M,3) mm
        (NaN = unobserved). With nothing observed the previous posture is held (NaN before any).
        ``global_pose (6,)``, when given (e.g. from a tracked wrist rigid body), is held fixed.
        ``replace_last``: solve the same frame again (other targets), replacing its previous solution."""
        if replace_last and self._history:
            self._history.pop()
        self._global_free = global_pose is None
        observed = np.isfinite(targets).all(axis=1)
        if not observed.any():
            if not self._history:
                return np.full(N_PARAMS, np.nan), np.full(targets.shape, np.nan)
            held = self._history[-1].copy()
            self._history = (self._history + [held])[-HISTORY_FRAMES:]
            return held, marker_positions(self.model, self.markers, held)
        clean_targets = np.where(observed[:, None], targets, 0.0)
        if not self._history:
            start = self.initial_pose(clean_targets, observed)
        elif self.settings.predict and len(self._history) >= 2:
            start = 2.0 * self._history[-1] - self._history[-2]
        else:
            start = self._history[-1].copy()
        if global_pose is not None:
            start[:6] = global_pose
        theta, energy, points = self._solve_from(start, clean_targets, observed)
        if energy > LOST_TRACK_MM ** 2 * observed.sum():
            fresh_start = self.initial_pose(clean_targets, observed)
            if global_pose is not None:
                fresh_start[:6] = global_pose
            restart = self._solve_from(fresh_start, clean_targets, observed)
            if restart[1] < energy:
                theta, energy, points = restart
        self._history = (self._history + [theta])[-HISTORY_FRAMES:]
        return theta, points


def match_layout(marker_names: list[str], layout: MarkerLayout) -> np.ndarray:
    """Column of each layout marker in a take's marker list, -1 where the take lacks it, (M_layout,)."""
    columns = marker_columns(marker_names, layout.names)
    if (columns < 0).all():
        raise InputError(f"no marker of layout '{layout.name}' is in the take "
                         f"(layout: {', '.join(layout.names[:6])}…; take: {', '.join(marker_names[:6])}…)")
    return columns


def solve_positions(targets: np.ndarray, model: HandModel, markers: MarkerSet, prior=None,
                    settings: IKSettings | None = None,
                    progress: Callable[[float], None] | None = None,
                    cancelled: Callable[[], bool] | None = None,
                    global_poses: np.ndarray | None = None) -> IKResult:
    """IK for targets (F,M,3) mm in the marker set's order; raises CancelledError when cancelled.
    ``global_poses (F,6)``: wrist pose per frame when known from elsewhere (held fixed), else solved."""
    solver = IKSolver(model, markers, prior, settings)
    frames = len(targets)
    angles = np.full((frames, N_PARAMS), np.nan)
    effectors = np.full((frames, len(markers.names), 3), np.nan)
    report_every = max(1, frames // 100)
    for frame in range(frames):
        angles[frame], effectors[frame] = solver.solve_frame(
            targets[frame], None if global_poses is None else global_poses[frame])
        if frame % report_every == 0:
            if cancelled is not None and cancelled():
                raise CancelledError("IK cancelled; the take is unchanged")
            if progress is not None:
                progress(frame / max(frames, 1))
    if progress is not None:
        progress(1.0)
    residuals = np.linalg.norm(effectors - targets, axis=2)
    return IKResult(angles, residuals, effectors, list(markers.names), solver.settings.method,
                    hand_side=model.side)


def solve_take(take, model: HandModel, layout: MarkerLayout, prior=None, method: str = "layered",
               progress: Callable[[float], None] | None = None,
               cancelled: Callable[[], bool] | None = None,
               settings: IKSettings | None = None) -> IKResult:
    """IK of a labelled take (``core.io.Take``) with ``layout``: markers are matched by name."""
    if take.n_frames == 0:
        raise InputError("the take has no frames")
    columns = match_layout(take.marker_names, layout)
    targets = np.full((take.n_frames, len(columns), 3), np.nan)
    present = columns >= 0
    targets[:, present] = take.marker_positions[:, columns[present]]
    settings = settings or IKSettings(method=method)
    if settings.method != method:
        settings = IKSettings(**{**settings.__dict__, "method": method})
    result = solve_positions(targets, model, resolve_layout(model, layout), prior, settings, progress, cancelled)
    result.frame_rate, result.first_frame = take.frame_rate, take.first_frame
    return result
