"""The order of interleaved timing runs, and how many there may be, shared by ``pymr study``
and ``pymr bench``."""
from __future__ import annotations

import numpy as np

#: Most timing runs per case (--repeats): beyond, a study or bench would not end in a day.
MAX_REPEATS = 1000


def shuffled(items: list, seed: int) -> list:
    """The items in an order drawn afresh for each timing pass (seeded: a study or bench
    repeats its order). In a fixed order a case always runs after the same neighbours: in
    ``pymr study`` the first 'exponential' cases ran after the seconds of 'full' runs, whose
    load slows what follows (measured: a tank run right after a 'full' one took 1.55x its
    CPU). Shuffled, that cost falls on every case alike."""
    order = np.random.default_rng(seed).permutation(len(items))
    return [items[i] for i in order]
