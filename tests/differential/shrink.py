"""Shrinking a disagreement (delta debugging over the program's lines).

A candidate drops one *unit* of the program: a line with the lines indented
under it (an event, a statement with its block, a declaration, a section),
keeps only texts that ``pccl check`` accepts (well-formed: parsed and
typed), then drops ``--invariant``/``--property`` forms, agents, and world
file lines, and simplifies integer literals, as long as the same
disagreement (check and modes) remains.  Greedy, to a fixpoint or the
budget: the result is 1-minimal in the units tried.
"""

from __future__ import annotations

import json
import os
import re
import time
from dataclasses import replace

from pccl import api
from pccl.lang.errors import PcclError

from . import oracle
from .gen import Case, parse


def _units(lines: list) -> list:
    """(start, end) of each line with the more-indented lines under it."""
    out = []
    for i, ln in enumerate(lines):
        if not ln.strip():
            continue
        ind = len(ln) - len(ln.lstrip())
        j = i + 1
        while j < len(lines) and (not lines[j].strip() or len(lines[j]) - len(lines[j].lstrip()) > ind):
            j += 1
        out.append((i, j))
    # biggest first: whole events and sections before single statements
    return sorted(out, key=lambda u: u[0] - u[1])


def _well_formed(case: Case) -> bool:
    files = oracle.Files(case)
    try:
        api.check(parse(case), world=files.world)
        return True
    except PcclError:
        return False
    except Exception:
        return False
    finally:
        files.close()


def modes_for(d: oracle.Disagreement) -> list:
    names = ["truth", d.mode] + ([d.against] if d.against not in ("", "truth") else [])
    return [m for m in oracle.MODES if m.name in names]


def reproduces(case: Case, d: oracle.Disagreement) -> bool:
    rep = oracle.compare(case, modes_for(d))
    return any(x.check == d.check and x.mode == d.mode for x in rep.disagreements)


def shrink(case: Case, d: oracle.Disagreement, budget: float = 120.0) -> Case:
    deadline = time.monotonic() + budget

    def ok(c: Case) -> bool:
        return time.monotonic() < deadline and _well_formed(c) and reproduces(c, d)

    changed = True
    while changed and time.monotonic() < deadline:
        changed = False
        # program units
        lines = case.text.split("\n")
        for a, b in _units(lines):
            cand = case.with_text("\n".join(lines[:a] + lines[b:]))
            if ok(cand):
                case, changed = cand, True
                break
        if changed:
            continue
        # properties given on the command line
        for attr in ("invariants", "properties"):
            for k in range(len(getattr(case, attr))):
                vals = list(getattr(case, attr))
                del vals[k]
                cand = replace(case, **{attr: vals})
                if ok(cand):
                    case, changed = cand, True
                    break
        if changed:
            continue
        if case.agents is not None and case.agents > 1:
            cand = replace(case, agents=case.agents - 1)
            if ok(cand):
                case, changed = cand, True
                continue
        # world lines (obstacles, functions)
        if case.world:
            wl = case.world.split("\n")
            for a, b in _world_units(wl):
                cand = replace(case, world="\n".join(wl[:a] + wl[b:]))
                if ok(cand):
                    case, changed = cand, True
                    break
        if changed:
            continue
        # literals: a big or edge integer to a small one
        for mt in re.finditer(r"(?<![\w.])\d{2,}(?![\w.])", case.text):
            for small in ("0", "1"):
                cand = case.with_text(case.text[:mt.start()] + small + case.text[mt.end():])
                if ok(cand):
                    case, changed = cand, True
                    break
            if changed:
                break
    return case


def _world_units(wl: list) -> list:
    out = []
    for i, ln in enumerate(wl):
        if ln.startswith("[[obstacles]]"):
            out.append((i, min(i + 2, len(wl))))
        elif "=" in ln and not ln.startswith(("agents", "start", "polygon")):
            out.append((i, i + 1))
    return out


REPRODUCE = '''"""Re-run the oracle's comparison of this finding (from the repository root)."""
import json
import os
import sys

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.getcwd())
from tests.differential import gen, oracle, shrink  # noqa: E402

spec = json.load(open(os.path.join(here, "case.json")))


def read(name):
    p = os.path.join(here, name)
    return open(p).read() if os.path.exists(p) else None


lang = spec.get("lang", "pccl")
case = gen.Case(spec["seed"], spec["family"], read("program.koord" if lang == "koord" else "program.pccl"),
                agents=spec["agents"], world=read("world.toml"), invariants=spec["invariants"],
                properties=spec["properties"], blackbox=read("userbb.py"), moves=spec["moves"],
                options=spec["options"], lang=lang)
d = oracle.Disagreement(spec["seed"], spec["family"], spec["check"], spec["mode"], spec["against"], "")
rep = oracle.compare(case, shrink.modes_for(d))
for x in rep.disagreements:
    print(x.check, x.mode, "vs", x.against or "truth", "-", x.known or "NEW")
    print(x.detail)
sys.exit(1 if rep.disagreements else 0)
'''


def write_finding(root: str, case: Case, d: oracle.Disagreement, original: Case) -> str:
    """Write the shrunk program, its world and blackbox and the commands that
    show the disagreement into ``root/seedN-check-mode/``; returns the directory."""
    name = f"seed{case.seed}-{d.check}-{d.mode}".replace(",", "+")
    out = os.path.join(root, name)
    os.makedirs(out, exist_ok=True)
    prog = case.filename
    with open(os.path.join(out, prog), "w") as f:
        f.write(case.text if case.text.endswith("\n") else case.text + "\n")
    files = [prog]
    common = []
    if case.world:
        with open(os.path.join(out, "world.toml"), "w") as f:
            f.write(case.world)
        common.append("--world world.toml")
    if case.blackbox:
        with open(os.path.join(out, "userbb.py"), "w") as f:
            f.write(case.blackbox)
        common.append("--blackbox userbb.py:BLACKBOX")
    if case.agents is not None:
        common.append(f"--agents {case.agents}")
    for k, v in case.options.items():
        common.append(f"--{k.replace('_', '-')}" if v is True else f"--{k.replace('_', '-')} {v}")
    for inv in case.invariants:
        common.append(f"--invariant '{inv}'")
    for p in case.properties:
        common.append(f"--property '{p}'")
    common.append(f"--all --max-states {oracle.MAX_STATES}")
    base = " ".join(common)
    cmds = [f"pccl explore {prog} {base} {oracle.TRUTH.cli()}"]
    for m in modes_for(d):
        if m.name == "truth":
            continue
        if m.kind == "covering":
            cmds.append(f"pccl explore {prog} {base}")
            cmds += [f"pccl run {prog} {base.split(' --all')[0].replace(' --invariant', ' --invariant')} "
                     f"--blackbox straight --seed {s} --max-time 30 --trace" for s in oracle.RUN_SEEDS]
        else:
            cmds.append(f"{m.env_prefix()}pccl explore {prog} {base} {m.cli()}")
    with open(os.path.join(out, "case.json"), "w") as f:
        json.dump({"seed": case.seed, "family": case.family, "agents": case.agents,
                   "invariants": case.invariants, "properties": case.properties,
                   "options": case.options, "moves": case.moves, "lang": case.lang, "check": d.check, "mode": d.mode,
                   "against": d.against}, f, indent=1)
    with open(os.path.join(out, "reproduce.py"), "w") as f:
        f.write(REPRODUCE)
    cmds.append(f"python {out}/reproduce.py     # from the repository root: the oracle's own comparison")
    with open(os.path.join(out, "README.md"), "w") as f:
        f.write(f"# {d.check} disagreement: {d.mode} vs {d.against or 'truth'}\n\n"
                f"Generated by `python -m tests.differential` (seed {original.seed}, family "
                f"{original.family}), shrunk from {len(original.text.splitlines())} to "
                f"{len(case.text.splitlines())} lines.\n"
                + (f"Known open hole: {d.known}\n" if d.known else "") +
                f"\n{d.detail}\n\nCommands (in this directory):\n\n```sh\n" + "\n".join(cmds) + "\n```\n")
    files.append("README.md")
    return out
