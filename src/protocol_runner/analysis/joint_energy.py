"""The energy lost per cycle by several joints moved together: the sum over the joints.

Each joint's cycles are found on its own angle (Eq 10-12 per joint); a gait-like motion gives every joint
the same number of complete cycles per trial, but the transition removal can leave one joint a cycle
fewer. The total pairs the joints' cycles by their order in each trial: the k-th cycle's total is the sum
of every joint's k-th complete cycle, for k up to the fewest cycles any joint completed in that trial.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


def total_energy_per_cycle(
    energies_j: Sequence[FloatArray], cycle_trials: Sequence[npt.NDArray[np.int64]]
) -> tuple[FloatArray, npt.NDArray[np.int64]]:
    """(total energy per cycle in J, its trial number) from each joint's energy per cycle and trials."""
    trials = sorted({int(t) for tr in cycle_trials for t in tr})
    total: list[float] = []
    which: list[int] = []
    for n in trials:
        per_joint = [e[np.asarray(tr) == n] for e, tr in zip(energies_j, cycle_trials, strict=True)]
        k = min(e.size for e in per_joint) if per_joint else 0
        if k:
            total += np.sum([e[:k] for e in per_joint], axis=0).tolist()
            which += [n] * k
    return np.asarray(total, dtype=np.float64), np.asarray(which, dtype=np.int64)
