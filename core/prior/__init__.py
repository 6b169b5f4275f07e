"""Posture prior: authored canonical postures and the PCA prior over the 20 finger angles."""

from handmocap.core.prior.canonical_postures import (
    HELDOUT_GRASPS,
    canonical_postures,
    heldout_grasp_postures,
    prior_grasp_postures,
    prior_postures,
)
from handmocap.core.prior.pca_prior import (
    DEFAULT_PRIOR_PATH,
    PosturePrior,
    build_default_prior,
    build_prior,
    build_prior_from_results,
    default_prior_samples,
    describe_prior,
    load_default_prior,
    soft_prior_matrix,
    write_default_prior,
)

__all__ = [
    "DEFAULT_PRIOR_PATH",
    "HELDOUT_GRASPS",
    "PosturePrior",
    "build_default_prior",
    "build_prior",
    "build_prior_from_results",
    "canonical_postures",
    "default_prior_samples",
    "describe_prior",
    "heldout_grasp_postures",
    "load_default_prior",
    "prior_grasp_postures",
    "prior_postures",
    "soft_prior_matrix",
    "write_default_prior",
]
