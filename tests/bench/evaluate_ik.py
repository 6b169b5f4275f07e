"""IK accuracy: grasp-4 layered vs standard IK on held-out simulated grasps (journal Table 1), and dense
noise-free angle error and residual.

Run: python tests/bench/evaluate_ik.py [frames]
"""

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from core.evaluation.ik import evaluate_ik  # noqa: E402


def main() -> None:
    figures = evaluate_ik(frames=int(sys.argv[1]) if len(sys.argv) > 1 else 1500)
    for key, value in figures.items():
        print(f"{key:<36} {value}")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
