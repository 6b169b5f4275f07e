"""Online adaptive posture subspace (thesis Ch. 5.4): a fixed anchor ``P`` (20×l principal components of the
posture prior) and a corrective matrix ``C`` (20×d) learnt from the solved postures that leave the anchor space.

Each solved posture's anchor residual ``s = (I − P Pᵀ)(θ − μ)`` (eq. 5.6) is kept in a FIFO buffer of ``N``
samples when ``s_min < ‖s‖ < s_max`` (thesis: 0.1 and 3 rad); the buffer's mean and covariance are updated
incrementally (eq. 5.9–5.10) and ``C`` holds the covariance's top ``d`` eigenvectors once the buffer is full.
The soft PCA prior (thesis §6.4.4) is then taken over ``[P C]``: postures the subject keeps making outside the
prior's subspace stop being pulled back into it.
"""

from __future__ import annotations

import numpy as np

from handmocap.core.prior import PosturePrior


class AdaptiveSubspace:
    """Anchor ``P`` (first ``anchor_dims`` components of ``prior``) plus ``corrective_dims`` learnt columns."""

    def __init__(self, prior: PosturePrior, anchor_dims: int = 3, corrective_dims: int = 3, buffer: int = 30,
                 residual_range: tuple[float, float] = (0.1, 3.0)) -> None:
        self.mean = prior.mean.copy()
        self.anchor = prior.components[:, :anchor_dims].copy()
        self.anchor_stddev = prior.stddev[:anchor_dims].copy()
        self.corrective = np.zeros((self.mean.size, 0))
        self.corrective_stddev = np.zeros(0)
        self.dims, self.capacity, self.residual_range = corrective_dims, buffer, residual_range
        self._buffer: list[np.ndarray] = []
        self._sample_mean = np.zeros(self.mean.size)
        self._covariance = np.zeros((self.mean.size, self.mean.size))
        self.accepted = 0
        self.offered = 0
        self.updates = 0

    def residual(self, posture: np.ndarray) -> np.ndarray:
        """The anchor-space residual (20,) rad of ``posture (20,)`` (eq. 5.6)."""
        centred = posture - self.mean
        return centred - self.anchor @ (self.anchor.T @ centred)

    def offer(self, posture: np.ndarray) -> bool:
        """Add a solved posture (20,) rad; True when its residual was kept (and ``C`` possibly updated)."""
        self.offered += 1
        sample = self.residual(posture)
        size = float(np.linalg.norm(sample))
        if not self.residual_range[0] < size < self.residual_range[1]:
            return False
        self.accepted += 1
        self._buffer.append(sample)
        count = self.capacity
        if len(self._buffer) < count:
            return True
        if len(self._buffer) == count:
            stacked = np.array(self._buffer)
            self._sample_mean = stacked.mean(axis=0)
            centred = stacked - self._sample_mean
            self._covariance = centred.T @ centred / count                                   # eq. 5.7
        else:
            outgoing = self._buffer.pop(0)
            previous_mean = self._sample_mean
            self._sample_mean = previous_mean + (sample - outgoing) / count                    # eq. 5.9
            self._covariance = (self._covariance + (np.outer(sample, sample) - np.outer(outgoing, outgoing)) / count
                                + np.outer(previous_mean, previous_mean)
                                - np.outer(self._sample_mean, self._sample_mean))          # eq. 5.10
        values, vectors = np.linalg.eigh(self._covariance)
        order = np.argsort(values)[::-1][:self.dims]
        corrective = vectors[:, order]
        corrective -= self.anchor @ (self.anchor.T @ corrective)    # in the anchor's null space (numerically)
        corrective /= np.maximum(np.linalg.norm(corrective, axis=0), 1e-12)
        self.corrective = corrective
        self.corrective_stddev = np.sqrt(np.maximum(values[order], 0.0))
        self.updates += 1
        return True

    def prior_matrix(self, omega4: float = 1.0, omega5: float = 0.0) -> np.ndarray:
        """``A = I − B M Bᵀ`` (20,20) of the soft prior over ``B = [P C]`` (see
        :func:`core.prior.pca_prior.soft_prior_matrix`); ``omega5 = 0``: orthogonal complement of the span."""
        basis = np.hstack([self.anchor, self.corrective])
        variance = np.concatenate([self.anchor_stddev, self.corrective_stddev]) ** 2
        denominator = omega5 + omega4 * variance
        shrink = np.divide(omega4 * variance, denominator, out=np.ones(len(variance)), where=denominator > 0)
        return np.eye(self.mean.size) - (basis * shrink) @ basis.T

    def report(self) -> dict:
        """What the adaptation did: postures offered and kept, ``C`` updates, corrective standard deviations (deg)."""
        return {"postures_offered": self.offered, "residuals_kept": self.accepted, "corrective_updates": self.updates,
                "corrective_stddev_deg": [round(float(np.degrees(value)), 2) for value in self.corrective_stddev]}
