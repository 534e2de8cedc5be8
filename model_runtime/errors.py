"""Error types. Every message is one line that names what is wrong and what to do about it."""


class RemogenError(ValueError):
    """Base class for predictable problems a user can fix (bad input, bad file)."""


class InputError(RemogenError):
    """A value given to the runtime has the wrong shape, units or content."""


class ModelFileError(RemogenError):
    """A model file is missing, truncated, foreign or does not match this runtime."""


class ModelOutputError(RemogenError):
    """The model produced a non-finite pose; the session is left as it was before that step."""


# Coordinates beyond this many metres are a broken transform or unit, never a real scene.
MAX_COORD = 1e5
# Classifier-free guidance above this only overshoots; far above it the pose becomes NaN.
MAX_GUIDANCE = 20.0
# The text guidance every session, group, bake and evaluation uses unless told otherwise. Chosen on the behaviour
# suite's val split with the shipped weights: 6 holds a standing ego still (drift 0.41 -> 0.15 m a minute) and keeps
# every text kind that 5 gives (with the weights before, 6 and 7 lost the jumps; README, "The model as it stands").
DEFAULT_GUIDANCE = 6.0
