"""``pccl check`` and ``pccl run``: one program, type-checked or executed once."""

from __future__ import annotations

import sys

import click

from pccl.cli import EXIT_STATUS_HELP
from pccl.cli.files import (_check_outputs, _check_with_world, _plot_run, _rates_text, _run_path,
                            _write_html, _write_trace)
from pccl.cli.options import (_EXIT_CODES, Choice, FiniteFloat, _check_repeats,
                              _check_watch, _exit_status, _fail, _size, cli_spelling,
                              common_options, view_options, watch_option)
from pccl.lang.errors import PcclError


@click.command(short_help="Parse and type-check a program.")
@click.argument("program", type=click.Path(dir_okay=False))
@click.option("--world", "-w", type=click.Path(dir_okay=False), default=None,
              help="world file whose uninterpreted functions the program may use")
@click.option("--lang", type=Choice(["pccl", "koord"]), default=None,
              help="read the program as this language [default: koord for .koord/.krd "
                   "files, else pccl]")
def check(program, world, lang):
    """Parse and statically check PROGRAM; print nothing else on success."""
    # the front end only (not pccl.api, which imports the engines: start-up)
    from pccl.lang.checker import check_program
    from pccl.lang.files import parse_program_file
    try:
        prog = parse_program_file(program, lang)    # PCCL, or Koord (.koord, .krd, --lang)
        w = None
        if world is not None:
            from pccl.lang.world import load_world
            w = load_world(world)
        names = frozenset(dict(w.functions).keys()) if w is not None else frozenset()
        check_program(prog, functions=names)
        if w is not None:
            _check_with_world(prog, w)
    except PcclError as e:
        _fail(e)
    click.echo(f"{program}: ok ({len(prog.events)} events, {prog.n_statements} statements)")


@click.command(short_help="Execute a program once (seeded).", epilog=EXIT_STATUS_HELP)
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
def run(program, agents, world, blackbox, delta, n0, rates, events, lang, semantics, skip_events, collisions,
        overrides, seed,
        max_time, max_steps, stall_steps, max_memory, invariants, properties, trace, fmt,
        exit_codes, plot, html, trace_out, view, full, watch):
    """Execute PROGRAM once, choosing among enabled transitions with a seeded generator."""
    import random

    from pccl.api import build_model, memory_bound
    from pccl.model.options import RunOptions
    from pccl.output import traces as T
    from pccl.tools.runner import run as run_model
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

def _print_run_json(program, seed, res, checked, doc, exit_codes) -> None:
    """Step of run: the result as JSON (--format json)."""
    import json

    from pccl.model.layout import AGS, POS
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
