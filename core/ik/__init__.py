"""Inverse kinematics: damped Gauss-Newton, full / subspace / layered, joint limits, warm start."""

from handmocap.core.ik.solver import (
           METHODS,
           IKResult,
           IKSettings,
           IKSolver,
           kabsch,
           match_layout,
           solve_positions,
           solve_take,
)

__all__ = ["METHODS", "IKResult", "IKSettings", "IKSolver", "kabsch", "match_layout", "solve_positions",
           "solve_take"]
