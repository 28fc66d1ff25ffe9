"""The ``pccl`` command line: run, check and explore PCCL programs."""

from __future__ import annotations

import json
import sys

import click

from . import display as D
from .errors import PcclError

BLACKBOX_HELP = ("environment model: instant, straight, nondet, pymunk, or module:attribute "
                 "for your own [default: straight]")


class RateType(click.ParamType):
    name = "AGENT=RATE"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        try:
            a, r = value.split("=")
            a, r = int(a), int(r)
        except ValueError:
            self.fail(f"{value!r} is not AGENT=RATE (for example 1=2)", param, ctx)
        if a < 0:
            self.fail(f"{value!r}: agents are numbered from 0", param, ctx)
        if r < 1:
            self.fail(f"{value!r}: a rate is a positive integer", param, ctx)
        return a, r


class FiniteFloat(click.FloatRange):
    """A float range that also refuses nan and inf (click lets them through)."""

    def convert(self, value, param, ctx):
        import math
        rv = super().convert(value, param, ctx)
        if not math.isfinite(rv):
            self.fail(f"{value!r} is not a finite number", param, ctx)
        return rv


class SetType(click.ParamType):
    name = "NAME=EXPR"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        name, sep, expr = value.partition("=")
        if not sep or not name.strip() or not expr.strip():
            self.fail(f"{value!r} is not NAME=EXPR (for example k=2)", param, ctx)
        return name.strip(), expr.strip()


def common_options(f):
    opts = [
        click.option("--agents", "-n", type=click.IntRange(min=1), default=None,
                     help="number of agents (overrides the world's count) [default: world's, else 2]"),
        click.option("--world", "-w", type=click.Path(dir_okay=False), default=None,
                     help="world file (TOML): start positions, obstacles, function values"),
        click.option("--blackbox", "-b", default="straight", show_default=False, help=BLACKBOX_HELP),
        click.option("--delta", type=FiniteFloat(min=0, min_open=True), default=1.0,
                     show_default=True, help="time step δ"),
        click.option("--n0", type=click.IntRange(min=1), default=1, show_default=True,
                     help="event-block executions per agent per time step"),
        click.option("--rate", "rates", type=RateType(), multiple=True,
                     help="per-agent rate ρ, 1..n0: each event block of agent A costs ρ of the "
                          "n0 per time step, e.g. --n0 2 --rate 1=2 (repeatable)"),
        click.option("--events", type=click.Choice(["any", "first"]), default="any",
                     show_default=True,
                     help="any enabled event may run, or only the first in source order"),
        click.option("--collisions", is_flag=True,
                     help="report robots overlapping each other or an obstacle"),
        click.option("--set", "overrides", type=SetType(), multiple=True,
                     help="override a variable's initialiser, e.g. --set k=2 (repeatable)"),
    ]
    for o in reversed(opts):
        f = o(f)
    return f


def _delta(d):
    return int(d) if float(d).is_integer() else d


def _model_options(delta, n0, rates, events, collisions, overrides):
    for opt, pairs, what in (("--rate", rates, "agent"), ("--set", overrides, "variable")):
        names = [k for k, _ in pairs]
        twice = sorted({str(k) for k in names if names.count(k) > 1})
        if twice:
            raise click.BadParameter(f"{what} {', '.join(twice)} given more than once",
                                     param_hint=f"'{opt}'")
    return dict(delta=_delta(delta), n0=n0, rates=dict(rates), events=events,
                collisions=collisions, overrides=dict(overrides))


def _fail(err: PcclError):
    click.echo(err.render(), err=True)
    sys.exit(2)


EXIT_STATUS_HELP = ("Exit status: 0 the properties hold (exhaustive, or within the bounds "
                    "named), 1 a violation, 2 bad input (the program, the world, an option), "
                    "130 interrupted (Ctrl-C), 143 terminated (SIGTERM).")

_signal = {"term": False}


def _on_sigterm(signum, frame):
    # stop like Ctrl-C (explore prints the statistics so far), exit 143
    _signal["term"] = True
    raise KeyboardInterrupt


def _interrupted_status(code: int) -> int:
    return 143 if code == 130 and _signal["term"] else code


class _Main(click.Group):
    """Ctrl-C and SIGTERM outside a search exit 130 and 143, not click's
    "Aborted!" with status 1 (which means a violation)."""

    def invoke(self, ctx):
        import signal
        import threading
        previous = None
        if threading.current_thread() is threading.main_thread():
            previous = signal.signal(signal.SIGTERM, _on_sigterm)
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt:
            click.echo("pccl: interrupted", err=True)
            sys.exit(_interrupted_status(130))
        finally:
            if previous is not None:
                signal.signal(signal.SIGTERM, previous)


@click.group(cls=_Main, epilog=EXIT_STATUS_HELP,
             context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="pccl")
def main():
    """pccl: run and model-check PCCL programs for teams of robots.

    \b
      pccl check PROGRAM            parse and type-check only
      pccl run PROGRAM              one seeded execution against a physics model
      pccl explore PROGRAM          every interleaving, breadth-first, with
                                    shortest counterexamples

    A violation is a stuck agent, a failed assertion or invariant, a deadlock
    or (with --collisions) a collision.
    """


@main.command(short_help="Parse and type-check a program.")
@click.argument("program", type=click.Path(dir_okay=False))
@click.option("--world", "-w", type=click.Path(dir_okay=False), default=None,
              help="world file whose uninterpreted functions the program may use")
def check(program, world):
    """Parse and statically check PROGRAM; print nothing else on success."""
    from .api import load_program, load_world_arg
    from .checker import check_program
    try:
        prog = load_program(program)
        w = load_world_arg(world)
        names = frozenset(dict(w.functions).keys()) if w is not None else frozenset()
        check_program(prog, functions=names)
    except PcclError as e:
        _fail(e)
    click.echo(f"{program}: ok ({len(prog.events)} events, {prog.n_statements} statements)")


@main.command(short_help="Execute a program once (seeded).", epilog=EXIT_STATUS_HELP)
@click.argument("program", type=click.Path(dir_okay=False))
@common_options
@click.option("--seed", type=int, default=0, show_default=True, help="random seed: same seed, same run")
@click.option("--max-time", type=FiniteFloat(min=0), default=100, show_default=True,
              help="stop when global time would pass this")
@click.option("--max-steps", type=click.IntRange(min=1), default=100_000, show_default=True,
              help="most transitions in one time step before the run is stopped as looping")
@click.option("--trace", is_flag=True, help="print every transition")
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True)
@click.option("--plot", type=click.Path(dir_okay=False), default=None,
              help="draw the arena and trajectories to this PNG (needs matplotlib)")
def run(program, agents, world, blackbox, delta, n0, rates, events, collisions, overrides, seed,
        max_time, max_steps, trace, fmt, plot):
    """Execute PROGRAM once, choosing among enabled transitions with a seeded generator."""
    from .api import run as api_run
    if plot:
        _check_plot_output(plot)
    try:
        res = api_run(program, world=world, blackbox=blackbox, agents=agents, seed=seed,
                      max_steps=max_steps, record_trace=trace or plot is not None,
                      max_time=_delta(max_time),
                      **_model_options(delta, n0, rates, events, collisions, overrides))
    except PcclError as e:
        _fail(e)
    m = res.model
    if fmt == "json":
        out = {"program": program, "blackbox": m.blackbox.name, "agents": m.N, "seed": seed,
               "delta": m.delta, "n0": m.n0, "rates": list(m.rho),
               "result": res.status, "message": res.message, "exit_status": res.exit_status,
               "steps": res.steps,
               "summary": [{"time": t, "positions": [list(ag[6]) for ag in s[4]]}
                           for t, s in res.summary],
               "final": D.state_json(m, res.final)}
        if trace:
            out["trace"] = [D.step_json(m, n + 1, lab, a, b) for n, (lab, a, b) in enumerate(res.trace)]
        click.echo(json.dumps(out, indent=2, default=str))
    else:
        click.echo(f"pccl run {program}: {m.N} agents, blackbox {m.blackbox.name}, "
                   f"δ={D.fmt_time(m.delta)}, n0={m.n0}{_rates_text(m)}, seed {seed}")
        if trace:
            click.echo("trace:")
            for n, (lab, a, b) in enumerate(res.trace):
                click.echo(D.format_step(m, n + 1, lab, a, b))
        click.echo("time steps:")
        prev = None
        for t, s in res.summary:
            click.echo(f"  t={D.fmt_time(t)}: " + _step_summary(m, prev, s))
            prev = s
        click.echo(f"result: {res.status} — {res.message} "
                   f"(t={D.fmt_time(res.final[0])}, {res.steps} transitions)")
        for v in res.violations:
            if v.span is not None:
                click.echo(f"  at {m.program.filename}:{v.span.line}:{v.span.column}: "
                           f"{D.source_line(m, v.span)}")
        click.echo("final configuration:")
        click.echo(D.format_state(m, res.final))
    if plot:
        _plot_run(m, res, plot, quiet=(fmt == "json"))
    sys.exit(res.exit_status)


def _rates_text(m) -> str:
    """The agents whose rate ρ is not 1, for the header line ("" when none)."""
    odd = [f"{i}={r}" for i, r in enumerate(m.rho) if r != 1]
    return f", rates {' '.join(odd)}" if odd else ""


def _step_summary(m, prev, s) -> str:
    parts = []
    for i, ag in enumerate(s[4]):
        st = D.status_text(m, ag[3])
        parts.append(f"a{i} {D.fmt_pos(ag[6])}" + ("" if st == "running" else f" {st}"))
    if prev is not None:
        ch = [c for c in D.diff(m, prev, s) if not c[0].startswith(("pos[", "time", "transitionState"))]
        if ch:
            parts.append("; ".join(f"{c}={nw}" for c, _, nw in ch))
    return "  ".join(parts)


def _plot_module():
    import importlib
    try:
        plot = importlib.import_module(".plot", __package__)
    except ImportError as e:  # matplotlib missing
        click.echo(f"pccl: --plot needs matplotlib: pip install 'pccl[plot]' ({e})", err=True)
        sys.exit(2)
    return plot


def _check_plot_output(path):
    """Before any work: --plot needs matplotlib and a writable path, so that
    a failure to write it never replaces the verdict's exit status."""
    _plot_module()
    try:
        check_writable(path, "--plot")
    except PcclError as e:
        _fail(e)


def check_writable(path, option):
    """Raise a PcclError unless ``path`` can be created or overwritten."""
    import os
    full = os.path.abspath(os.fspath(path))
    parent = os.path.dirname(full)
    problem = None
    if os.path.isdir(full):
        problem = "it is a directory"
    elif not os.path.isdir(parent):
        problem = f"directory {os.path.dirname(os.fspath(path)) or parent} does not exist"
    elif os.path.exists(full) and not os.access(full, os.W_OK):
        problem = "the file is not writable"
    elif not os.path.exists(full) and not os.access(parent, os.W_OK | os.X_OK):
        problem = f"directory {os.path.dirname(os.fspath(path)) or '.'} is not writable"
    if problem:
        raise PcclError(f"cannot write {path}: {problem}", filename=option)


def _plot_run(m, res, path, *, quiet=False):
    try:
        _plot_module().plot_run(m, res, path)
    except PcclError as e:      # the run's verdict stands: report, keep its exit status
        click.echo(e.render(), err=True)
        return
    click.echo(f"plot written to {path}", err=quiet)


@main.command(short_help="Explore every interleaving; shortest counterexamples.",
              epilog=EXIT_STATUS_HELP)
@click.argument("program", type=click.Path(dir_okay=False))
@common_options
@click.option("--depth", type=click.IntRange(min=0), default=None,
              help="explore at most this many transitions from an initial state")
@click.option("--max-time", type=FiniteFloat(min=0), default=None,
              help="global time bound (TIME ADVANCE fires only while time + δ ≤ T)")
@click.option("--max-states", type=click.IntRange(min=1), default=None,
              help="stop after this many distinct states")
@click.option("--max-memory", "max_memory", metavar="SIZE", default=None, callback=lambda c, p, v: _size(v),
              help="stop (as a bound) when the process's memory passes SIZE, e.g. 800M or 4G "
                   "[default: 80% of physical memory]")
@click.option("--abstract-time/--no-abstract-time", default=None,
              help="leave the clock out of state identity [default: on when sound and no --max-time]")
@click.option("--invariant", "invariants", multiple=True, metavar="EXPR",
              help="a state property to check, e.g. 'count(inCs) <= 1' (repeatable)")
@click.option("--reduce", "reduce", metavar="auto|none|LIST", default="auto", show_default=True,
              help="state-space reductions: auto (every sound one), none, or a "
                   "comma-separated list of merge, symmetry")
@click.option("--no-deadlock", is_flag=True, help="do not report deadlocks")
@click.option("--all", "find_all", is_flag=True,
              help="keep exploring and report each distinct violation once")
@click.option("--exact", is_flag=True,
              help="store canonical state encodings instead of 128-bit fingerprints (more memory, no collisions)")
@click.option("--format", "fmt", type=click.Choice(["text", "json", "k"]), default="text",
              show_default=True)
@click.option("--plot", type=click.Path(dir_okay=False), default=None,
              help="draw the counterexample's trajectories to this PNG (needs matplotlib)")
@click.option("--progress/--no-progress", default=None,
              help="progress line on stderr [default: when stderr is a terminal]")
def explore(program, agents, world, blackbox, delta, n0, rates, events, collisions, overrides, depth,
            max_time, max_states, max_memory, abstract_time, invariants, reduce, no_deadlock,
            find_all, exact, fmt, plot, progress):
    """Explore every interleaving of PROGRAM breadth-first and report the first
    violation with a shortest counterexample."""
    from .api import explore_model, make_model
    if plot:
        _check_plot_output(plot)
    try:
        model = make_model(program, world=world, blackbox=blackbox, agents=agents,
                           max_time=None if max_time is None else _delta(max_time),
                           abstract_time=abstract_time, invariants=tuple(invariants),
                           reduce=reduce, **_model_options(delta, n0, rates, events, collisions, overrides))
    except PcclError as e:
        _fail(e)
    show = sys.stderr.isatty() if progress is None else progress
    reporter = _progress_printer() if show else None
    try:
        res = explore_model(model, depth=depth, max_states=max_states, deadlock=not no_deadlock,
                            find_all=find_all, exact=exact, progress=reporter,
                            max_memory="default" if max_memory is None else max_memory)
    except PcclError as e:      # found only while exploring (a blackbox, a world value, ...)
        if show:
            click.echo("\r\033[K", err=True, nl=False)
        _fail(e)
    if show:
        click.echo("\r\033[K", err=True, nl=False)
    if fmt == "json":
        click.echo(json.dumps(_explore_json(program, res), indent=2, default=str))
    else:
        _print_explore_text(program, res, k_style=(fmt == "k"))
    if plot and res.violations:
        try:
            _plot_module().plot_trace(model, list(res.counterexamples[0].trace), plot,
                                      title=res.violations[0]["message"])
            click.echo(f"plot written to {plot}", err=(fmt == "json"))
        except PcclError as e:  # the violation stands: report, keep exit status 1
            click.echo(e.render(), err=True)
    elif plot:
        click.echo(f"pccl: no counterexample, so no plot written to {plot}", err=True)
    sys.exit(_interrupted_status(res.exit_status))


def _size(value):
    if value is None:
        return None
    from .api import parse_size
    try:
        return parse_size(value)
    except ValueError as e:
        raise click.BadParameter(str(e)) from None


def _progress_printer():
    def report(p):
        sps = p["states"] / p["seconds"] if p["seconds"] > 0 else 0
        click.echo(f"\r\033[Kstates {p['states']:,}  frontier {p['frontier']:,}  depth {p['depth']}  "
                   f"{sps:,.0f} states/s  mem {p['memory'] / 2**20:,.0f} MiB", err=True, nl=False)
    return report


def _stats_lines(res) -> list:
    s = res.stats
    lines = [f"  initial states   {s.initial_states:,}",
             f"  states           {s.states:,}",
             f"  transitions      {s.transitions:,}",
             f"  max depth        {s.max_depth}",
             f"  seconds          {s.seconds:.2f}",
             f"  states/second    {s.states_per_second:,.0f}",
             f"  peak memory      {s.peak_memory / 2**20:,.1f} MiB"]
    if res.search is not None and res.search.exact:
        lines.append("  state identity   exact (canonical encodings; no collision possible)")
    else:
        lines.append(f"  fingerprints     128-bit xxh3 of a canonical encoding; "
                     f"collision probability ≤ {res.collision_probability:.1e}")
    return lines


def _print_explore_text(program, res, *, k_style=False):
    m = res.model
    click.echo(f"pccl explore {program}: {m.N} agents, blackbox {m.blackbox.name}, "
               f"δ={D.fmt_time(m.delta)}, n0={m.n0}{_rates_text(m)}, events {m.events_policy}, "
               f"time abstraction {'on' if m.abstract_time else 'off'}, "
               f"reductions {m.reduction.describe()}")
    click.echo(res.verdict)
    for v, cx in zip(res.violations, res.counterexamples):
        click.echo("")
        click.echo(f"{v['message']}")
        if v["line"]:
            click.echo(f"  at {m.program.filename}:{v['line']}:{v['column']}")
        tr = cx.trace
        note = ", shortest under the reductions" if m.reduction.on else ""
        click.echo(f"counterexample ({len(tr)} steps{note}):")
        for st in tr.steps:
            click.echo(D.format_step(m, st.number, st.label, st.before, st.after))
        click.echo("violating state:")
        if k_style:
            click.echo(D.format_state_k(m, tr.last))
        else:
            click.echo(D.format_state(m, tr.last))
    click.echo("statistics:")
    for ln in _stats_lines(res):
        click.echo(ln)


def _explore_json(program, res) -> dict:
    m = res.model
    return {"program": program, "blackbox": res.blackbox, "agents": m.N,
            "delta": m.delta, "n0": m.n0, "rates": list(m.rho),
            "status": res.status, "verdict": res.verdict, "exit_status": res.exit_status,
            "bounds": res.bounds, "time_abstraction": m.abstract_time,
            "reductions": m.reduction.as_dict(),
            "statistics": res.stats.as_dict(),
            "collision_probability": res.collision_probability,
            "fingerprints": "exact" if res.search.exact else "xxh3_128",
            "violations": res.violations}


if __name__ == "__main__":  # pragma: no cover
    main()
