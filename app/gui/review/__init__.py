"""The review of the shown take, one module per responsibility; :mod:`.controller` composes them."""
