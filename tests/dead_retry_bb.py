"""A user blackbox for tests/model/test_dead.py (issue 41, hole 2): it subclasses
the shipped ``straight`` and so keeps its name, "straight", but treats a
settled robot differently: a robot whose doReach failed is carried to its
target on the next step (flags left as they are).  It declares no
capabilities of its own, so the one ``Straight`` declares must not count
for it (pccl.blackboxes.base.declared_capabilities)."""

from pccl.blackboxes.base import Outcome
from pccl.blackboxes.straight import Straight


class Retry(Straight):          # name = "straight", inherited
    def step(self, world, motions, env, time, delta):
        out = super().step(world, motions, env, time, delta)[0]
        pos = list(out.positions)
        for i, m in enumerate(motions):
            if m.fail and m.target is not None:
                z = m.position[2] if len(m.position) > 2 else 0.0
                pos[i] = (float(m.target[0]), float(m.target[1]), float(z))
        return [Outcome(tuple(pos), out.done, out.fail, None)]


BLACKBOX = Retry()
