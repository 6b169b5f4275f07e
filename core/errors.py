"""User-facing error types: their message is one clear line meant for the operator."""


class HandMocapError(Exception):
    """Base class of every error whose message is shown to the user as is."""


class InputError(HandMocapError):
    """A file, argument or data set the user gave cannot be used (malformed, empty, wrong units...)."""


class CancelledError(HandMocapError):
    """A long computation was cancelled by the user; nothing was changed."""
