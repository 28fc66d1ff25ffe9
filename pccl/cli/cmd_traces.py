"""``pccl replay``, ``view``, ``serve`` and ``graph``: trace files, the viewer and the state graph."""

from __future__ import annotations

import sys

import click

from pccl.cli import EXIT_STATUS_HELP
from pccl.cli.files import (_check_output, _check_plot_output, _plot_module, _rates_text,
                            _stdout_is_terminal, _world_of, _write_html)
from pccl.cli.options import (Choice, FiniteFloat, _check_repeats, _check_watch,
                              _fail, _render, _size, cli_spelling, common_options, view_options,
                              watch_option)
from pccl.lang.errors import PcclError


@click.command(short_help="Re-execute a trace file; report the first divergence.",
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
    import json

    from pccl.output import display as D
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

@click.command(short_help="Write the HTML viewer of a trace file.",
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
    from pccl.tools.replay import recorded_file
    from pccl.tools.replay import replay as do_replay
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


@click.command(short_help="Interactive explorer in the browser (127.0.0.1).",
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
def serve(program, agents, world, blackbox, delta, n0, rates, events, lang, semantics, skip_events,
          collisions, overrides,
          max_time, invariants, abstract_time, port, max_memory, search_seconds):
    """Explore PROGRAM interactively in a browser: start from an initial state,
    see every enabled transition with its rule and source line, take one, go
    back, jump to a visited state, load a trace file, run a bounded search from
    the current state.  The model is explore's (same options), unreduced.  The
    server listens on 127.0.0.1 only and answers only the URL it prints (with
    its per-run token); stop it with Ctrl-C."""
    from pccl.api import build_model, default_max_memory
    from pccl.model.options import ExploreOptions
    from pccl.output import traces as T
    from pccl.tools import serve as S
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

@click.command(short_help="Write the reachable state graph (DOT or JSON).", epilog=EXIT_STATUS_HELP)
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
def graph(program, agents, world, blackbox, delta, n0, rates, events, lang, semantics, skip_events,
          collisions, overrides,
          output, max_states, max_time, invariants, no_deadlock):
    """Write the reachable state graph of PROGRAM, breadth-first up to --max-states
    states: states as nodes (violating ones in red), transitions as edges labelled
    with agent, rule, line and changes, one colour per agent."""
    import os

    from pccl.api import build_model
    from pccl.model.options import ModelOptions
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
