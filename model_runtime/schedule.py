"""How a segment's diffusion job is spread over the frames of the segment before it."""
from __future__ import annotations

from functools import lru_cache

# Cost of one denoising step in units of a plain step: a steered step adds a decoder forward and backward.
STEERED_STEP_COST = 2.5
# The boundary frame (f = 0) also decodes a segment and encodes contexts: about this many plain steps.
BOUNDARY_COST = 1.0


@lru_cache(maxsize=64)
def steps_per_frame(steps: int, frames: int, steered: int, boundary: float = BOUNDARY_COST) -> tuple[int, ...]:
    """Denoising steps per frame of a segment, spreading the job's cost evenly over its frames.

    Steps run in order and the last `steered` of them cost STEERED_STEP_COST each; frame 0 starts with
    `boundary` already spent (its decode, contexts and seam steering). The split minimises the sum of squared
    frame costs (so both the typical and the worst frame stay low), by dynamic programming over (steps done,
    frame). Sums to `steps`.
    """
    if steps * steps * frames > 2_000_000:     # research configs with very many steps: an even split
        base, extra = divmod(steps, frames)
        return tuple(base + (1 if i >= frames - extra else 0) for i in range(frames))
    cost = [STEERED_STEP_COST if t < steered else 1.0 for t in range(steps - 1, -1, -1)]
    prefix = [0.0]
    for c in cost:
        prefix.append(prefix[-1] + c)
    inf = float("inf")
    # best[f][i]: least sum of squares with the first i steps done by the end of frame f
    best = [[inf] * (steps + 1) for _ in range(frames)]
    choice = [[0] * (steps + 1) for _ in range(frames)]
    for i in range(steps + 1):
        best[0][i] = (boundary + prefix[i]) ** 2
    for f in range(1, frames):
        for i in range(steps + 1):
            for j in range(i + 1):
                v = best[f - 1][j] + (prefix[i] - prefix[j]) ** 2
                if v < best[f][i] - 1e-12:
                    best[f][i], choice[f][i] = v, j
    out, i = [0] * frames, steps
    for f in range(frames - 1, 0, -1):
        j = choice[f][i]
        out[f], i = i - j, j
    out[0] = i
    return tuple(out)
