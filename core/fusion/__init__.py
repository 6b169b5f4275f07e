"""Markers + RGB-D fusion tracking (Zhao et al. 2012; articulated ICP and adaptive subspace after Schröder 2015):
silhouettes, rendering of hypotheses, the energy, swarm and ICP optimisers, frame-rate lifting, :func:`fuse_take`."""

from handmocap.core.fusion.tracker import FusionResult, FusionSettings, RGBDFrames, fuse_take

__all__ = ["FusionResult", "FusionSettings", "RGBDFrames", "fuse_take"]
