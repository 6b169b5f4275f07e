"""Live capture (no Qt): sources that stream 3D points from a capture system (Qualisys QTM through the
real-time protocol with ``qtm-rt``, OptiTrack Motive through NatNet with ``natnet``) behind one interface and
registry (:mod:`core.live.sources`, :mod:`core.live.systems`), the stand-in server that replays a take over
each protocol on loopback (:mod:`core.live.server`), and the capture that labels every frame causally as it
arrives, journals it into the session and supervises the hands (:mod:`core.live.capture`,
:mod:`core.live.recorder`, :mod:`core.live.supervision`)."""
