"""The ``pccl`` command line: run, check and explore PCCL programs.

One module per command group (``cmd_run``: check, run; ``cmd_explore``;
``cmd_traces``: replay, view, serve, graph; ``cmd_simulate``; ``cmd_utility``:
fmt, lsp, cache), the shared options in :mod:`pccl.cli.options` and the
output files in :mod:`pccl.cli.files`; this module is the ``pccl`` group
(the entry point ``pccl.cli:main``)."""

from __future__ import annotations

import sys

import click

from pccl.cli.cmd_explore import _progress_printer, explore
from pccl.cli.cmd_run import check, run
from pccl.cli.cmd_simulate import simulate
from pccl.cli.cmd_traces import graph, replay, serve, view
from pccl.cli.cmd_utility import cache_cmd, fmt_cmd, lsp
from pccl.cli.options import EXIT_STATUS_HELP, FLAGS, _interrupted_status, _on_sigterm, _signal, cli_spelling, flag

__all__ = ["main", "FLAGS", "flag", "cli_spelling", "_progress_printer"]

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

for _command in (check, run, explore, replay, view, serve, graph, simulate, fmt_cmd, lsp, cache_cmd):
    main.add_command(_command)

if __name__ == "__main__":  # pragma: no cover
    main()
