"""Seeds of the random streams (initial velocities, thermostat noise): the one place a missing seed is drawn."""
from __future__ import annotations

import numpy as np


def resolve_seed(seed: int | None) -> int:
    """``seed`` as an int, or, for None, a new seed in [0, 2^31) from the operating system's entropy (recorded by
    the caller, so the run can be repeated)."""
    if seed is not None:
        return int(seed)
    entropy = np.random.SeedSequence().entropy
    assert isinstance(entropy, int)
    return entropy % 2**31
