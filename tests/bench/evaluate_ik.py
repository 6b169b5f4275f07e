"""IK accuracy: grasp-4 layered vs standard IK on held-out simulated grasps (journal Table 1), and dense
noise-free angle error and residual.

Run: python tests/bench/evaluate_ik.py [frames]
"""

import json
import sys

from handmocap.core.evaluation.ik import evaluate_ik


def main() -> None:
    figures = evaluate_ik(frames=int(sys.argv[1]) if len(sys.argv) > 1 else 1500)
    for key, value in figures.items():
        print(f"{key:<36} {value}")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
