"""Particle swarm optimisation of one frame's pose (Zhao et al. §5.3, after Clerc & Kennedy 2002).

``v ← w (v + c1 r1 (P − x) + c2 r2 (G − x))``, ``x ← x + v`` (eq. 9–10) with the constriction factor
``w = 2 / |2 − φ − √(φ² − 4φ)|``, ``φ = c1 + c2`` (eq. 11; 0.7298 for the paper's c1 = 2.8, c2 = 1.3). The
initial population is the previous frame's pose and Gaussian perturbations of it (plus any extra starts);
positions are kept within the joint limits.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from handmocap.core.errors import CancelledError


@dataclass(frozen=True)
class SwarmSettings:
    """The paper's swarm: 48 particles, 200 generations, c1 = 2.8, c2 = 1.3."""

    particles: int = 48
    generations: int = 200
    c1: float = 2.8
    c2: float = 1.3

    @property
    def constriction(self) -> float:
        phi = self.c1 + self.c2
        return 2.0 / abs(2.0 - phi - np.sqrt(phi * phi - 4.0 * phi))


#: Gaussian spread (σ) of the initial population around the previous pose: wrist translation (mm), wrist
#: rotation (rad), finger angles (rad) — a 30 Hz frame moves a finger joint by up to ~0.2 rad
SPREAD = np.concatenate([np.full(3, 4.0), np.full(3, 0.04), np.full(20, 0.12)])


def particle_swarm(energy: Callable[[np.ndarray], float], start: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                   settings: SwarmSettings, rng: np.random.Generator, extra_starts: tuple[np.ndarray, ...] = (),
                   spread: np.ndarray = SPREAD, cancelled: Callable[[], bool] | None = None
                   ) -> tuple[np.ndarray, float]:
    """Minimise ``energy`` over 26-D poses from ``start (26,)`` within ``lower``/``upper (26,)``: ``(best pose,
    its energy)``. Particle 0 is ``start``, the next ones ``extra_starts``, the rest perturbations of ``start``."""
    count = max(settings.particles, 1 + len(extra_starts))
    positions = np.clip(start + rng.normal(size=(count, start.size)) * spread, lower, upper)
    positions[0] = np.clip(start, lower, upper)
    for index, extra in enumerate(extra_starts):
        positions[1 + index] = np.clip(extra, lower, upper)
    velocities = np.zeros_like(positions)
    scores = np.array([energy(position) for position in positions])
    best_positions, best_scores = positions.copy(), scores.copy()
    leader = int(np.argmin(best_scores))
    w = settings.constriction
    for _ in range(settings.generations):
        if cancelled is not None and cancelled():
            raise CancelledError("fusion cancelled; the take is unchanged")
        r1, r2 = rng.random(positions.shape), rng.random(positions.shape)
        velocities = w * (velocities + settings.c1 * r1 * (best_positions - positions)
                          + settings.c2 * r2 * (best_positions[leader] - positions))
        positions = np.clip(positions + velocities, lower, upper)
        scores = np.array([energy(position) for position in positions])
        better = scores < best_scores
        best_positions[better], best_scores[better] = positions[better], scores[better]
        leader = int(np.argmin(best_scores))
    return best_positions[leader].copy(), float(best_scores[leader])
