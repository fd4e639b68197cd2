"""The energy balance a run's energy columns close, shared by the tests that check it."""
from __future__ import annotations

import numpy as np


def balance(res) -> np.ndarray:
    """E(t) - E(0) - (W_drive + W_load + W_motion - D_damping) at each row (J): what the
    energy gained less the drives', loads' and motions' work and the damping's loss."""
    e = res["energy.total"]
    w = res["energy.drive_work"] + res["energy.load_work"] + res["energy.motion_work"] - res["energy.damping_loss"]
    return e - e[0] - w
