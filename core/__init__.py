"""The Qt-free core of Hand Mocap Studio: takes and their files, the hand model, IK, labelling, gap filling,
calibration, review, sessions and workflows, in layers that import-linter enforces (see pyproject.toml)."""
