"""Write ``surrogate_v1.h5`` and ``surrogate_v1_expected.npz``: a surrogate file in the layout of
format ``podkrig.surrogate``, schema 1 (written before the kriging persisted itself), and the
predictions that code made from it. Run with the podkrig of commit 50129b9:

    git worktree add /tmp/podkrig-50129b9 50129b9
    PYTHONPATH=/tmp/podkrig-50129b9 python tests/data/make_surrogate_v1.py tests/data

Analytic snapshots (no FE): 3 parameters (one log-scaled), 24 Sobol' samples, readings of shape
(3 loads, 4 sensors) in mm; beta="fit" (one exponent per POD mode).
"""

import sys
from pathlib import Path

import numpy as np

from podkrig.io.surrogate_file import save_surrogate
from podkrig.offline.sampling import sobol, uniform
from podkrig.parameters import Parameter, ParameterSpace
from podkrig.surrogate.kriging import OrdinaryKriging
from podkrig.surrogate.pod import POD
from podkrig.surrogate.podkriging import PODKriging


def snapshots(X):
    """(n, 3, 4) readings, mm: smooth in the three parameters, linear in the load."""
    E, k, r = X.T
    base = np.stack([1e3 / E, 1 / k, r / k ** 0.5, np.sin(2 * r) / E ** 0.5], axis=1)
    return np.stack([lvl * base for lvl in (1.0, 2.0, 3.0)], axis=1)


SPACE = ParameterSpace((Parameter("E_b", 5000.0, 20000.0, unit="MPa"),
                        Parameter("kN_bj", 10.0, 1000.0, "log", "N/mm³"),
                        Parameter("r_hj", 0.1, 1.0)))

if __name__ == "__main__":
    out = Path(sys.argv[1])
    X = SPACE.from_unit(sobol(24, 3, seed=0, skip=8))
    sur = PODKriging(pod=POD(energy=1 - 1e-10), kriging=OrdinaryKriging(beta="fit"), space=SPACE).fit(X, snapshots(X))
    sur.provenance_.update({"note": "reference file of tests/test_surrogate_files.py"})
    save_surrogate(sur, out / "surrogate_v1.h5")
    Xp = SPACE.from_unit(uniform(16, 3, seed=5))
    mean, std = sur.predict(Xp, return_std=True, reshape=True)
    np.savez(out / "surrogate_v1_expected.npz", X=Xp, mean=mean, std=std)
