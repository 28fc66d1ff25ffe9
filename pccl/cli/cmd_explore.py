"""``pccl explore``: every interleaving; its progress display, its text and JSON reports."""

from __future__ import annotations

import sys

import click

from pccl.cli import EXIT_STATUS_HELP
from pccl.cli.files import _check_outputs, _explore_path, _plot_module, _rates_text, _write_html, _write_trace
from pccl.cli.options import (_EXIT_CODES, Choice, FiniteFloat, _check_repeats,
                              _check_watch, _exit_status, _fail, _interval, _render, _size,
                              _workers, cli_spelling, common_options, flag, view_options,
                              watch_option)
from pccl.lang.errors import PcclError


@click.command(short_help="Explore every interleaving; shortest counterexamples.",
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
def explore(program, agents, world, blackbox, delta, n0, rates, events, lang, semantics, skip_events,
            collisions, overrides, depth,
            max_time, max_states, max_memory, abstract_time, invariants, properties, timelock,
            stall, shorten, fastest, reduce, engine, deadlock, find_all, exact, fmt, exit_codes, plot,
            progress, progress_interval, html, trace_out, view, full, coverage, workers, ray,
            checkpoint, checkpoint_interval, resume, spill, watch):
    """Explore every interleaving of PROGRAM breadth-first and report the first
    violation with a shortest counterexample."""
    import json

    from pccl.api import build_model, explore_model
    from pccl.model.options import ExploreOptions, conflict
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


#: What falling back to the Python engine costs, said in the header: the
#: range of the ratios measured by ``benchmarks/native_programs.py`` on the
#: programs that fell back before issue 43, run both ways (docs/benchmarks.md,
#: "The programs that fell back before issue 43"; a test holds the two equal).
#: A program that still falls back is not measured natively, so the figure
#: is the cost where it was measured, not a promise for that program.
PYTHON_COST = ("11-36x slower than the native engine on the programs measured in docs/benchmarks.md, "
               "because ")


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
