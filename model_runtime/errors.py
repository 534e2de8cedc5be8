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
# The share of the guidance's push past the conditional pass that the last denoising step keeps (1: full guidance
# on every step), for an ego whose history moves at least DEFAULT_FINAL_GUIDANCE_MIN_SPEED. That step draws the
# clean pose's detail; easing it keeps a segment closer to the ego's own history (held-out next-segment error 77.8 mm
# with full guidance, 69.3 so). A still body keeps full guidance: eased there too, a standing ego now and then sets
# off walking (val split, 144 standing episodes: drift 0.19 m a minute with full guidance, 0.53 eased everywhere,
# 0.19 eased only when moving). Chosen on the val split (README, "Guidance eased on the last denoising step").
DEFAULT_FINAL_GUIDANCE_SHARE = 0.4
DEFAULT_FINAL_GUIDANCE_MIN_SPEED = 0.2     # m/s of the pelvis over the history, horizontally
