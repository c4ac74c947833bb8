"""Several interface laws behind the one law API: each point belongs to one of them."""

import numpy as np

from .state import InterfaceState, LawUpdate


class MixedInterface:
    """Points ``groups[i]`` (index arrays partitioning ``range(n)``) follow ``laws[i]``.

    Used when joints follow one law and unit mid-planes another (e.g. the hyperbolic joints with
    tension-only unit cracks of the composite law).
    """

    name = "mixed"

    def __init__(self, laws, groups):
        self.laws = tuple(laws)
        self.groups = tuple(np.asarray(g, dtype=np.intp) for g in groups)
        self.n = int(sum(len(g) for g in self.groups))
        seen = np.zeros(self.n, int)
        for g in self.groups:
            seen[g] += 1
        if not np.all(seen == 1):
            raise ValueError("the groups of a mixed interface law must partition the points")

    def __len__(self):
        return self.n

    def initial_state(self):
        return InterfaceState.zeros(self.n)

    def update(self, du, state):
        n = self.n
        jump, t, up, kap, work = np.empty((n, 2)), np.empty((n, 2)), np.empty((n, 2)), np.empty((n, 3)), np.empty(n)
        tangent, its, status = np.empty((n, 2, 2)), np.empty(n, np.int64), np.empty(n, np.int64)
        for law, g in zip(self.laws, self.groups):
            u = law.update(du[g], state.take(g))
            s = u.state
            jump[g], t[g], up[g], kap[g], work[g] = s.jump, s.traction, s.plastic, s.kappa, s.work
            tangent[g], its[g], status[g] = u.tangent, u.iterations, u.status
        return LawUpdate(InterfaceState(jump, t, up, kap, work), tangent, its, status)

    def elastic_tangent(self):
        D = np.empty((self.n, 2, 2))
        for law, g in zip(self.laws, self.groups):
            D[g] = law.elastic_tangent()
        return D

    def near_surfaces(self, state, fraction):
        out = np.zeros((self.n, 2), bool)
        for law, g in zip(self.laws, self.groups):
            if hasattr(law, "near_surfaces"):
                out[g] = law.near_surfaces(state.take(g), fraction)
        return out
