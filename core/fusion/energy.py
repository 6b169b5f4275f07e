"""The fusion energy of Zhao et al. eq. 3–8: ``E = λm Em + λs Es + λd Ed + λe Ee + λc Ec``.

- ``Em`` (eq. 4, mm): mean over the model's markers of the distance to the nearest observed marker, cut off at
  ``T`` = 8 mm (robust to missing markers).
- ``Es`` (eq. 5): the share of the observed silhouette the model misses plus the share of the model outside it.
- ``Ed`` (eq. 6, mm): mean |observed − rendered depth| over the overlap of the two silhouettes (observed depth
  present), each difference clamped at ``depth_clamp_mm`` as Oikonomidis et al. 2011 do: a few observed pixels
  of the background (2 m behind the hand) would otherwise outweigh the whole hand.
- ``Ee`` (eq. 7, image px): mean distance-transform value of the observed edges at the rendered edges plus the
  converse.
- ``Ec`` (eq. 8): ‖q − q̃(t−1)‖ over the 26 parameters as the paper writes it (mm and rad mixed: a 1 mm step
  of the wrist costs as much as 1 rad of a joint).
Every term can be switched off by a zero weight; the paper's weights are the defaults.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from handmocap.core.fusion.hand_render import HandRenderer, distance_to
from handmocap.core.fusion.observation import Observation
from handmocap.core.model import MarkerSet, marker_positions

TERMS = ("marker", "silhouette", "depth", "edge", "smoothness")


@dataclass(frozen=True)
class EnergyWeights:
    """λ of eq. 3 (paper: 1.5, 22, 0.8, 0.4, 0.16), the marker cut-off ``T`` (mm, paper: 8) and the depth clamp
    (mm)."""

    marker: float = 1.5
    silhouette: float = 22.0
    depth: float = 0.8
    edge: float = 0.4
    smoothness: float = 0.16
    cutoff_mm: float = 8.0
    depth_clamp_mm: float = 40.0

    def vector(self) -> np.ndarray:
        return np.array([self.marker, self.silhouette, self.depth, self.edge, self.smoothness])


class FrameEnergy:
    """Eq. 3 for one frame: ``energy(theta)`` (weighted sum) and ``terms(theta) (5,)`` (unweighted, :data:`TERMS`)."""

    def __init__(self, renderer: HandRenderer, observation: Observation, markers: MarkerSet,
                 previous: np.ndarray | None, weights: EnergyWeights | None = None) -> None:
        self.renderer, self.observation, self.markers = renderer, observation, markers
        self.previous = previous
        self.weights = weights or EnergyWeights()
        self._lambda = self.weights.vector()
        seen = observation.markers[np.isfinite(observation.markers).all(axis=1)]
        self._observed_markers = seen
        self._observed_area = max(int(observation.silhouette.sum()), 1)
        self._observed_edges = max(int(observation.edges.sum()), 1)
        self.evaluations = 0

    def marker_term(self, theta: np.ndarray) -> float:
        """Eq. 4 (mm)."""
        if len(self._observed_markers) == 0:
            return 0.0
        model = marker_positions(self.renderer.model, self.markers, theta)
        distance = np.linalg.norm(model[:, None, :] - self._observed_markers[None, :, :], axis=2).min(axis=1)
        return float(np.minimum(distance, self.weights.cutoff_mm).mean())

    def terms(self, theta: np.ndarray) -> np.ndarray:
        """Unweighted terms (5,) in the order of :data:`TERMS`; image terms are skipped when their weight is 0."""
        self.evaluations += 1
        values = np.zeros(5)
        if self._lambda[0]:
            values[0] = self.marker_term(theta)
        if self._lambda[1] or self._lambda[2] or self._lambda[3]:
            values[1:4] = self.image_terms(theta)
        if self._lambda[4] and self.previous is not None:
            values[4] = float(np.linalg.norm(theta - self.previous))
        return values

    def image_terms(self, theta: np.ndarray) -> np.ndarray:
        """``(Es, Ed mm, Ee px)`` of eq. 5–7 for the pose ``theta``."""
        observation = self.observation
        rendering = self.renderer.render(theta, observation.crop, with_edges=bool(self._lambda[3]))
        rendered = rendering.silhouette
        area = int(rendered.sum())
        observed = observation.silhouette
        silhouette = float((observed & ~rendered).sum()) / self._observed_area + (
            float((rendered & ~observed).sum()) / area if area else 1.0)
        overlap = observed & rendered & (observation.depth > 0)
        difference = np.minimum(np.abs(observation.depth[overlap] - rendering.depth[overlap]),
                                self.weights.depth_clamp_mm)
        depth = float(difference.mean()) if overlap.any() else 0.0
        edge = 0.0
        if self._lambda[3]:
            rendered_edges = rendering.edges
            stride = observation.crop.stride
            if rendered_edges.any():
                edge += float(observation.edge_distance[rendered_edges].mean()) * stride
                from_rendered = distance_to(rendered_edges)
                edge += float(from_rendered[observation.edges].sum()) / self._observed_edges * stride
            else:
                edge = float(sum(rendered.shape)) * stride
        return np.array([silhouette, depth, edge])

    def __call__(self, theta: np.ndarray) -> float:
        return float(self._lambda @ self.terms(theta))

