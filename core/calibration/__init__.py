"""Subject calibration: a subject-specific hand model from a 3D hand scan and its 20 landmarks (rigid then
non-rigid fit), and bone lengths and marker offsets from labelled takes."""
