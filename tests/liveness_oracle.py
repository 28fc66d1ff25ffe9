"""The differential oracle (tests/differential/) restricted to the generated
programs that carry a liveness property (issue 46): per program the truth
(``--reduce none --exact --engine python``) and the modes given; prints the
agreement figures and which reductions ``auto`` used.

    python tests/liveness_oracle.py FIRST_SEED N MODE,MODE,...

(docs/reductions.md, "Temporal properties under the reductions", quotes a
run.)"""
import collections
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from differential import gen, oracle  # noqa: E402
from pccl import api  # noqa: E402
from pccl.lang.parser import parse_program  # noqa: E402


def live(p: str) -> bool:
    return p.startswith("eventually") or ("~>" in p and "within" not in p)


def main(argv) -> None:
    first, n = int(argv[0]), int(argv[1])
    modes = [oracle.TRUTH] + [oracle.BY_NAME[x] for x in argv[2].split(",")]
    stats: collections.Counter = collections.Counter()
    red: collections.Counter = collections.Counter()
    dis = []
    t0 = time.time()
    seed = first
    while stats["programs"] < n:
        case = gen.case(seed)
        seed += 1
        if not any(live(p) for p in case.properties):
            continue
        stats["programs"] += 1
        files = oracle.Files(case)
        try:
            prog = parse_program(case.text, "<input>")
            m = api.make_model(prog, **{k: v for k, v in oracle.base_kw(case, files).items()
                                         if k not in ("find_all", "max_states")})
            red["+".join(m.reduction.on) or "none"] += 1
        except Exception:
            red["load error"] += 1
        rep = oracle.compare(case, modes)
        t = rep.outcomes.get("truth")
        stats["truth " + (t.status if t else "?")] += 1
        stats["inconclusive"] += bool(rep.inconclusive)
        stats["agreements"] += rep.agreements
        for d in rep.disagreements:
            dis.append((seed - 1, d.check, d.mode, d.detail[:300]))
        print(f"seed {seed - 1} [{case.family}] {case.properties} truth {t.status if t else '?'} "
              f"agreements {rep.agreements} disagreements {len(rep.disagreements)}", flush=True)
    print("programs with a liveness property:", dict(stats))
    print("reductions under auto:", dict(red))
    print("disagreements:", len(dis))
    for d in dis:
        print("  ", d)
    print(f"seconds {time.time() - t0:.0f}")


if __name__ == "__main__":
    main(sys.argv[1:])
