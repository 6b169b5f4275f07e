"""Hand Mocap Studio's application layer: the command line (:mod:`app.cli`) and the Qt window (:mod:`app.gui`)."""
