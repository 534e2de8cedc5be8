"""Error types. Every message is one line that names what is wrong and what to do about it."""


class RemogenError(ValueError):
    """Base class for predictable problems a user can fix (bad input, bad file)."""


class InputError(RemogenError):
    """A value given to the runtime has the wrong shape, units or content."""


class ModelFileError(RemogenError):
    """A model file is missing, truncated, foreign or does not match this runtime."""


# Coordinates beyond this many metres are a broken transform or unit, never a real scene.
MAX_COORD = 1e5
