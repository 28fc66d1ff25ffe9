"""What the commands write and check: output files (traces, plots, HTML viewers),
their paths, the world beside a program."""

from __future__ import annotations

import sys

import click

from pccl.cli.options import _fail, _render
from pccl.lang.errors import PcclError


def _check_outputs(plot, trace_out, html) -> None:
    """Step of run and explore: the output files given can be written."""
    if plot:
        _check_plot_output(plot)
    if trace_out:
        _check_output(trace_out, "--trace-out")
    if html:
        _check_output(html, "--html")

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

def _world_of(path):
    """The world file ``path`` (one with a trace's recorded sha256), when it
    can be read (else None)."""
    from pccl.lang.world import load_world
    try:
        return load_world(path)
    except (PcclError, OSError):
        return None
