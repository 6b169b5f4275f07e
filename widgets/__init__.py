"""Reusable Qt widgets of Hand Mocap Studio: 3D hand viewport, timeline, marker table, and for take
review the marker lanes, review table, gap list, fill preview and session browser.

They take numpy arrays and Qt models, never the application's documents (``widgets`` never imports ``app``).
"""
