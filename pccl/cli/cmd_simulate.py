"""``pccl simulate``: many seeded runs, their outcomes and reproducing commands."""

from __future__ import annotations

import sys

import click

from pccl.cli.files import _check_output, _rates_text, _run_path, _write_trace
from pccl.cli.options import FiniteFloat, _check_repeats, _delta, _fail, cli_spelling, common_options_without_n
from pccl.lang.errors import PcclError

#: steps of the first violating run that simulate prints without --trace
SIM_TAIL = 10


@click.command(short_help="Many seeded runs: outcome frequencies, times, reproducing commands.",
              epilog="Exit status: 0 no run had a violation, 1 some run had one (a failed "
                     "invariant or property, a stuck agent, a deadlock, a stall, or a run "
                     "stopped by --max-steps), 2 bad input.")
@click.argument("program", type=click.Path(dir_okay=False))
@common_options_without_n
@click.option("--runs", "runs", type=click.IntRange(min=1), default=None,
              help="number of runs (seeds SEED, SEED+1, ...)  [default: 100]")
@click.option("-n", "runs_n", type=click.IntRange(min=1), default=None, metavar="RUNS",
              help="deprecated spelling of --runs (in run and explore -n is --agents)")
@click.option("--seed", type=int, default=0, show_default=True, help="seed of the first run")
@click.option("--max-time", type=FiniteFloat(min=0), default=100, show_default=True,
              help="stop a run when global time would pass this")
@click.option("--max-steps", type=click.IntRange(min=1), default=100_000, show_default=True,
              help="most transitions in one time step before a run is stopped as looping")
@click.option("--stall-steps", type=click.IntRange(min=0), default=20, show_default=True,
              help="stop a run, as stalled, when nothing changed for this many time steps")
@click.option("--invariant", "invariants", multiple=True, metavar="EXPR",
              help="a state property checked after every transition of every run "
                   "(repeatable; the program's invariant: section is always checked)")
@click.option("--property", "properties", multiple=True, metavar="FORM",
              help="a property checked on every run, as pccl run --property (repeatable)")
@click.option("--trace", is_flag=True,
              help="print every step of the first violating run (default: its last "
                   f"{SIM_TAIL})")
@click.option("--trace-out", type=click.Path(dir_okay=False), default=None,
              help="write the first violating run as a trace file (for pccl replay)")
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True)
def simulate(program, agents, world, blackbox, delta, n0, rates, events, lang, semantics, skip_events,
             collisions, overrides,
             runs, runs_n, seed, max_time, max_steps, stall_steps, invariants, properties,
             trace, trace_out, fmt):
    """Run PROGRAM many times (as pccl run, with seeds SEED, SEED+1, ...), checking
    the program's invariants and any --invariant/--property on every run, and count
    the outcomes: final, bounded, deadlock, stalled, max-steps and each violation, with
    their frequencies (95% confidence intervals), the times, the first violating run's
    trace, and the pccl run command that reproduces each outcome."""
    import random

    from pccl.model.options import RunOptions
    from pccl.output import traces as T
    from pccl.tools import simulate as S
    runs = _runs_count(runs, runs_n)
    if trace_out:
        _check_output(trace_out, "--trace-out")
    rng = random.Random(seed)
    _check_repeats(rates, overrides)
    # the runs of pccl run, one per seed
    opts = RunOptions.from_cli(click.get_current_context().params)
    model, outcomes, first_bad = _simulate_runs(program, opts, rng, runs, seed, max_steps,
                                                stall_steps)

    def command(s):
        return S.run_command(program, seed=s, world=world, blackbox=blackbox, agents=agents,
                             delta=_delta(delta), n0=n0, rates=rates, events=events,
                             semantics=semantics, skip_events=skip_events, lang=lang,
                             collisions=collisions, overrides=overrides,
                             max_time=_delta(max_time), max_steps=max_steps,
                             invariants=invariants, properties=properties,
                             stall_steps=stall_steps)
    bad = any(S.is_bad(o) for o in outcomes.values())
    # a run out of memory is a limit of the tool, not a verdict (exit 2)
    code = 2 if ("out-of-memory",) in outcomes else 1 if bad else 0
    doc = None
    if first_bad is not None and (trace_out or fmt == "json"):
        cfg = T.config("run", model, program=program, seed=_first_bad_seed(outcomes))
        doc = T.run_document(first_bad, cfg)
    if fmt == "json":
        _print_simulate_json(program, model, outcomes, first_bad, seed, code, doc, command,
                             invariants, properties)
        if doc is not None and trace_out:
            _write_trace(doc, trace_out, quiet=True)
        sys.exit(code)
    _print_simulate_text(program, model, outcomes, first_bad, seed, command, trace)
    if doc is not None:
        _write_trace(doc, trace_out)
    sys.exit(code)


def _runs_count(runs, runs_n) -> int:
    """Step of simulate: the number of runs, from --runs or the deprecated -n."""
    if runs is not None and runs_n is not None:
        raise click.UsageError("give the number of runs once: --runs (or the deprecated -n)")
    if runs_n is not None:
        click.echo("pccl simulate: -n is deprecated (in run and explore -n is the number of "
                   "agents); use --runs", err=True)
        runs = runs_n
    return 100 if runs is None else runs


def _simulate_runs(program, opts, rng, runs, seed, max_steps, stall_steps) -> tuple:
    """Step of simulate: (model, outcomes, the first violating run replayed
    with its trace or None)."""
    from pccl.api import build_model
    from pccl.tools import simulate as S
    first_bad = None
    try:
        model = build_model(program, opts, rng=rng)
        outcomes = S.simulate(model, rng, runs=runs, seed=seed, max_steps=max_steps,
                              stall_steps=stall_steps, spelling=cli_spelling)
        bad_seeds = [o.first_seed for o in outcomes.values() if S.is_bad(o)
                     and o.key[0] != "out-of-memory"]
        if bad_seeds:
            first_bad = S.replay_run(model, rng, seed=min(bad_seeds), max_steps=max_steps,
                                     stall_steps=stall_steps, spelling=cli_spelling)
            first_bad.model = model
    except PcclError as e:
        _fail(e)
    return model, outcomes, first_bad


def _first_bad_seed(outcomes) -> int:
    """The first seed of a violating outcome (there is one)."""
    from pccl.tools import simulate as S
    return min(o.first_seed for o in outcomes.values() if S.is_bad(o))


def _print_simulate_json(program, model, outcomes, first_bad, seed, code, doc, command,
                         invariants, properties) -> None:
    """Step of simulate: the outcomes as JSON (--format json)."""
    import json

    from pccl.output.codec import output
    from pccl.tools import simulate as S
    done_runs = sum(len(o.seeds) for o in outcomes.values())
    bad_times = [t for o in outcomes.values() if S.is_bad(o) for t in o.times]
    n_bad = len(bad_times)
    lo, hi = S.wilson(n_bad, done_runs)
    status = "out-of-memory" if code == 2 else "violation" if n_bad else "clean"
    message = (f"violations: {S.frequency(n_bad, done_runs)}" if n_bad else
               f"violations: none in {done_runs} runs")
    click.echo(json.dumps(output(
        "simulate", status=status, message=message, exit_status=code, trace=doc,
        **{"program": program, "runs": done_runs, "first_seed": seed, "agents": model.N,
        "blackbox": model.blackbox.name,
        "invariants": list(invariants), "properties": list(properties),
        "outcomes": [{"outcome": o.label, "count": len(o.seeds),
                      "frequency": len(o.seeds) / done_runs,
                      "ci95": list(S.wilson(len(o.seeds), done_runs)),
                      "first_seed": o.first_seed,
                      "seeds": o.seeds[:100], "example": o.example,
                      "times": {"min": min(o.times), "median": statistics_median(o.times),
                                "mean": sum(o.times) / len(o.times),
                                "max": max(o.times)},
                      "violation": S.is_bad(o),
                      "command": command(o.first_seed)} for o in outcomes.values()],
        "violations": {"count": n_bad, "frequency": n_bad / done_runs, "ci95": [lo, hi],
                       "time_to_violation": ({"min": min(bad_times),
                                              "median": statistics_median(bad_times),
                                              "mean": sum(bad_times) / n_bad,
                                              "max": max(bad_times)} if bad_times else None),
                       "first_seed": first_bad and _first_bad_seed(outcomes)}}),
        indent=2, default=str))


def _print_simulate_text(program, model, outcomes, first_bad, seed, command, trace) -> None:
    """Step of simulate: the outcomes as text."""
    from pccl.output import display as D
    from pccl.tools import simulate as S
    done_runs = sum(len(o.seeds) for o in outcomes.values())
    bad_times = [t for o in outcomes.values() if S.is_bad(o) for t in o.times]
    n_bad = len(bad_times)
    click.echo(f"pccl simulate {program}: {done_runs} runs (seeds {seed}–{seed + done_runs - 1}), "
               f"{model.N} agents, blackbox {model.blackbox.name}, δ={D.fmt_time(model.delta)}, "
               f"n0={model.n0}{_rates_text(model)}")
    props = _property_names(model)
    if props:
        click.echo("checked on every run: " + ", ".join(props))
    click.echo("outcomes:")
    for o in sorted(outcomes.values(), key=lambda o: -len(o.seeds)):
        click.echo(f"  {o.label}: {S.frequency(len(o.seeds), done_runs)}, "
                   f"{S.time_summary(o.times)}")
        if S.is_bad(o):
            click.echo(f"    e.g. {o.example}")
        click.echo(f"    first seed {o.first_seed}: {command(o.first_seed)}")
    if n_bad:
        click.echo(f"violations: {S.frequency(n_bad, done_runs)}; time to violation: "
                   + S.time_summary(bad_times).removeprefix("time "))
    else:
        lo, hi = S.wilson(0, done_runs)
        click.echo(f"violations: none in {done_runs} runs (95% CI 0.0–{100 * hi:.1f}%: a "
                   f"sample, not a proof; pccl explore checks every run)")
    done = [t for o in outcomes.values() if o.key[0] == "final" for t in o.times]
    if done:
        click.echo(f"completion time ({len(done)} runs in which every agent exited):")
        for ln in S.histogram(done):
            click.echo(ln)
    if first_bad is not None:
        _print_first_bad(model, outcomes, first_bad, trace)


def _print_first_bad(model, outcomes, first_bad, trace) -> None:
    """Step of simulate: the first violating run and the tail of its trace
    (all of it with --trace)."""
    from pccl.output import display as D
    s0 = _first_bad_seed(outcomes)
    click.echo(f"first violating run (seed {s0}): {first_bad.status} — {first_bad.message}")
    path = _run_path(first_bad)
    n_steps = len(path)
    skip = 0 if trace else max(0, n_steps - SIM_TAIL)
    click.echo(f"trace ({n_steps} steps" + (f"; the last {n_steps - skip}, --trace for all"
                                            if skip else "") + "):")
    for st in path.steps[skip:]:
        click.echo(D.format_step(model, st.number, st.label, st.before, st.after))


def _property_names(model) -> list:
    """The invariants and temporal properties a model checks, as the user wrote them."""
    out = []
    for p in list(model.properties) + list(model.temporal):
        if not p.text:
            continue
        name = f"{p.name} " if p.name and p.name != p.text else ""
        label = f"{name}'{p.text}'"
        if label not in out:
            out.append(label)
    return out


def statistics_median(xs):
    import statistics
    return statistics.median(xs)
