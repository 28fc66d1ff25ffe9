"""A user blackbox for tests/tools/test_replay.py: every moving agent arrives at
the next step (like ``instant``, without obstacles), under its own name.
Importing it leaves a marker file next to it, so that a test can tell
whether ``pccl replay`` imported it."""

from pathlib import Path

from pccl.blackboxes.base import Outcome, settled

Path(__file__).with_suffix(".imported").write_text("imported\n")


class Hop:
    name = "hop"
    uses_time = False

    def init_env(self, world, n_agents):
        return None

    def step(self, world, motions, env, time, delta):
        positions, done, fail = [], [], []
        for m in motions:
            held = settled(m)
            if held is not None:
                positions.append(m.position)
                done.append(held[0])
                fail.append(held[1])
            else:
                positions.append((float(m.target[0]), float(m.target[1]), float(m.position[2])))
                done.append(True)
                fail.append(False)
        return [Outcome(tuple(positions), tuple(done), tuple(fail), None)]


BLACKBOX = Hop()
