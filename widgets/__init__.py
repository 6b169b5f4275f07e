"""Reusable Qt widgets of Hand Mocap Studio: 3D hand viewport, timeline, marker table.

They take numpy arrays and Qt models, never the application's documents (``widgets`` never imports ``app``).
"""
