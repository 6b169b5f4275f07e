"""PCA posture prior over the 20 finger angles (journal "Subspace prior", thesis §3.2.3 and §6.4.4).

A :class:`PosturePrior` holds the mean posture, the principal components sorted by variance, their
standard deviations, the range of the training projections (PC-space limits for joint-limit
avoidance, thesis §3.2.3) and the training angle range (a prior may narrow the joint limits).
Subspace IK uses ``theta[6:] = P alpha + mean`` with ``P = components[:, :dims]``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io.durable import durable_stream, verify_zip
from handmocap.core.io.npz import load_npz
from handmocap.core.io.resources import resource_path
from handmocap.core.model.joint_angles import read_result_joint_angles
from handmocap.core.model.skeleton import N_GLOBAL, N_POSTURE, default_joint_limits
from handmocap.core.prior.canonical_postures import prior_postures

DEFAULT_PRIOR_PATH = resource_path("priors", "default_prior.npz")

#: the training angle range is widened by this margin (rad, 5°) before clipping to the default limits
ANGLE_RANGE_MARGIN = np.radians(5.0)

# Default prior samples (build_default_prior): each prior-set canonical posture plus NOISY_COPIES
# copies with Gaussian noise of NOISE_DEG per angle, and INTERPOLATIONS postures on the segment
# between two random distinct prior-set postures (uniform blend factor) with the same noise.
NOISY_COPIES = 10
INTERPOLATIONS = 3000
NOISE_DEG = 2.0

_ARRAY_FIELDS = ("mean", "components", "stddev", "explained_variance_ratio", "alpha_lower", "alpha_upper",
                 "angle_lower", "angle_upper")


@dataclass(frozen=True, eq=False)
class PosturePrior:
    """PCA of 20-D finger postures (radians).

    ``mean (20,)``; ``components (20, K)`` orthonormal columns sorted by decreasing variance;
    ``stddev (K,)`` standard deviation along each component; ``explained_variance_ratio (K,)`` share
    of the total variance per component; ``alpha_lower``/``alpha_upper (K,)`` min/max of the training
    projections ``componentsᵀ (posture - mean)``; ``angle_lower``/``angle_upper (20,)`` training range
    widened by :data:`ANGLE_RANGE_MARGIN` and clipped to :func:`default_joint_limits`.
    """

    mean: np.ndarray
    components: np.ndarray
    stddev: np.ndarray
    explained_variance_ratio: np.ndarray
    alpha_lower: np.ndarray
    alpha_upper: np.ndarray
    angle_lower: np.ndarray
    angle_upper: np.ndarray
    source: str
    n_samples: int

    @property
    def n_components(self) -> int:
        return self.components.shape[1]

    def subspace(self, dims: int) -> tuple[np.ndarray, np.ndarray]:
        """The first ``dims`` components ``P (20, dims)`` and the mean ``(20,)``."""
        if not 1 <= dims <= self.n_components:
            raise InputError(f"the prior has {self.n_components} components; cannot use {dims}")
        return self.components[:, :dims].copy(), self.mean.copy()

    def cumulative_variance(self) -> np.ndarray:
        """Share of the variance explained by the first 1, 2, ..., K components ``(K,)``."""
        return np.cumsum(self.explained_variance_ratio)

    def save(self, path: str | Path) -> None:
        """Store as ``.npz`` through :mod:`core.io.durable` (WriteError naming the file on failure)."""
        with durable_stream(path, verify=verify_zip) as stream:
            np.savez_compressed(stream, source=np.array(self.source), n_samples=np.array(self.n_samples),
                                **{name: getattr(self, name) for name in _ARRAY_FIELDS})

    @classmethod
    def load(cls, path: str | Path) -> PosturePrior:
        """Read a prior written by :meth:`save`; :class:`InputError` when the file is not one."""
        name = Path(path).name
        data = load_npz(path, "a posture prior file")
        try:
            arrays = {field: np.asarray(data[field], dtype=float) for field in _ARRAY_FIELDS}
            prior = cls(**arrays, source=str(data["source"]), n_samples=int(data["n_samples"]))
        except (KeyError, ValueError, TypeError) as error:
            raise InputError(f"{name}: not a posture prior file ({error})") from error
        problem = prior.problem()
        if problem:
            raise InputError(f"{name}: invalid posture prior ({problem})")
        return prior

    def problem(self) -> str:
        """A description of the first inconsistency of the arrays, or ``""`` when consistent."""
        if self.mean.shape != (N_POSTURE,) or self.components.shape[:1] != (N_POSTURE,) \
                or self.components.ndim != 2:
            return "mean must be (20,) and components (20, K)"
        count = self.components.shape[1]
        if count == 0:
            return "no components"
        for field in ("stddev", "explained_variance_ratio", "alpha_lower", "alpha_upper"):
            if getattr(self, field).shape != (count,):
                return f"{field} must be ({count},)"
        for field in ("angle_lower", "angle_upper"):
            if getattr(self, field).shape != (N_POSTURE,):
                return f"{field} must be (20,)"
        if not all(np.all(np.isfinite(getattr(self, field))) for field in _ARRAY_FIELDS):
            return "non-finite values"
        if not np.allclose(self.components.T @ self.components, np.eye(count), atol=1e-6):
            return "components are not orthonormal"
        if np.any(np.diff(self.stddev) > 1e-12) or np.any(self.stddev < 0):
            return "standard deviations must be non-negative and sorted"
        if np.any(self.angle_lower > self.angle_upper) or np.any(self.alpha_lower > self.alpha_upper):
            return "lower limits above upper limits"
        return ""


def build_prior(postures: np.ndarray, source: str) -> PosturePrior:
    """PCA (by SVD) of finger postures ``(N, 20)`` rad; ``source`` says where they came from.

    Keeps ``K = min(N - 1, 20)`` components. :class:`InputError` for ``N < 3``, a wrong shape or
    non-finite rows.
    """
    postures = np.asarray(postures, dtype=float)
    if postures.ndim != 2 or postures.shape[1] != N_POSTURE:
        raise InputError(f"postures must be (N, 20) finger angles, got shape {postures.shape}")
    if len(postures) < 3:
        raise InputError(f"a posture prior needs at least 3 postures, got {len(postures)}")
    if not np.all(np.isfinite(postures)):
        raise InputError("postures contain NaN or infinite values")
    mean = postures.mean(axis=0)
    centred = postures - mean
    _, singular_values, right_vectors = np.linalg.svd(centred, full_matrices=False)
    count = min(len(postures) - 1, N_POSTURE)
    components = right_vectors[:count].T
    # fix each component's sign (largest entry positive) so that rebuilt priors compare equal
    signs = np.sign(components[np.argmax(np.abs(components), axis=0), np.arange(count)])
    components = components * np.where(signs == 0, 1.0, signs)
    variance = singular_values**2 / (len(postures) - 1)
    total = variance.sum()
    projections = centred @ components
    default_lower, default_upper = default_joint_limits()
    low, high = default_lower[N_GLOBAL:], default_upper[N_GLOBAL:]
    return PosturePrior(
        mean=mean,
        components=components,
        stddev=np.sqrt(variance[:count]),
        explained_variance_ratio=variance[:count] / total if total > 0 else np.zeros(count),
        alpha_lower=projections.min(axis=0),
        alpha_upper=projections.max(axis=0),
        angle_lower=np.clip(postures.min(axis=0) - ANGLE_RANGE_MARGIN, low, high),
        angle_upper=np.clip(postures.max(axis=0) + ANGLE_RANGE_MARGIN, low, high),
        source=source,
        n_samples=len(postures),
    )


def default_prior_samples(seed: int = 0) -> np.ndarray:
    """The training postures ``(N, 20)`` rad of the default prior (see the constants above)."""
    rng = np.random.default_rng(seed)
    canonical = np.array(list(prior_postures().values()))
    count = len(canonical)
    noise = np.radians(NOISE_DEG)
    copies = np.repeat(canonical, NOISY_COPIES, axis=0)
    copies += rng.normal(0.0, noise, copies.shape)
    first = rng.integers(0, count, INTERPOLATIONS)
    second = (first + rng.integers(1, count, INTERPOLATIONS)) % count
    blend = rng.uniform(0.0, 1.0, (INTERPOLATIONS, 1))
    blended = (1.0 - blend) * canonical[first] + blend * canonical[second]
    blended += rng.normal(0.0, noise, blended.shape)
    lower, upper = default_joint_limits()
    samples = np.vstack([canonical, copies, blended])
    return np.clip(samples, lower[N_GLOBAL:], upper[N_GLOBAL:])


def build_default_prior(seed: int = 0) -> PosturePrior:
    """The shipped prior: PCA of :func:`default_prior_samples` (prior-set canonical postures,
    noisy copies and pairwise interpolations; the held-out grasps are not used)."""
    samples = default_prior_samples(seed)
    count = len(prior_postures())
    source = (f"default: {count} authored canonical postures + {count * NOISY_COPIES} noisy copies + "
              f"{INTERPOLATIONS} pairwise interpolations (noise {NOISE_DEG:g} deg, seed {seed})")
    return build_prior(samples, source)


def build_prior_from_results(paths: list[str | Path]) -> PosturePrior:
    """A prior from solved takes: result ``.npz`` files holding ``joint_angles (F, 26)`` rad.

    Frames with any NaN angle are dropped. :class:`InputError` for unreadable files or too few frames.
    """
    if not paths:
        raise InputError("no result files given to build a posture prior from")
    postures = [angles[np.all(np.isfinite(angles), axis=1), N_GLOBAL:]
                for angles in map(read_result_joint_angles, paths)]
    names = ", ".join(Path(path).name for path in paths)
    return build_prior(np.vstack(postures), f"results: {names}")


def write_default_prior(path: str | Path = DEFAULT_PRIOR_PATH, seed: int = 0) -> PosturePrior:
    """Build the default prior and store it at ``path``."""
    prior = build_default_prior(seed)
    prior.save(path)
    return prior


@lru_cache(maxsize=1)
def load_default_prior() -> PosturePrior:
    """The shipped default prior (read once, then cached)."""
    if not DEFAULT_PRIOR_PATH.exists():
        raise InputError(f"default posture prior missing: {DEFAULT_PRIOR_PATH} "
                         "(regenerate it with core.prior.write_default_prior())")
    return PosturePrior.load(DEFAULT_PRIOR_PATH)


def describe_prior(prior: PosturePrior) -> str:
    """A text table of the variance explained per component and cumulatively."""
    lines = [f"posture prior: {prior.source}", f"{prior.n_samples} samples, {prior.n_components} components",
             " PC  stddev(deg)  variance  cumulative"]
    cumulative = prior.cumulative_variance()
    for index in range(prior.n_components):
        share = 100 * prior.explained_variance_ratio[index]
        lines.append(f"{index + 1:3d}  {np.degrees(prior.stddev[index]):10.2f}  {share:7.2f} %  "
                     f"{100 * cumulative[index]:7.2f} %")
    return "\n".join(lines)


def soft_prior_matrix(prior: PosturePrior, dims: int, omega4: float, omega5: float) -> np.ndarray:
    """``A = I - P M Pᵀ (20, 20)`` of the soft PCA prior (thesis §6.4.4).

    ``E_posture = omega4 ‖A (theta[6:] - mean)‖²`` with ``P`` the first ``dims`` components and
    ``M = omega4 (omega5 Σ² + omega4 I)⁻¹``, ``Σ = diag(1 / stddev)``; written per component as
    ``omega4 σ² / (omega5 + omega4 σ²)`` so that zero-variance components are safe. ``omega5 = 0``
    gives the orthogonal projector onto the complement of the subspace.
    """
    if omega4 <= 0 or omega5 < 0:
        raise InputError(f"soft prior weights must be omega4 > 0 and omega5 >= 0, got {omega4}, {omega5}")
    basis, _ = prior.subspace(dims)
    variance = prior.stddev[:dims] ** 2
    denominator = omega5 + omega4 * variance
    shrink = np.divide(omega4 * variance, denominator, out=np.ones(dims), where=denominator > 0)
    return np.eye(N_POSTURE) - (basis * shrink) @ basis.T

