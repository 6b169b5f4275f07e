"""PCA marker-intercorrelation gap fill (Gløersen & Federolf 2016, PLoS ONE 11(3): e0152616; after
Federolf 2013, PLoS ONE 8(10): e78689).

The markers of a take move together, so a missing marker follows from the others. Around one gap of
one marker, within ``window`` frames on each side (the cost stays linear in the take's length):

1. the donors are the other markers measured from the frame before the gap to the frame after it;
   a donor that has gaps of its own in the window and is *distal* (farther from the gap marker than
   ``distal_share`` of the mean donor distance, the paper's strategy R2) is left out, so that its
   gaps do not remove training frames for little information; the near ones with gaps are added
   nearest first while enough training frames remain (many markers occluded in turn);
2. every position is expressed in a coordinate system moving with the hand: the paper subtracts the
   donors' mean per frame; here the donors' weighted centroid is subtracted and their weighted
   least-squares rotation from the frame before the gap is undone as well, so that turning the whole
   hand does not look like a change of posture;
3. the frames × (3 · markers) matrix is centred and scaled to unit variance per column on the
   training frames (every used marker measured) and each marker's columns are weighted by
   ``exp(-d² / (2 σ²))``, ``d`` the marker's mean distance to the gap marker and ``σ``
   ``weight_scale`` times the median donor distance (the paper's weights, with σ in units of the
   take's own marker spacing instead of a fixed 200 mm); the gap marker's own columns weigh
   ``gap_weight`` (the paper's 0.02), so the components describe the donors' coordination;
4. principal components of the training frames, as many as carry ``min_cumulative`` of the sum of
   the singular values (the paper's 0.99); the variance of the others is the noise;
5. per gap frame, the component scores are the least-squares fit of the donors' observed
   coordinates, regularised by that noise (the posterior mean of probabilistic PCA, so a posture
   outside the training frames is not extrapolated wildly), and the gap marker's coordinates follow
   from its loadings;
6. the reconstruction's error at the measured frame on each side of the gap is interpolated linearly
   through the gap and removed, so the fill joins the measured ends without a jump.
"""

from __future__ import annotations

import numpy as np

from handmocap.core.errors import InputError

#: frames on each side of a gap whose measured samples train the components
PCA_WINDOW = 400
#: weight of the gap marker's own coordinates in the components (Gløersen & Federolf: 0.02)
GAP_WEIGHT = 0.02
#: share of the sum of singular values the components keep (Gløersen & Federolf: 0.99)
MIN_CUMULATIVE = 0.99
#: a donor with gaps farther than this share of the mean donor distance is left out (strategy R2: 0.5)
DISTAL_SHARE = 0.5
#: σ of the distance weights, in units of the median donor distance
WEIGHT_SCALE = 1.0
#: a donor with gaps of its own is used only while the training frames number this many per column
FRAMES_PER_COLUMN = 2


def _validate(positions: np.ndarray, marker: int, start: int, length: int) -> None:
    if positions.ndim != 3 or positions.shape[2] != 3:
        raise InputError(f"PCA fill: positions must have shape (frames, markers, 3), got {positions.shape}")
    if not 0 <= marker < positions.shape[1]:
        raise InputError(f"PCA fill: marker {marker} is not a column of the take ({positions.shape[1]} markers)")
    if length < 1 or start < 1 or start + length >= len(positions):
        raise InputError(f"PCA fill needs a measured frame on each side of the gap (frames "
                         f"{start}..{start + length - 1} of 0..{len(positions) - 1})")


def fill_pca(positions: np.ndarray, marker: int, start: int, length: int, window: int = PCA_WINDOW,
             weight_scale: float = WEIGHT_SCALE, gap_weight: float = GAP_WEIGHT,
             min_cumulative: float = MIN_CUMULATIVE, distal_share: float = DISTAL_SHARE) -> np.ndarray:
    """Fill frames ``start .. start + length - 1`` of column ``marker`` of ``positions (F, M, 3)`` mm from
    the other markers (module docstring), (length, 3) mm. The gap samples are ignored.

    InputError when the marker is not measured on both sides of the gap, fewer than 2 other markers are
    measured through it, or the window holds too few frames with every used marker measured."""
    _validate(positions, marker, start, length)
    end = start + length
    if not (np.isfinite(positions[start - 1, marker]).all() and np.isfinite(positions[end, marker]).all()):
        raise InputError(f"PCA fill needs the marker measured in the frames on each side of the gap "
                         f"({start - 1} and {end})")
    first, last = max(0, start - window), min(len(positions), end + window)
    block = positions[first:last]
    gap = np.arange(start - first, end - first)
    span = np.arange(gap[0] - 1, gap[-1] + 2)            # the gap and its measured ends
    observed = np.isfinite(block[:, :, 0] + block[:, :, 1] + block[:, :, 2])   # NaN in any axis: not measured
    observed[gap, marker] = False
    donors = np.flatnonzero(observed[span].all(axis=0))
    donors = donors[donors != marker]
    if len(donors) < 2:
        raise InputError(f"PCA fill needs 2 other markers measured through the gap (frames {start - 1}..{end}); "
                         f"{len(donors)} are")
    distances = _mean_distances(block, observed, marker, donors)
    keep, training = _training_donors(observed, marker, donors, distances, distal_share)
    donors, distances = donors[keep], distances[keep]
    used = np.append(donors, marker)
    columns = 3 * len(used)
    if len(donors) < 2:
        raise InputError(f"PCA fill needs 2 other markers measured together with the gap marker within {window} "
                         f"frames of the gap; {len(donors)} are")
    if training.sum() < columns:
        raise InputError(f"PCA fill needs {columns} frames with every used marker measured within {window} "
                         f"frames of the gap; there are {int(training.sum())}")
    weights = np.append(np.exp(-distances ** 2 / (2.0 * (weight_scale * np.median(distances)) ** 2)), gap_weight)
    in_span = np.zeros(len(block), dtype=bool)
    in_span[span] = True
    frames = np.flatnonzero(training | in_span)
    rotations, origins = _poses(block[frames][:, donors], block[span[0], donors], weights[:-1])
    local = np.matmul(block[frames][:, used] - origins[:, None], rotations)     # each frame in the donors' pose
    matrix = np.full((len(block), columns), np.nan)
    matrix[frames] = local.reshape(len(frames), columns)
    trained = matrix[training]
    centre = trained.mean(axis=0)
    spread = trained.std(axis=0)
    spread[spread <= 0.0] = 1.0
    scale = np.repeat(weights, 3) / spread
    singular, components = _principal_components((trained - centre) * scale)
    count = int(np.searchsorted(np.cumsum(singular), min_cumulative * singular.sum()) + 1)
    count = min(count, columns - 3)
    variances = singular ** 2 / max(1, int(training.sum()) - 1)
    noise = variances[count:].sum() / (columns - count)
    loadings = components[:count].T * np.sqrt(np.maximum(variances[:count] - noise, 0.0))   # (columns, count)
    known = loadings[:-3]
    observed_scaled = ((matrix[span] - centre) * scale)[:, :-3]
    scores = np.linalg.solve(known.T @ known + noise * np.eye(count), known.T @ observed_scaled.T)
    estimate = (loadings[-3:] @ scores).T / scale[-3:] + centre[-3:]
    at_span = np.searchsorted(frames, span)
    estimate = np.matmul(rotations[at_span], estimate[:, :, None])[:, :, 0] + origins[at_span]
    residuals = block[span[[0, -1]], marker] - estimate[[0, -1]]
    ramp = (np.arange(1, length + 1) / (length + 1))[:, None]
    return estimate[1:-1] + (1.0 - ramp) * residuals[0] + ramp * residuals[1]


def _principal_components(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The singular values (C,), largest first, and the right singular vectors (C, C) (rows) of ``matrix (N, C)``,
    from the eigendecomposition of its Gram matrix (C ≪ N: a fraction of the cost of the SVD of the matrix; a
    vector's sign is arbitrary, as in the SVD)."""
    eigenvalues, eigenvectors = np.linalg.eigh(matrix.T @ matrix)
    return np.sqrt(np.maximum(eigenvalues[::-1], 0.0)), eigenvectors[:, ::-1].T


def _poses(donors: np.ndarray, reference: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per frame, the pose of the donors ``(N, K, 3)`` mm: rotations (N, 3, 3), the weighted least-squares
    rotation of ``reference (K, 3)`` onto them (Kabsch: ``V diag(1, 1, sign det(U V^T)) U^T`` of the weighted
    covariance ``U S V^T``), and origins (N, 3) mm, their weighted centroid. Compiled
    (:func:`core.gaps.pca_kernel.poses_kernel`: a polar decomposition by Newton steps, Horn's quaternion where
    that does not apply)."""
    from handmocap.core.gaps.pca_kernel import poses_kernel

    share = weights / weights.sum()
    origins, rotations = poses_kernel(np.ascontiguousarray(donors, dtype=np.float64),
                                      np.ascontiguousarray(reference, dtype=np.float64),
                                      np.ascontiguousarray(share, dtype=np.float64))
    return rotations, origins


def _training_donors(observed: np.ndarray, marker: int, donors: np.ndarray, distances: np.ndarray,
                     distal_share: float) -> tuple[np.ndarray, np.ndarray]:
    """Which ``donors`` (K,) bool to use and the training frames (N,) bool where they and ``marker`` are
    all measured: every donor measured throughout the window; then, nearest first, the others that are
    not distal, each while at least :data:`FRAMES_PER_COLUMN` training frames per column remain."""
    keep = np.asarray(observed[:, donors].all(axis=0))
    training = observed[:, marker] & observed[:, donors[keep]].all(axis=1)
    for index in np.argsort(distances, kind="stable"):
        if keep[index] or distances[index] > distal_share * distances.mean():
            continue
        narrower = training & observed[:, donors[index]]
        if narrower.sum() >= FRAMES_PER_COLUMN * 3 * (keep.sum() + 2):
            keep[index], training = True, narrower
    return keep, training


def _mean_distances(block: np.ndarray, observed: np.ndarray, marker: int, donors: np.ndarray) -> np.ndarray:
    """Mean distance (mm) of each donor to ``marker`` over the frames where both are measured (at least
    the two ends of the gap), (K,)."""
    both = observed[:, donors] & observed[:, [marker]]
    offsets = block[:, donors] - block[:, [marker]]
    gaps = np.where(both, np.sqrt(np.einsum("nki,nki->nk", offsets, offsets)), 0.0)
    return gaps.sum(axis=0) / both.sum(axis=0)
