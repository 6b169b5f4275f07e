"""Cameras beside the markers: camera model and files, frame sources, intrinsic and extrinsic calibration,
synchronisation, rendering and overlays (no Qt)."""
