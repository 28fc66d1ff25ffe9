"""The ``pccl`` command line: run, check and explore PCCL programs."""

from __future__ import annotations

import sys

import click

from pccl.lang.errors import PcclError

#: Options whose flag is not ``--`` + the name with ``-`` for ``_``.  The flags
#: are spelt here only: the engine, the API and the outputs name options by
#: placeholders (``{depth=10}``, :func:`pccl.lang.errors.spell`) that the API
#: writes as keywords and the CLI as flags (:func:`cli_spelling`).
FLAGS = {"agents": "--agents", "rates": "--rate", "overrides": "--set",
         "invariants": "--invariant", "deadlock": "--no-deadlock", "find_all": "--all",
         "properties": "--property", "timelock": "--no-timelock",
         "stall": "--no-stall", "shorten": "--no-shorten"}
#: Options written with their short flag when given with a value (as the
#: verdict's note has always said it: ``-b nondet explores every timing``).
SHORT_FLAGS = {"blackbox": "-b"}


def flag(name: str) -> str:
    """The command-line flag of the option ``name``."""
    return FLAGS.get(name, "--" + name.replace("_", "-"))


def cli_spelling(name: str, value) -> "str | None":
    """An option as the command line spells it: ``--fastest``, ``--workers 1``,
    ``--no-timelock`` for ``timelock=False``, ``--rate 1=2`` (for
    :func:`pccl.lang.errors.spell`); None for a name that is no option."""
    from pccl.model.options import OPTION_NAMES
    if name not in OPTION_NAMES:
        return None
    if value is not None and name in SHORT_FLAGS:
        return f"{SHORT_FLAGS[name]} {value}"
    f = flag(name)
    if value is None or value == "True" or (value == "False" and f.startswith("--no-")):
        return f
    return f"{f} {value}"


def _render(err: PcclError) -> str:
    """``err`` as the command line says it: its options as flags."""
    return err.respell(cli_spelling).render()

BLACKBOX_HELP = ("environment model: instant, straight, nondet, nondet-fail, pymunk, or "
                 "module:attribute for your own [default: straight; explore: nondet for a "
                 "program that calls doReach: every timing, and every failure straight or "
                 "pymunk could report]")


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


class Choice(click.Choice):
    """click.Choice that also says which choice a misspelt value is closest to."""

    def convert(self, value, param, ctx):
        try:
            return super().convert(value, param, ctx)
        except click.BadParameter:
            import difflib
            close = difflib.get_close_matches(str(value).lower(), list(self.choices), n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            self.fail(f"{value!r} is not one of {', '.join(map(repr, self.choices))}{hint}",
                      param, ctx)


class SetType(click.ParamType):
    name = "NAME=EXPR"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        name, sep, expr = value.partition("=")
        if not sep or not name.strip() or not expr.strip():
            self.fail(f"{value!r} is not NAME=EXPR (for example k=2)", param, ctx)
        return name.strip(), expr.strip()


def common_options(f, *, agents_flags=("--agents", "-n")):
    opts = [
        click.option(*agents_flags, "agents", type=click.IntRange(min=1), default=None,
                     help="number of agents (overrides the world's count) [default: world's, else 2]"),
        click.option("--world", "-w", type=click.Path(dir_okay=False), default=None,
                     help="world file (TOML): start positions, obstacles, function values"),
        click.option("--blackbox", "-b", default=None, show_default=False, help=BLACKBOX_HELP),
        click.option("--delta", type=FiniteFloat(min=0, min_open=True), default=1.0,
                     show_default=True, help="time step δ"),
        click.option("--n0", type=click.IntRange(min=1), default=1, show_default=True,
                     help="event-block executions per agent per time step"),
        click.option("--rate", "rates", type=RateType(), multiple=True,
                     help="per-agent rate ρ, 1..n0: each event block of agent A costs ρ of the "
                          "n0 per time step, e.g. --n0 2 --rate 1=2 (repeatable)"),
        click.option("--events", type=Choice(["any", "first"]), default="any",
                     show_default=True,
                     help="any enabled event may run, or only the first in source order"),
        click.option("--semantics", type=Choice(["pccl", "koord"]), default=None,
                     help="the execution model: PCCL's (statements interleave) or Koord's "
                          "rounds (one event per robot per round as one transition, "
                          "round-consistent memory; Koord programs only: docs/koord.md) "
                          "[default: koord for .koord/.krd files, else pccl]"),
        click.option("--skip-events", is_flag=True,
                     help="Koord's SkipEvent: a robot may let a round pass although an event "
                          "is enabled (--semantics koord)"),
        click.option("--collisions", is_flag=True,
                     help="report robots overlapping each other or an obstacle"),
        click.option("--set", "overrides", type=SetType(), multiple=True,
                     help="override a variable's initialiser, e.g. --set k=2 (repeatable)"),
    ]
    for o in reversed(opts):
        f = o(f)
    return f


def common_options_without_n(f):
    """The common options, with -n left free (simulate's -n is the number of runs)."""
    return common_options(f, agents_flags=("--agents",))


def view_options(f):
    f = click.option("--full", is_flag=True,
                     help="with --view steps: also show the steps that change nothing")(f)
    f = click.option("--view", type=click.Choice(["steps", "swimlane"]), default=None,
                     help="how to show the trace: steps (from the initial state, branches "
                          "named, empty steps folded) or swimlane (one column per agent)")(f)
    return f


def watch_option(f):
    return click.option("--watch", "watch", multiple=True, metavar="EXPR",
                        help="with --html: an expression (a property expression of any type) "
                             "to evaluate in every state of the path, shown in the page's "
                             "expressions panel and plot (repeatable)")(f)


def _check_watch(model, watch, html) -> None:
    """--watch: each expression checks against the program (a PcclError at
    its caret otherwise), and it needs --html."""
    if watch and not html:
        raise PcclError("--watch needs --html (it shows in the page)", filename="--watch")
    from pccl.output.viewer import watch_function
    for k, text in enumerate(watch):
        watch_function(model, text, k)


def _delta(d):
    # 2.0 is 2; a huge integral float stays a float (its int would print 300 digits)
    return int(d) if float(d).is_integer() and abs(d) < 2 ** 53 else d


def _check_repeats(rates, overrides):
    """A repeated --rate for one agent or --set for one variable is a mistake."""
    for opt, pairs, what in (("--rate", rates, "agent"), ("--set", overrides, "variable")):
        names = [k for k, _ in pairs]
        twice = sorted({str(k) for k in names if names.count(k) > 1})
        if twice:
            raise click.BadParameter(f"{what} {', '.join(twice)} given more than once",
                                     param_hint=f"'{opt}'")


def _fail(err: PcclError):
    click.echo(_render(err), err=True)
    sys.exit(2)


EXIT_STATUS_HELP = ("Exit status: 0 the properties hold (exhaustive, or within the bounds "
                    "named; a 'reachable P' has a witness), 1 a violation (also a liveness "
                    "counterexample, a time-lock, a stall, an unreachable 'reachable P', a stalled "
                    "run), 2 bad input (the program, the world, an option) or a limit of the "
                    "tool (out of memory, rand over 1,000,000 outcomes), "
                    "130 interrupted (Ctrl-C), 143 terminated (SIGTERM). With --exit-codes "
                    "detailed (run, explore) a violation exits 11 deadlock/stall, 12 "
                    "invariant/collision, 13 temporal property, 14 assertion/stuck, "
                    "15 time-lock, 16 --max-steps.")

_signal = {"term": False}


def _on_sigterm(signum, frame):
    # stop like Ctrl-C (explore prints the statistics so far), exit 143
    _signal["term"] = True
    raise KeyboardInterrupt


def _interrupted_status(code: int) -> int:
    return 143 if code == 130 and _signal["term"] else code


def _exit_status(code: int, kinds, mode: str) -> int:
    """The status to exit with: 143 for SIGTERM, and under ``--exit-codes
    detailed`` a violation's status by its kind (pccl/tools/exitcodes.py)."""
    from pccl.tools.exitcodes import status
    return status(_interrupted_status(code), kinds, mode)


def _print_version(ctx, value) -> None:
    """``--version``: what a bug report needs to say what ran
    (:mod:`pccl.tools.about`; imports no engine module)."""
    if not value or ctx.resilient_parsing:
        return
    from pccl.tools.about import version_lines
    click.echo("\n".join(version_lines()))
    ctx.exit()


class _Main(click.Group):
    """Ctrl-C and SIGTERM outside a search exit 130 and 143, not click's
    "Aborted!" with status 1 (which means a violation)."""

    def invoke(self, ctx):
        import signal
        import threading
        previous = None
        _signal["term"] = False
        try:
            if threading.current_thread() is threading.main_thread():
                previous = signal.signal(signal.SIGTERM, _on_sigterm)
            return super().invoke(ctx)
        except KeyboardInterrupt:
            click.echo("pccl: interrupted", err=True)
            sys.exit(_interrupted_status(130))
        except MemoryError:
            # what the command held is released with its frames by now
            from pccl.search.memory import peak_rss_bytes
            click.echo(f"pccl {ctx.invoked_subcommand or ''}: out of memory: the process could "
                       f"not allocate more (peak memory {peak_rss_bytes() / 2**20:,.1f} MiB; a "
                       f"limit such as ulimit -v, or the machine's memory); give --max-memory "
                       f"below that limit to stop cleanly as a bound", err=True)
            sys.exit(2)
        finally:
            if previous is not None:
                signal.signal(signal.SIGTERM, previous)


@click.group(cls=_Main, epilog=EXIT_STATUS_HELP,
             context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.option("--version", is_flag=True, expose_value=False, is_eager=True,
              callback=lambda ctx, param, value: _print_version(ctx, value),
              help="Show the version, the native engine's availability, the extras installed, "
                   "Python and the platform, and exit.")
def main():
    """pccl: run and model-check PCCL programs for teams of robots.

    \b
      pccl check PROGRAM            parse and type-check only
      pccl run PROGRAM              one seeded execution against a physics model
      pccl explore PROGRAM          every interleaving, breadth-first, with
                                    shortest counterexamples
      pccl replay FILE              re-execute a trace file (--trace-out)
      pccl view FILE -o F.html      a self-contained HTML viewer of a trace file
      pccl serve PROGRAM            interactive explorer in the browser (127.0.0.1)
      pccl graph PROGRAM -o F.dot   the reachable state graph (DOT or JSON)
      pccl simulate PROGRAM --runs N  many seeded runs: outcomes and their seeds
      pccl fmt PROGRAM...           canonical layout (--check: exit 1 if not)
      pccl lsp                      language server for editors (stdio)
      pccl cache                    the native engine's module cache (--clear)

    A violation is a stuck agent, a failed assertion or invariant, a deadlock,
    a time-lock, a stall, a failed temporal property (--property: eventually P, P ~> Q,
    P ~> Q within T, reachable P) or (with --collisions) a collision.
    """


#: ``--exit-codes`` of run and explore (one option, one help text)
_EXIT_CODES = click.option(
    "--exit-codes", "exit_codes", type=Choice(["default", "detailed"]),
    default="default", show_default=True,
    help="detailed: a violation exits 11 deadlock/stall, 12 invariant/collision, "
         "13 temporal property, 14 assertion/stuck, 15 time-lock, 16 --max-steps "
         "(instead of 1)")


@main.command(short_help="Parse and type-check a program.")
@click.argument("program", type=click.Path(dir_okay=False))
@click.option("--world", "-w", type=click.Path(dir_okay=False), default=None,
              help="world file whose uninterpreted functions the program may use")
def check(program, world):
    """Parse and statically check PROGRAM; print nothing else on success."""
    # the front end only (not pccl.api, which imports the engines: start-up)
    from pccl.lang.checker import check_program
    from pccl.lang.files import parse_program_file
    from pccl.lang.world import load_world
    try:
        prog = parse_program_file(program)      # PCCL, or Koord (.koord, .krd)
        w = load_world(world) if world is not None else None
        names = frozenset(dict(w.functions).keys()) if w is not None else frozenset()
        check_program(prog, functions=names)
        if w is not None:
            _check_with_world(prog, w)
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
@click.option("--stall-steps", type=click.IntRange(min=0), default=20, show_default=True,
              help="stop, as stalled (exit 1), when no variable, position or flag has changed "
                   "for this many time steps while agents still run (0: never)")
@click.option("--max-memory", "max_memory", metavar="SIZE", default=None,
              callback=lambda c, p, v: _size(v),
              help="stop (as a bound) when the process's memory passes SIZE, e.g. 800M or 4G "
                   "[default: 80% of physical memory]")
@click.option("--trace", is_flag=True, help="print every transition")
@click.option("--format", "fmt", type=Choice(["text", "json", "k"]), default="text",
              show_default=True,
              help="k: the final configuration as a K configuration, as explore --format k")
@_EXIT_CODES
@click.option("--plot", type=click.Path(dir_okay=False), default=None,
              help="draw the arena and trajectories to this PNG (needs matplotlib)")
@click.option("--html", type=click.Path(dir_okay=False), default=None,
              help="write a self-contained HTML viewer of the path to this file")
@click.option("--trace-out", type=click.Path(dir_okay=False), default=None,
              help="write the run as a trace file (JSON, docs/trace-format.md) for pccl replay")
@click.option("--invariant", "invariants", multiple=True, metavar="EXPR",
              help="a state property checked after every transition; the run stops at "
                   "the first state that violates it (repeatable)")
@click.option("--property", "properties", multiple=True, metavar="FORM",
              help="a property of any form, checked on this run: P; 'P ~> Q within T' "
                   "(violated when T passes after P without Q); 'eventually P', 'P ~> Q' "
                   "(decided when the run ends for good, else undecided); 'reachable P' "
                   "(witnessed or not in this run) (repeatable; docs/temporal.md)")
@view_options
@watch_option
def run(program, agents, world, blackbox, delta, n0, rates, events, semantics, skip_events, collisions,
        overrides, seed,
        max_time, max_steps, stall_steps, max_memory, invariants, properties, trace, fmt,
        exit_codes, plot, html, trace_out, view, full, watch):
    """Execute PROGRAM once, choosing among enabled transitions with a seeded generator."""
    from pccl.model.options import RunOptions
    import random
    from pccl.api import build_model, memory_bound
    from pccl.tools.runner import run as run_model
    from pccl.output import traces as T
    _check_outputs(plot, trace_out, html)
    record = bool(trace or plot or trace_out or fmt == "json" or view or html)
    _check_repeats(rates, overrides)
    opts = RunOptions.from_cli(click.get_current_context().params).replace(record_trace=record)
    try:
        rng = random.Random(seed)
        model = build_model(program, opts, rng=rng)
        _check_watch(model, watch, html)
        res = run_model(model, seed=seed, max_steps=max_steps, record_trace=record, rng=rng,
                        stall_steps=stall_steps, max_memory=memory_bound(opts.max_memory),
                        spelling=cli_spelling)
        res.model = model
    except PcclError as e:
        _fail(e)
    m = res.model
    from pccl.output.checked import for_run
    checked = for_run(m, res, opts, cli_spelling)
    doc = None
    if record:
        cfg = T.config("run", m, program=program)
        doc = T.run_document(res, cfg)
    if fmt == "json":
        _print_run_json(program, seed, res, checked, doc, exit_codes)
    else:
        _print_run_text(program, seed, res, checked, fmt, view, full, trace)
    _write_run_files(res, doc, trace_out, plot, html, quiet=(fmt == "json"), watch=watch)
    sys.exit(_exit_status(res.exit_status, [v.kind for v in res.violations] + [res.status],
                          exit_codes))


def _check_outputs(plot, trace_out, html) -> None:
    """Step of run and explore: the output files given can be written."""
    if plot:
        _check_plot_output(plot)
    if trace_out:
        _check_output(trace_out, "--trace-out")
    if html:
        _check_output(html, "--html")


def _print_run_json(program, seed, res, checked, doc, exit_codes) -> None:
    """Step of run: the result as JSON (--format json)."""
    from pccl.model.layout import AGS, POS
    import json
    m = res.model
    from pccl.output.codec import encode_state, output
    out = output(
        "run", status=res.status, message=res.message,
        exit_status=_exit_status(res.exit_status,
                                 [v.kind for v in res.violations] + [res.status],
                                 exit_codes),
        program=program, blackbox=m.blackbox.name, agents=m.N, seed=seed,
        delta=m.delta, n0=m.n0, rates=list(m.rho), steps=res.steps,
        summary=[{"time": t, "positions": [list(ag[POS]) for ag in s[AGS]]}
                 for t, s in res.summary],
        final=encode_state(m, res.final),
        properties=[{"name": o.name, "kind": o.kind, "outcome": o.outcome,
                     "detail": o.detail} for o in res.properties],
        checked=checked.to_json(), trace=doc)
    click.echo(json.dumps(out, indent=2, default=str))


def _print_run_text(program, seed, res, checked, fmt, view, full, trace) -> None:
    """Step of run: the result as text."""
    from pccl.model.layout import TIME
    from pccl.output import display as D
    from pccl.output.checked import NO_PROPERTY_NOTE
    m = res.model
    click.echo(f"pccl run {program}: {m.N} agents, blackbox {m.blackbox.name}, "
               f"δ={D.fmt_time(m.delta)}, n0={m.n0}{_rates_text(m)}, seed {seed}")
    if view:
        from pccl.output import views
        click.echo(views.render(view, m, _run_path(res), full=full))
    elif trace:
        click.echo("trace:")
        for st in _run_path(res).steps:
            click.echo(D.format_step(m, st.number, st.label, st.before, st.after))
    from pccl.output.views import time_steps
    click.echo("time steps:")
    for _, ln in time_steps(m, res.summary):
        click.echo(ln)
    mem = (f", peak memory {res.peak_memory / 2**20:,.1f} MiB"
           if res.status == "out-of-memory" or res.message.startswith("stopped at --max-memory")
           else "")
    click.echo(f"result: {res.status} — {res.message} "
               f"(t={D.fmt_time(res.final[TIME])}, {res.steps} transitions{mem})")
    for v in res.violations:
        if v.span is not None:
            click.echo(f"  at {m.program.filename}:{v.span.line}:{v.span.column}: "
                       f"{D.source_line(m, v.span)}")
    if res.properties:
        click.echo("properties on this run:")
        for o in res.properties:
            click.echo(f"  {o.name}: {o.outcome} — {o.detail}")
    for note in checked.notes:
        if note != NO_PROPERTY_NOTE:       # a run is one execution, not a proof
            click.echo(f"note: {note}")
    click.echo("final configuration:")
    click.echo(D.format_state_k(m, res.final) if fmt == "k" else D.format_state(m, res.final))


def _write_run_files(res, doc, trace_out, plot, html, *, quiet: bool, watch=()) -> None:
    """Step of run: the trace file, the plot and the viewer asked for (none
    of a run out of memory, whose trace was dropped)."""
    m = res.model
    if trace_out and res.status == "out-of-memory":     # its trace was dropped
        click.echo(f"pccl: the run ran out of memory and its trace was dropped: nothing "
                   f"written to {trace_out}", err=True)
    elif trace_out:
        _write_trace(doc, trace_out, quiet=quiet)
    if plot:
        _plot_run(m, res, plot, quiet=quiet)
    if html and res.status == "out-of-memory":
        click.echo(f"pccl: the run ran out of memory and its trace was dropped: nothing "
                   f"written to {html}", err=True)
    elif html:
        _write_html(html, doc, model=m, path=_run_path(res), quiet=quiet, watch=watch)


def _run_path(res):
    """A run's path (its recorded trace, else its last state alone)."""
    from pccl.search.explorer import Trace
    return res.trace if res.trace is not None else Trace((res.final,), ())


def _check_with_world(prog, world) -> None:
    """What run and explore check of a program with its world before the
    first step: the world's function values against the types the program
    reads them as (errors at the world file's line), the team and its start
    positions (the world file's checks: inside the arena, off obstacles and
    apart), the initial state."""
    from pccl.model.engine import Model
    from pccl.model.options import RunOptions
    model = Model(prog, RunOptions(world=world, blackbox="instant"))
    next(iter(model.init_states()), None)


def _stdout_is_terminal() -> bool:
    """Whether stdout is a terminal (replay then shows the steps by default)."""
    try:
        return sys.stdout.isatty()
    except (AttributeError, ValueError):
        return False


def _check_output(path, option):
    try:
        check_writable(path, option)
    except PcclError as e:
        _fail(e)


def _write_trace(doc, path, *, quiet=False):
    from pccl.output import traces as T
    try:
        T.write(doc, path)
    except PcclError as e:      # the verdict stands: report, keep its exit status
        click.echo(_render(e), err=True)
        return
    click.echo(f"trace written to {path}", err=quiet)


def _rates_text(m) -> str:
    """The agents whose rate ρ is not 1, for the header line ("" when none)."""
    odd = [f"{i}={r}" for i, r in enumerate(m.rho) if r != 1]
    return f", rates {' '.join(odd)}" if odd else ""


def _plot_module():
    import importlib
    try:
        plot = importlib.import_module("pccl.output.plot")
    except ImportError as e:  # matplotlib missing
        from pccl.lang.errors import install_hint
        click.echo(f"pccl: --plot needs matplotlib: {install_hint('plot')} ({e})", err=True)
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
        click.echo(_render(e), err=True)
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
@click.option("--workers", metavar="N|auto", default=None,
              callback=lambda c, p, v: _workers(v),
              help="search with N processes (auto: one per usable core), or N threads "
                   "of one process for a native search without temporal properties, "
                   "--fastest, --coverage, checkpoints or --spill; results are identical for every N [default: 1; with "
                   "--ray: auto, one actor per CPU of the Ray cluster]")
@click.option("--ray", "ray", metavar="ADDRESS|local", default=None,
              help="run the workers as Ray actors: on the cluster at ADDRESS (HOST:PORT, "
                   "auto), or on a Ray instance started on this machine (local); needs "
                   "the ray extra (pip install -e '.[ray]' in the pccl checkout)")
@click.option("--max-memory", "max_memory", metavar="SIZE", default=None, callback=lambda c, p, v: _size(v),
              help="stop (as a bound) when the process's memory passes SIZE, e.g. 800M or 4G "
                   "[default: 80% of physical memory]")
@click.option("--abstract-time/--no-abstract-time", default=None,
              help="leave the clock out of state identity [default: on when sound and no --max-time]")
@click.option("--invariant", "invariants", multiple=True, metavar="EXPR",
              help="a state property to check, e.g. 'count(inCs) <= 1' (repeatable)")
@click.option("--property", "properties", multiple=True, metavar="FORM",
              help="a property of any form: P, 'eventually P', 'P ~> Q', 'P ~> Q within T', "
                   "'reachable P'; 'forall i:' in front makes one per agent, e.g. "
                   "'forall i: want[i] ~> has[i]' (repeatable; docs/temporal.md)")
@click.option("--no-timelock", "timelock", flag_value=False, default=True,
              help="do not report time-locks (states from which time can never advance again "
                   "while an agent has not exited)")
@click.option("--no-stall", "stall", flag_value=False, default=True,
              help="do not report stalls (states from which the team can only let time pass: "
                   "no variable, position or flag can change again, while an agent has not "
                   "exited)")
@click.option("--fastest", is_flag=True,
              help="report the counterexample that reaches its violation at the smallest "
                   "global time (ties: fewest transitions) instead of the shortest")
@click.option("--no-shorten", "shorten", flag_value=False, default=True,
              help="show the counterexample the reduced search found, without searching "
                   "the unreduced semantics for a shorter one (docs/reductions.md)")
@click.option("--reduce", "reduce", metavar="auto|none|LIST", default="auto", show_default=True,
              help="state-space reductions: auto (every sound one), none, or a "
                   "comma-separated list of merge, symmetry, por, dead, counters")
@click.option("--engine", type=Choice(["auto", "native", "python"]), default="auto",
              show_default=True,
              help="successors in generated C (native, compiled with the system cc) or in "
                   "Python; auto: native where it can serve the program and the search")
@click.option("--no-deadlock", "deadlock", flag_value=False, default=True,
              help="do not report deadlocks")
@click.option("--all", "find_all", is_flag=True,
              help="keep exploring and report each distinct violation once")
@click.option("--exact", is_flag=True,
              help="store canonical state encodings instead of 128-bit fingerprints (more memory, no collisions)")
@click.option("--format", "fmt", type=Choice(["text", "json", "k"]), default="text",
              show_default=True)
@_EXIT_CODES
@click.option("--plot", type=click.Path(dir_okay=False), default=None,
              help="draw the counterexample's trajectories to this PNG (needs matplotlib)")
@click.option("--progress/--no-progress", default=None,
              help="progress on stderr: a live line on a terminal, else a timestamped line "
                   "every --progress-interval seconds [default: live on a terminal; otherwise "
                   "plain lines once the search has run that long]")
@click.option("--progress-interval", type=FiniteFloat(min=0, min_open=True), default=10.0,
              show_default=True, metavar="SECONDS",
              help="seconds between plain progress lines (when stderr is not a terminal)")
@click.option("--html", type=click.Path(dir_okay=False), default=None,
              help="write a self-contained HTML viewer of the path to this file")
@click.option("--trace-out", type=click.Path(dir_okay=False), default=None,
              help="write the first counterexample as a trace file (JSON, docs/trace-format.md)")
@view_options
@watch_option
@click.option("--coverage", is_flag=True,
              help="report how often each event's guard held and it fired, and statements "
                   "never executed")
@click.option("--checkpoint", "checkpoint", metavar="DIR", default=None,
              help="write the search's state to DIR every --checkpoint-interval and when "
                   "interrupted (Ctrl-C, SIGTERM); --resume DIR continues it")
@click.option("--checkpoint-interval", "checkpoint_interval", metavar="DURATION",
              default="30m", show_default=True, callback=lambda c, p, v: _interval(v),
              help="time between checkpoints: 90s, 10m, 1h (0: at every level)")
@click.option("--resume", "resume", metavar="DIR", default=None,
              help="continue the search from the checkpoint in DIR (same program and "
                   "options; it keeps writing checkpoints there)")
@click.option("--spill", "spill", metavar="DIR", default=None,
              help="when the search's memory nears --max-memory, move the visited states "
                   "and the frontier to files under DIR instead of stopping (one process; "
                   "the files are removed at the end)")
def explore(program, agents, world, blackbox, delta, n0, rates, events, semantics, skip_events,
            collisions, overrides, depth,
            max_time, max_states, max_memory, abstract_time, invariants, properties, timelock,
            stall, shorten, fastest, reduce, engine, deadlock, find_all, exact, fmt, exit_codes, plot,
            progress, progress_interval, html, trace_out, view, full, coverage, workers, ray,
            checkpoint, checkpoint_interval, resume, spill, watch):
    """Explore every interleaving of PROGRAM breadth-first and report the first
    violation with a shortest counterexample."""
    from pccl.model.options import ExploreOptions, conflict
    import json
    from pccl.api import build_model, explore_model
    from pccl.output import traces as T
    from pccl.search.spill import SpillError
    _check_outputs(plot, trace_out, html)
    if ray is not None:
        from pccl.api import require_ray
        try:
            require_ray()
        except PcclError as e:
            _fail(e)
    _check_repeats(rates, overrides)
    opts = ExploreOptions.from_cli(click.get_current_context().params)
    try:
        model = build_model(program, opts, explore=True)
        if coverage:
            model = model.with_uses(("coverage",))
        _check_watch(model, watch, html)
        c = conflict(opts)
        if c is not None:
            raise PcclError(c.message(cli_spelling), filename=flag(c.option))
    except PcclError as e:
        _fail(e)
    reporter = _progress_printer(_explore_header(program, model), progress, progress_interval)
    try:
        res = explore_model(model, options=opts.replace(
            progress=reporter, progress_interval=min(0.5, progress_interval)), spelling=cli_spelling)
    except (PcclError, SpillError) as e:   # found only while exploring (a blackbox, a world
        if reporter is not None:            # value, a full disk with --spill, ...)
            reporter.close()    # erase the live display before the message
        _fail(e if isinstance(e, PcclError) else PcclError(str(e), filename=e.option, template=True))
    finally:
        if reporter is not None:
            reporter.close()
    cfg = T.config("explore", model, program=program)
    doc = T.explore_document(res, cfg)
    if fmt == "json":
        out = _explore_json(program, res)
        out["exit_status"] = _exit_status(res.exit_status, [v.kind for v in res.violations],
                                          exit_codes)
        out["trace"] = doc
        if res.coverage is not None:
            out["coverage"] = res.coverage.as_dict()
        click.echo(json.dumps(out, indent=2, default=str))
    else:
        _print_explore_text(program, res, k_style=(fmt == "k"), view=view, full=full)
    _write_explore_files(model, res, doc, trace_out, plot, html, quiet=(fmt == "json"), watch=watch)
    if res.status == "interrupted" and (checkpoint or resume):
        _resume_hint(res, checkpoint or resume)
    sys.exit(_exit_status(res.exit_status, [v.kind for v in res.violations], exit_codes))


def _write_explore_files(model, res, doc, trace_out, plot, html, *, quiet: bool, watch=()) -> None:
    """Step of explore: the trace file, the plot and the viewer asked for
    (the plot and the viewer only of a counterexample)."""
    if trace_out:
        _write_trace(doc, trace_out, quiet=quiet)
    if plot and res.violations:
        try:
            _plot_module().plot_trace(model, res.counterexamples[0].trace, plot,
                                      title=res.violations[0].message)
            click.echo(f"plot written to {plot}", err=quiet)
        except PcclError as e:  # the violation stands: report, keep exit status 1
            click.echo(_render(e), err=True)
    elif plot:
        click.echo(f"pccl: no counterexample, so no plot written to {plot}", err=True)
    if html and doc["initial"] is not None:
        _write_html(html, doc, model=model, path=_explore_path(res), quiet=quiet, watch=watch)
    elif html:
        click.echo(f"pccl: no counterexample, so no viewer written to {html}", err=True)


def _resume_hint(res, directory) -> None:
    """After an interrupted search with --checkpoint: where the checkpoint
    is and the command that resumes it (on stderr)."""
    import shlex
    if not any(n.startswith("checkpoint written to") for n in res.notes):
        click.echo("pccl: interrupted before the first level was complete: no checkpoint "
                   "written", err=True)
        return
    args = sys.argv[1:]
    if "explore" in args:
        args = args[args.index("explore") + 1:]
    keep, skip = [], False
    for a in args:
        if skip:
            skip = False
            continue
        if a in ("--checkpoint", "--resume"):
            skip = True
            continue
        if a.startswith(("--checkpoint=", "--resume=")):
            continue
        keep.append(a)
    cmd = shlex.join(["pccl", "explore", *keep, "--resume", str(directory)])
    click.echo(f"pccl: checkpoint written to {directory}; resume with: {cmd}", err=True)


@main.command(short_help="Re-execute a trace file; report the first divergence.",
              epilog="Exit status: 0 a clean run or a witness reproduced (or nothing to "
                     "replay), 1 a violation reproduced, 2 the trace diverges, its verdict "
                     "cannot be reproduced by a trace (unreachable), or bad input "
                     "(docs/trace-format.md).")
@click.argument("trace_file", metavar="FILE", type=click.Path(dir_okay=False))
@click.option("--blackbox", "-b", default=None, metavar="MODULE:ATTR",
              help="the user blackbox the trace was recorded with (it must be the one the "
                   "file names); replay never imports a module named in the file itself")
@click.option("--program", "program_file", type=click.Path(dir_okay=False), default=None,
              help="replay against this program instead of the recorded one (its hash is "
                   "compared with the recorded one)")
@click.option("--world", "world_file", type=click.Path(dir_okay=False), default=None,
              help="replay against this world file instead of the recorded one")
@view_options
@click.option("--plot", type=click.Path(dir_okay=False), default=None,
              help="draw the replayed trajectories to this PNG (needs matplotlib)")
@click.option("--html", type=click.Path(dir_okay=False), default=None,
              help="write a self-contained HTML viewer of the trace to this file")
@click.option("--format", "fmt", type=Choice(["text", "json"]), default="text",
              show_default=True,
              help="json: the verdict and the replayed trace, in the vocabulary of run and "
                   "explore (docs/trace-format.md)")
def replay(trace_file, blackbox, program_file, world_file, view, full, plot, html, fmt):
    """Re-execute the trace FILE (written by --trace-out) through the interpreter:
    check the file, rebuild the model from the recorded configuration, start
    from the recorded initial state, check that every recorded step is enabled
    and makes the recorded changes, and re-derive the recorded end.  The program
    and world are found by the recorded path, the path relative to FILE or the
    absolute path (the one with the recorded hash); --program/--world override.
    On a terminal the steps are shown (--view steps) unless --view says otherwise."""
    from pccl.output import display as D
    import json
    from pccl.tools.replay import replay as do_replay
    if plot:
        _check_plot_output(plot)
    if html:
        _check_output(html, "--html")
    if view is None and _stdout_is_terminal() and fmt == "text":
        view = "steps"
    try:
        res = do_replay(trace_file, blackbox=blackbox, program=program_file, world=world_file, spelling=cli_spelling)
    except PcclError as e:
        _fail(e)
    cfg = res.doc["config"]
    m = res.model
    if fmt == "json":
        from pccl.output.codec import output
        from pccl.tools.replay import replayed_document
        click.echo(json.dumps(output(
            "replay", status=res.status, message=res.message, exit_status=res.exit_status,
            trace=replayed_document(res),
            **{"file": str(trace_file), "recorded_version": res.doc["version"],
               "recorded_command": cfg["command"], "steps_replayed": len(res.labels),
               "steps_total": res.steps_total, "diverged_at": res.diverged_at,
               "warnings": list(res.warnings)}), indent=2, default=str))
        sys.exit(res.exit_status)
    click.echo(f"pccl replay {trace_file}: {cfg['command']} of {cfg['program']['path']}, "
               f"{m.N} agents, blackbox {m.blackbox.name}, δ={D.fmt_time(m.delta)}, "
               f"n0={m.n0}{_rates_text(m)}" + (f", seed {cfg['seed']}" if "seed" in cfg else ""))
    for w in res.warnings:
        click.echo(w)
    if view and res.states:
        from pccl.output import views
        click.echo(views.render(view, m, res.trace, full=full))
    click.echo(f"replayed {len(res.labels)} of {res.steps_total} steps")
    click.echo(res.message)
    if plot and res.states:
        try:
            _plot_module().plot_trace(m, res.trace, plot, title=res.message)
            click.echo(f"plot written to {plot}")
        except PcclError as e:
            click.echo(_render(e), err=True)
    if html and res.doc.get("initial") is not None:
        notes = [res.message] if res.status == "diverged" else []
        page_model, page_path = m, res.trace
        if program_file is None:
            # a page is shared: it shows a program the trace merely names only
            # when its bytes are the recorded ones (--program: the user's choice)
            from pccl.tools.replay import recorded_file
            found, why = recorded_file(cfg.get("program"), trace_file)
            if found is None:
                page_model, page_path = None, None
                notes.append(f"source not shown: {why}")
                click.echo(f"pccl replay: the viewer shows no source: {why}", err=True)
        _write_html(html, res.doc, model=page_model, path=page_path, notes=notes)
    elif html:
        click.echo(f"pccl: nothing to replay, so no viewer written to {html}", err=True)
    sys.exit(res.exit_status)


def _write_html(out, doc, *, model=None, path=None, world=None, notes=(), quiet=False,
                source_file=None, embed_paths=False, watch=()):
    """Write the HTML viewer of ``doc`` to ``out``; the path's states
    (pending computations) and labels (the CLI's text of its steps) are kept
    only when they are the document's whole path."""
    from pccl.output import viewer
    states = labels = None
    if path is not None and len(path.states) == len(doc["steps"]) + 1:
        states, labels = list(path.states), list(path.labels)
    try:
        viewer.write(out, doc, model=model, states=states, labels=labels, world=world,
                     notes=list(notes), source_file=source_file, embed_paths=embed_paths,
                     watch=watch if states is not None else ())
    except PcclError as e:      # the verdict stands: report, keep its exit status
        click.echo(_render(e), err=True)
        return
    click.echo(f"viewer written to {out}", err=quiet)


def _explore_path(res):
    """The path explore_document records (None: no path)."""
    if res.counterexamples:
        return res.counterexamples[0].trace
    if res.witnesses:
        return res.witnesses[0]["_trace"]
    return None


@main.command(short_help="Write the HTML viewer of a trace file.",
              epilog="Exit status: 0 written, 2 bad input (docs/tools.md#viewer).")
@click.argument("trace_file", metavar="TRACE", type=click.Path(dir_okay=False))
@click.option("--output", "-o", type=click.Path(dir_okay=False), required=True,
              help="the HTML file to write")
@click.option("--blackbox", "-b", default=None, metavar="MODULE:ATTR",
              help="the user blackbox the trace was recorded with, to replay it (as for replay)")
@click.option("--embed-paths", is_flag=True,
              help="keep the absolute paths of the program and world in the page (left out "
                   "by default: a page is made to be shared)")
@watch_option
def view(trace_file, output, blackbox, embed_paths, watch):
    """Write a self-contained HTML viewer of the trace file TRACE (written by
    --trace-out): the arena or timeline, swimlane, state inspector and source,
    animated step by step.  The program (and world) are used only when a file
    with the recorded sha256 is found (as replay finds it: the recorded path,
    the path relative to TRACE, the absolute path); then the trace is replayed
    (to show every agent's pending computation exactly) and its source shown.
    Otherwise the trace is shown as recorded, without source, with a note
    saying why (also on stderr): a trace from elsewhere may name any file."""
    from pccl.output import tracecheck as TC
    from pccl.tools.replay import recorded_file, replay as do_replay
    _check_output(output, "--output")
    try:
        doc = TC.load(trace_file)
    except PcclError as e:
        _fail(e)
    notes: list = []
    model, path, world, source = None, None, None, None
    cfg = doc.get("config") or {}
    prog, why = recorded_file(cfg.get("program"), trace_file)
    wfile, wwhy = (recorded_file(cfg["world"], trace_file) if cfg.get("world")
                   else (None, ""))
    if wfile is not None:
        world = _world_of(wfile)
    if prog is None:
        notes.append(f"source not shown and the trace not replayed: {why}")
    elif cfg.get("world") and wfile is None:
        source = prog
        notes.append(f"not replayed (the world: {wwhy}): shown as recorded")
    else:
        source = prog
        try:
            res = do_replay(trace_file, blackbox=blackbox, program=prog, world=wfile,
                            spelling=cli_spelling)
            model, path = res.model, res.trace
            if res.status == "diverged":
                notes.append(f"the trace does not replay: {res.message}")
        except PcclError as e:
            notes.append(f"not replayed ({e.respell(cli_spelling).message}): shown as recorded")
    if model is not None:
        try:
            _check_watch(model, watch, output)
        except PcclError as e:
            _fail(e)
    elif watch:
        notes.append("--watch not evaluated: the trace was not replayed")
    for note in notes:
        click.echo(f"pccl view: {note}", err=True)
    if doc["initial"] is None:
        notes.append("the trace holds no path")
    _write_html(output, doc, model=model, path=path, world=world, notes=notes,
                source_file=source, embed_paths=embed_paths, watch=watch)


@main.command(short_help="Interactive explorer in the browser (127.0.0.1).",
              epilog="Exit status: 0 stopped (Ctrl-C), 2 bad input (docs/tools.md#serve).")
@click.argument("program", type=click.Path(dir_okay=False))
@common_options
@click.option("--max-time", type=FiniteFloat(min=0), default=None,
              help="stop time from advancing past this (as explore)")
@click.option("--invariant", "invariants", multiple=True, metavar="EXPR",
              help="an invariant to check in every state shown (repeatable)")
@click.option("--abstract-time/--no-abstract-time", default=None,
              help="as explore: time abstraction (default: on when the program never reads time)")
@click.option("--port", type=click.IntRange(min=0, max=65535), default=0,
              help="the port on 127.0.0.1 [default: a free one]")
@click.option("--max-memory", "max_memory", metavar="SIZE", default=None, callback=lambda c, p, v: _size(v),
              help="stop a search from the page (as a bound) when the process's memory passes "
                   "SIZE, e.g. 800M [default: 80% of physical memory, as explore]")
@click.option("--search-seconds", type=FiniteFloat(min=0), default=60.0, show_default=True,
              help="stop a search from the page after this many seconds")
def serve(program, agents, world, blackbox, delta, n0, rates, events, semantics, skip_events, collisions, overrides,
          max_time, invariants, abstract_time, port, max_memory, search_seconds):
    """Explore PROGRAM interactively in a browser: start from an initial state,
    see every enabled transition with its rule and source line, take one, go
    back, jump to a visited state, load a trace file, run a bounded search from
    the current state.  The model is explore's (same options), unreduced.  The
    server listens on 127.0.0.1 only and answers only the URL it prints (with
    its per-run token); stop it with Ctrl-C."""
    from pccl.model.options import ExploreOptions
    from pccl.api import build_model, default_max_memory
    from pccl.tools import serve as S
    from pccl.output import traces as T
    _check_repeats(rates, overrides)
    params = dict(click.get_current_context().params)
    params.pop("max_memory", None)
    params.pop("search_seconds", None)
    opts = ExploreOptions.from_cli(params).replace(reduce="none")
    try:
        model = build_model(program, opts, explore=True)
        cfg = T.config("explore", model, program=program)
        session = S.Session(model, cfg,
                            max_memory=default_max_memory() if max_memory is None else max_memory,
                            search_seconds=search_seconds or None)
    except PcclError as e:
        _fail(e)
    try:
        srv = S.make_server(session, port)
    except OSError as e:
        _fail(PcclError(f"cannot listen on 127.0.0.1:{port}: {e.strerror or e}", filename="--port"))
    click.echo(f"pccl serve {program}: {model.N} agents, blackbox {model.blackbox.name}; "
               f"open {S.url(srv)} (Ctrl-C stops)")
    try:
        srv.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        srv.server_close()
    sys.exit(0)


def _world_of(path):
    """The world file ``path`` (one with a trace's recorded sha256), when it
    can be read (else None)."""
    from pccl.lang.world import load_world
    try:
        return load_world(path)
    except (PcclError, OSError):
        return None


@main.command(short_help="Write the reachable state graph (DOT or JSON).", epilog=EXIT_STATUS_HELP)
@click.argument("program", type=click.Path(dir_okay=False))
@common_options
@click.option("--output", "-o", type=click.Path(dir_okay=False), required=True,
              help="FILE.dot (or .gv) for Graphviz, FILE.json for the data")
@click.option("--max-states", type=click.IntRange(min=1), default=10_000, show_default=True,
              help="stop adding states after this many")
@click.option("--max-time", type=FiniteFloat(min=0), default=None,
              help="global time bound (TIME ADVANCE fires only while time + δ ≤ T)")
@click.option("--invariant", "invariants", multiple=True, metavar="EXPR",
              help="a state property; violating states are marked (repeatable)")
@click.option("--no-deadlock", is_flag=True, help="do not mark deadlocks as violations")
def graph(program, agents, world, blackbox, delta, n0, rates, events, semantics, skip_events, collisions, overrides,
          output, max_states, max_time, invariants, no_deadlock):
    """Write the reachable state graph of PROGRAM, breadth-first up to --max-states
    states: states as nodes (violating ones in red), transitions as edges labelled
    with agent, rule, line and changes, one colour per agent."""
    from pccl.model.options import ModelOptions
    import os
    from pccl.api import build_model
    from pccl.output import graph as G
    from pccl.output import traces as T
    ext = os.path.splitext(output)[1].lower()
    if ext not in (".dot", ".gv", ".json"):
        _fail(PcclError(f"cannot tell the format of {output}: use a .dot, .gv or .json file",
                        filename="--output"))
    _check_output(output, "--output")
    _check_repeats(rates, overrides)
    # the graph is the unreduced semantics: every state and transition
    opts = ModelOptions.from_cli(click.get_current_context().params).replace(reduce="none")
    try:
        model = build_model(program, opts)
        g = G.build(model, max_states=max_states, deadlock=not no_deadlock)
        if g.out_of_memory:
            from pccl.search.memory import peak_rss_bytes
            click.echo(f"pccl graph {program}: out of memory after {len(g.states):,} states and "
                       f"{len(g.edges):,} transitions (peak memory "
                       f"{peak_rss_bytes() / 2**20:,.1f} MiB); nothing written to {output}: "
                       f"give a smaller --max-states", err=True)
            sys.exit(2)
        if ext == ".json":
            cfg = T.config("explore", model, program=program, deadlock=not no_deadlock)
            text = G.dumps(G.to_json(model, g, cfg, max_states))
        else:
            text = G.to_dot(model, g, name=os.path.basename(program))
        G.write(text, output)
    except PcclError as e:
        _fail(e)
    bad = len(g.violations)
    click.echo(f"pccl graph {program}: {len(g.states):,} states, {len(g.edges):,} transitions, "
               f"{bad} violating" + (f" (truncated at --max-states {max_states})" if g.truncated
                                     else " (complete)") + f"; written to {output}")
    sys.exit(1 if bad else 0)


#: steps of the first violating run that simulate prints without --trace
SIM_TAIL = 10


@main.command(short_help="Many seeded runs: outcome frequencies, times, reproducing commands.",
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
def simulate(program, agents, world, blackbox, delta, n0, rates, events, semantics, skip_events, collisions, overrides,
             runs, runs_n, seed, max_time, max_steps, stall_steps, invariants, properties,
             trace, trace_out, fmt):
    """Run PROGRAM many times (as pccl run, with seeds SEED, SEED+1, ...), checking
    the program's invariants and any --invariant/--property on every run, and count
    the outcomes: final, bounded, deadlock, stalled, max-steps and each violation, with
    their frequencies (95% confidence intervals), the times, the first violating run's
    trace, and the pccl run command that reproduces each outcome."""
    from pccl.model.options import RunOptions
    import random
    from pccl.tools import simulate as S
    from pccl.output import traces as T
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
                             semantics=semantics, skip_events=skip_events,
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
    from pccl.tools import simulate as S
    from pccl.output.codec import output
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


def _workers(value):
    if value is None:
        return None
    if value == "auto":
        return value            # the API resolves it: local cores, or the Ray cluster's CPUs
    try:
        n = int(value)
    except ValueError:
        raise click.BadParameter(f"expected a number of processes or 'auto', got {value!r}") from None
    if not 1 <= n <= 256:
        raise click.BadParameter(f"expected 1 to 256 processes, got {n}")
    return n


def _interval(value):
    from pccl.search.checkpoint import parse_interval
    try:
        return parse_interval(value)
    except ValueError as e:
        raise click.BadParameter(str(e)) from None


def _size(value):
    if value is None:
        return None
    from pccl.api import parse_size
    try:
        return parse_size(value)
    except ValueError as e:
        raise click.BadParameter(str(e)) from None


def _progress_printer(header: str, progress, interval: float, *, stream=None, tty=None):
    """The progress reporter for ``pccl explore`` (None for --no-progress).

    On a terminal: a live display on stderr (rich), the header line first and
    under it states, frontier, depth, rate, memory and elapsed time; it is
    erased when the search ends (the report repeats the header).  Otherwise
    (a file, a pipe, CI, nohup): plain timestamped lines every ``interval``
    seconds, never a carriage return; with --progress the header and the
    lines start at once, by default only once the search has run
    ``interval`` seconds."""
    stream = sys.stderr if stream is None else stream
    if tty is None:
        tty = stream.isatty()
    if progress is False:
        return None
    if tty:
        return _LiveProgress(header, stream)
    return _PlainProgress(header, stream, interval, start_after=0 if progress else interval)


def _progress_figures(p, rate) -> str:
    from pccl.output import display as D
    t = p.get("max_time")
    init = p.get("initial_candidates")
    return ((f"initial configurations generated {init:,}  " if init is not None else "")
            + f"states {p['states']:,}  frontier {p['frontier']:,}  depth {p['depth']}  "
            + (f"t {D.fmt_time(t)}  " if t is not None else "")
            + f"{rate:,.0f} states/s  mem {p['memory'] / 2**20:,.0f} MiB")


class _Rate:
    """States per second since the previous report (the average at first)."""

    def __init__(self):
        self.last = None

    def __call__(self, p) -> float:
        states, secs = p["states"], p["seconds"]
        if self.last is None or secs <= self.last[1]:
            rate = states / secs if secs > 0 else 0.0
        else:
            rate = (states - self.last[0]) / (secs - self.last[1])
        self.last = (states, secs)
        return rate


class _LiveProgress:
    def __init__(self, header, stream):
        from rich.console import Console
        from rich.live import Live
        from rich.text import Text
        self._text = Text
        self.header = header
        self.console = Console(file=stream, force_terminal=True, highlight=False,
                               soft_wrap=False)
        self.rate = _Rate()
        self.live = Live(self._render("exploring ..."), console=self.console, transient=True,
                         auto_refresh=False, redirect_stdout=False, redirect_stderr=False)
        self.live.start(refresh=True)

    def _render(self, line):
        from rich.console import Group
        return Group(self._text(self.header, overflow="ellipsis", no_wrap=True),
                     self._text(line, style="bold", overflow="ellipsis", no_wrap=True))

    def note(self, text):
        """A note (a zero-time runaway) above the live line, at once."""
        self.console.print(self._text(f"note: {text}"))

    def __call__(self, p):
        elapsed = _hms(p["seconds"])
        self.live.update(self._render(f"{elapsed}  {_progress_figures(p, self.rate(p))}"),
                         refresh=True)

    def close(self):
        self.live.stop()


class _PlainProgress:
    def __init__(self, header, stream, interval, start_after):
        self.header, self.stream = header, stream
        self.interval, self.start_after = interval, start_after
        self.next_line = start_after
        self.started = False
        self.rate = _Rate()
        if start_after <= 0:
            self._start()

    def _echo(self, text):
        import datetime
        now = datetime.datetime.now().strftime("%Y-%m-%d %H:%M:%S")
        self.stream.write(f"{now}  {text}\n")
        self.stream.flush()

    def _start(self):
        self.started = True
        self._echo(self.header)

    def note(self, text):
        """A note (a zero-time runaway), at once."""
        self._echo(f"note: {text}")

    def __call__(self, p):
        if p["seconds"] < self.next_line:
            return
        if not self.started:
            self._start()
        self.next_line = p["seconds"] + self.interval
        self._echo(_progress_figures(p, self.rate(p)))

    def close(self):
        pass


def _hms(seconds: float) -> str:
    s = int(seconds)
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"


def _stats_lines(res) -> list:
    from pccl.output import display as D
    s = res.stats
    on = res.model.reduction.on if res.model is not None else ()
    # counts of the reduced graph are not those of the rules (section 5)
    red = f" (reduced: {'+'.join(on)})" if on else ""
    lines = [f"  initial states   {s.initial_states:,}{red}",
             f"  states           {s.states:,}{red}",
             f"  transitions      {s.transitions:,}{red}",
             f"  max depth        {s.max_depth}"]
    if s.max_time is not None:
        lines.append(f"  max time         {D.fmt_time(s.max_time)}")
    lines += [f"  seconds          {s.seconds:.2f}",
              f"  states/second    {s.states_per_second:,.0f}",
              f"  peak memory      {s.peak_memory / 2**20:,.1f} MiB"]
    if res.search is not None and res.search.exact:
        lines.append("  state identity   exact (canonical encodings; no collision possible)")
    else:
        lines.append(f"  fingerprints     128-bit xxh3 of a canonical encoding; "
                     f"collision probability ≤ {res.collision_probability:.1e}")
    return lines


def _explore_header(program, m) -> str:
    """The first line of ``pccl explore``: program, agents, blackbox (and why
    it was chosen, when by default), options."""
    from pccl.output import display as D
    reason = getattr(m, "blackbox_reason", None)
    why = f" ({reason})" if reason else ""
    from pccl.api import not_covered_note
    uncovered = not_covered_note(m, cli_spelling)
    if uncovered:
        why += f", {uncovered}"
    return (f"pccl explore {program}: {m.N} agents, blackbox {m.blackbox.name}{why}, "
            f"δ={D.fmt_time(m.delta)}, n0={m.n0}{_rates_text(m)}, events {m.events_policy}, "
            f"time abstraction {'on' if m.abstract_time else 'off'}, "
            f"reductions {m.reduction.describe(cli_spelling)}{_engine_text(m)}")


def _engine_text(m) -> str:
    """The header's engine: named when the native engine ran, when an engine
    was asked for (``--engine``), and under ``--engine auto`` when Python runs
    because the native engine cannot, with the reason."""
    used = getattr(m, "engine_used", None)
    why = getattr(m, "engine_reason", None)
    if used is None or (used == "python" and why is None
                        and not getattr(m, "engine_asked", False)):
        return ""
    threads = getattr(m, "engine_threads", 1)
    cost = PYTHON_COST if used == "python" and why and not getattr(m, "engine_asked", False) \
        else ""
    narrow = getattr(m, "engine_threads_note", None) if threads > 1 else None
    on = f" on 1 thread of {threads} ({narrow})" if narrow else \
        f" on {threads} threads" if threads > 1 else ""
    return f", engine {used}{on}" + (f" ({cost}{why})" if why else "")


#: What falling back to the Python engine costs, said in the header (the
#: shipped programs: 1,800-3,600 states/s against 130,000-280,000 natively,
#: measured 2026-12-07 for issue 43).
PYTHON_COST = "about 50x slower than the native engine, because "


def _print_explore_text(program, res, *, k_style=False, view=None, full=False):
    from pccl.output import display as D
    m = res.model
    click.echo(_explore_header(program, m))
    click.echo(res.verdict)
    for v, cx in zip(res.violations, res.counterexamples):
        _print_counterexample(res, v, cx, k_style=k_style, view=view, full=full)
    for w in res.witnesses:
        click.echo("")
        click.echo(f"reachable: `{w['text']}` is reached; witness ({len(w['_trace'])} steps):")
        for st in w["_trace"].steps:
            click.echo(D.format_step(m, st.number, st.label, st.before, st.after))
        click.echo("witness state:")
        click.echo(D.format_state(m, w["_trace"].last))
    if res.notes:
        click.echo("")
        for note in res.notes:
            click.echo(f"note: {note}")
    # what the verdict covers; it says which properties hold
    for ln in res.checked.lines():
        click.echo(ln)
    click.echo("statistics:")
    for ln in _stats_lines(res):
        click.echo(ln)
    if res.coverage is not None:
        for ln in res.coverage.lines():
            click.echo(ln)


def _print_counterexample(res, v, cx, *, k_style=False, view=None, full=False) -> None:
    """Step of :func:`_print_explore_text`: violation ``v`` and its
    counterexample ``cx``."""
    from pccl.model.layout import TIME
    from pccl.output import display as D
    m = res.model
    click.echo("")
    click.echo(v.message)
    if v.line:
        click.echo(f"  at {m.program.filename}:{v.line}:{v.column}")
    tr = cx.trace
    if tr is None:          # reachable P: unreachable has no path to show
        return
    note = _shortest_note(m, cx, tr)
    if res.search is not None and getattr(res.search, "fastest", False):
        note += f", fastest: violation at t={D.fmt_time(tr.last[TIME])}"
    loop = cx.cycle_start
    if loop is not None:
        click.echo(f"counterexample (a lasso: {_steps(loop)}, then a cycle of "
                   f"{_steps(len(tr) - loop)} repeated forever{note}):")
    else:
        click.echo(f"counterexample ({_steps(len(tr))}{note}):")
    if view:
        from pccl.output import views
        click.echo(views.render(view, m, tr, full=full))
    else:
        for st in tr.steps:
            if loop is not None and st.number == loop + 1:
                click.echo("  -- cycle: the steps below repeat forever --")
            click.echo(D.format_step(m, st.number, st.label, st.before, st.after))
        if loop is not None:
            click.echo(f"  -- back to the state after step {loop} --")
    click.echo("state at the end of the cycle (= its start):" if loop is not None
               else "violating state:")
    if k_style:
        click.echo(D.format_state_k(m, tr.last))
    else:
        click.echo(D.format_state(m, tr.last))


def _shortest_note(m, cx, tr) -> str:
    """What the counterexample's header says of its length: under
    reductions, whether shortening against the unreduced semantics
    (pccl/model/shorten.py) showed it shortest, shortened it, or could not."""
    if not m.reduction.on:
        return ""
    sh = getattr(cx, "shortening", None)
    lasso = cx.cycle_start is not None
    if sh is not None and sh.status == "shortened":
        note = (f", {'as short as without the reductions' if lasso else 'shortest'}: "
                f"the reduced search's had {_steps(sh.reduced_steps)}")
    elif sh is not None and sh.status == "confirmed":
        note = ", as short as without the reductions" if lasso else ", shortest"
    else:
        note = ", shortest under the reductions"
        if sh is not None and sh.status == "off":
            note += f"; not compared with the unreduced graph ({cli_spelling('shorten', 'False')})"
        elif sh is not None:
            note += f"; not shown to be shortest: {sh.reason or 'not tried'}"
    depth = getattr(cx, "depth", None)
    if depth is not None and depth != len(tr) and not lasso:
        # --depth counts transitions of the reduced graph, the steps shown
        # are the rules' (expanded): say both, so --depth can be read here
        note += f"; depth {depth} in the reduced graph, as --depth counts"
    return note


def _steps(n: int) -> str:
    return f"{n} step" + ("" if n == 1 else "s")


def _explore_json(program, res) -> dict:
    from pccl.output.codec import output
    from pccl.output.results import path_json
    m = res.model
    return output(
        "explore", status=res.status, message=res.verdict, exit_status=res.exit_status,
        **{"exhaustive": res.exhaustive,
           "program": program, "blackbox": res.blackbox, "agents": m.N,
            "delta": m.delta, "n0": m.n0, "rates": list(m.rho),
            "bounds": res.bound_labels, "time_abstraction": m.abstract_time,
            "reductions": m.reduction.as_dict(cli_spelling),
            "statistics": {**res.stats.as_dict(), "reduced": bool(m.reduction.on)},
            "collision_probability": res.collision_probability,
            "fingerprints": "exact" if res.search.exact else "xxh3_128",
            "violations": [v.to_json() for v in res.violations],
            "witnesses": [{"name": w["name"], "text": w["text"], "depth": w["depth"],
                           "trace": path_json(w["initial"], w["trace"], w["state"])}
                          for w in res.witnesses],
            "holds": res.holds, "notes": res.notes, "timelock_check": res.timelock,
            "not_covered": res.not_covered,
            # "pymunk: a second leg ...", "straight/pymunk: positions ..."
            "not_exhaustive_for": (res.not_covered.removeprefix("not exhaustive for ")
                                   if res.not_covered else None),
            "stall_check": res.stall,
            "checked": res.checked.to_json()})


@main.command(name="fmt", short_help="Format programs in the canonical layout.")
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=False, allow_dash=True))
@click.option("--check", is_flag=True,
              help="write nothing; exit 1 if a file would change (for CI)")
@click.option("--diff", "show_diff", is_flag=True,
              help="write nothing; print the changes as a unified diff, exit 1 if any")
def fmt_cmd(files, check, show_diff):
    """Rewrite each PROGRAM in the canonical layout (docs/editors.md):
    indentation, spacing and blank lines only; comments and line structure
    are kept, and the program's meaning never changes.  `-` reads standard
    input and writes the result to standard output."""
    import difflib

    from pccl.tools.fmt import FormatterBug, format_source
    changed = []
    for path in files:
        try:
            if path == "-":
                source = sys.stdin.read()
            else:
                try:
                    with open(path, encoding="utf-8-sig", newline="") as fh:
                        source = fh.read()
                except (OSError, UnicodeDecodeError) as e:
                    raise PcclError(f"cannot read '{path}': {getattr(e, 'strerror', None) or e}",
                                    filename=path) from None
            out = format_source(source, "<stdin>" if path == "-" else path)
        except PcclError as e:
            _fail(e)
        except FormatterBug as e:
            click.echo(f"pccl fmt: internal error, file left as it is: {e}", err=True)
            sys.exit(2)
        if path == "-" and not (check or show_diff):
            click.echo(out, nl=False)
            continue
        if out == source:
            continue
        changed.append(path)
        if show_diff:
            click.echo("".join(difflib.unified_diff(source.splitlines(True), out.splitlines(True),
                                                    path, path + " (formatted)")), nl=False)
        elif check:
            click.echo(f"would reformat {path}")
        else:
            with open(path, "w", encoding="utf-8", newline="") as fh:
                fh.write(out)
            click.echo(f"reformatted {path}")
    if (check or show_diff) and changed:
        sys.exit(1)


@main.command(short_help="Language server for editors (LSP over stdio).")
def lsp():
    """Run the PCCL language server on standard input and output: diagnostics,
    hover, definitions, references, symbols, completion, formatting
    (docs/editors.md).  Needs the `lsp` extra: pip install -e '.[lsp]' in the pccl
    checkout."""
    try:
        import lsprotocol  # noqa: F401
        import pygls  # noqa: F401
    except ImportError as e:
        from pccl.lang.errors import install_hint
        click.echo(f"pccl lsp: error: {e.name or 'pygls'} is not installed; "
                   f"{install_hint('lsp')}", err=True)
        sys.exit(2)
    from pccl.tools.lsp import serve
    serve()


@main.command(name="cache", short_help="The native engine's module cache: size, bound, --clear.")
@click.option("--clear", is_flag=True, help="remove every compiled module of the cache")
@click.option("--format", "fmt", type=Choice(["text", "json"]), default="text",
              show_default=True)
def cache_cmd(clear, fmt):
    """Show the native engine's module cache (--engine native compiles one
    module per program into $PCCL_CACHE or ~/.cache/pccl): its directory,
    how many modules it holds, their size and the bound ($PCCL_CACHE_SIZE,
    default 100M; 0: none), beyond which the least recently used modules
    are removed after a new one is compiled.  --clear removes them all
    (docs/benchmarks.md#the-module-cache)."""
    import json
    import os
    from pccl.model import native_build as NV
    from pccl.search.memory import format_size
    try:
        bound = NV.cache_bound()
    except PcclError as e:
        _fail(e)
    d = NV.cache_dir()
    removed = NV.clear_cache(d) if clear and os.path.isdir(d) else (0, 0)
    mods = NV.cache_modules(d)
    size = sum(m[1] for m in mods)
    if fmt == "json":
        click.echo(json.dumps({"directory": d, "modules": len(mods), "bytes": size,
                               "bound_bytes": bound, "removed": removed[0],
                               "removed_bytes": removed[1]}, indent=2))
        return
    if clear:
        click.echo(f"removed {removed[0]:,} modules ({format_size(removed[1])})")
    click.echo(f"directory  {d}")
    click.echo(f"modules    {len(mods):,} ({format_size(size)})")
    click.echo(f"bound      {format_size(bound) if bound is not None else 'none'} "
               f"(${NV.CACHE_SIZE_ENV})")


if __name__ == "__main__":  # pragma: no cover
    main()
