"""Issue 48: one version number (pccl/__init__.py, which pyproject.toml reads),
``pccl --version`` saying what ran; issue 43 item 4: the start-up of
``pccl --version`` and ``pccl check`` imports no engine (timings are in
benchmarks/startup.py, not here)."""

from __future__ import annotations

import importlib.metadata
import json
import os
import platform
import re
import subprocess
import sys
import tomllib

import pytest
from click.testing import CliRunner

import pccl
from pccl.cli import main
from pccl.tools import about

from conftest import RACE, ROOT

#: Modules that the --version and check paths must not import (the engines,
#: numpy, the extras): each costs start-up time a quick command does not need.
HEAVY = ("numpy", "xxhash", "shapely", "rich", "psutil", "pygments", "matplotlib", "pymunk", "ray",
         "pygls", "pccl.api", "pccl.model.engine", "pccl.model.native", "pccl.search.explorer",
         "pccl.semantics.rules")


def test_one_source_of_the_version():
    """pyproject.toml reads the number from pccl/__init__.py; the installed
    metadata (written from it at install) and CHANGELOG.md's newest release agree."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in project["project"] and "version" in project["project"]["dynamic"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "pccl.__version__"}
    assert re.fullmatch(r"\d+\.\d+\.\d+", pccl.__version__)
    assert importlib.metadata.version("pccl") == pccl.__version__
    changelog = (ROOT / "CHANGELOG.md").read_text()
    released = re.findall(r"^## \[(\d+\.\d+\.\d+)\]", changelog, re.M)
    assert released[0] == pccl.__version__


def test_version_says_what_ran():
    res = CliRunner().invoke(main, ["--version"])
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert lines[0] == f"pccl {pccl.__version__}"
    assert ("native engine available" in lines[1]) == (about.native_unavailable() is None)
    if about.native_unavailable() is None:
        assert about.compiler() in lines[1]
    extras = lines[2]
    import importlib.util
    for extra, mod in about.EXTRAS:
        state = "installed" if importlib.util.find_spec(mod) is not None else "not installed"
        assert f"{mod} ({extra}) {state}" in extras
    assert lines[3].startswith(f"Python {platform.python_version()} ")
    assert lines[4] == f"platform: {platform.system()} {platform.release()} {platform.machine()}"


def test_version_without_a_compiler_or_extras(tmp_path):
    """No C compiler on the PATH, an extra missing (pymunk hidden): the lines
    say so."""
    code = ("import sys\nsys.modules['pymunk'] = None\nsys.argv = ['pccl', '--version']\n"
            "from pccl.cli import main\nmain()\n")
    env = {**os.environ, "CC": "no-such-cc", "PATH": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         timeout=60)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[1] == ("native engine unavailable (no C compiler (cc) found): "
                        "searches run the Python engine")
    assert "pymunk (physics) not installed" in lines[2]


def test_the_engine_agrees_that_no_compiler_means_no_native_engine(monkeypatch):
    """What --version says is what the engine decides (one function)."""
    from pccl.api import make_model
    from pccl.model import native
    monkeypatch.setenv("CC", "no-such-cc")
    monkeypatch.setenv("PATH", "/nonexistent")
    assert native.unsupported(make_model(RACE)) == "no C compiler (cc) found" == about.native_unavailable()


def _imported(args: list[str]) -> set[str]:
    code = (f"import sys\nsys.argv = ['pccl', *{args!r}]\nimport pccl.cli\n"
            "try:\n    pccl.cli.main()\nexcept SystemExit:\n    pass\n"
            "import json\nprint(json.dumps(sorted(sys.modules)), file=sys.stderr)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    return set(json.loads(out.stderr.splitlines()[-1]))


#: The command modules of pccl/cli/ other than check's (pccl.cli.cmd_run): the
#: group imports a command's module when the command is looked up.
OTHER_COMMANDS = ("pccl.cli.cmd_explore", "pccl.cli.cmd_traces", "pccl.cli.cmd_simulate",
                  "pccl.cli.cmd_utility")


@pytest.mark.parametrize("args", [["--version"], ["check", RACE]], ids=["version", "check"])
def test_quick_commands_import_no_engine(args):
    """The start-up of `pccl --version` and `pccl check` (issue 43, item 4):
    no numpy, no engine, no extra, no other command's module; --version not
    even the parser or a command's module, check of a PCCL file no Koord
    front end and (without --world) no world reader."""
    mods = _imported(args)
    assert "pccl.cli" in mods
    assert not {m for m in mods if m.split(".")[0] in HEAVY or m in HEAVY}
    assert not mods & set(OTHER_COMMANDS)
    if args == ["--version"]:
        assert "lark" not in mods and "pccl.lang.ast" not in mods
        assert not {m for m in mods if m.startswith("pccl.cli.")}
    else:
        assert "lark" in mods and "pccl.lang.checker" in mods
        assert not mods & {"pccl.lang.koord", "pccl.lang.koordfun", "pccl.lang.world"}


def test_check_with_a_world_or_a_koord_file_still_imports_their_readers(tmp_path):
    """The laziness above does not lose the readers where they are needed."""
    mods = _imported(["check", RACE, "--world", str(ROOT / "programs" / "race.toml")])
    assert "pccl.lang.world" in mods and "pccl.lang.koord" not in mods
    koord = tmp_path / "add.koord"
    koord.write_text((ROOT / "programs" / "koord" / "add_numbers.koord").read_text())
    assert "pccl.lang.koord" in _imported(["check", str(koord)])


def test_import_of_the_cli_alone_is_light():
    """`import pccl.cli` (what the console script does first) imports no
    command's module, no option and not the language's errors."""
    code = "import sys, pccl.cli; print(sorted(m for m in sys.modules if m.startswith('pccl')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert eval(out.stdout) == ["pccl", "pccl.cli"]


def test_the_lazy_group_knows_every_command():
    """Every command module's commands are in the group under the names
    they had when the modules were imported up front (the help lists them
    all), each looked up as the command object its module defines."""
    import importlib
    import click
    from pccl.cli import COMMANDS
    defined = {}
    for module in {m for m, _ in COMMANDS.values()}:
        for obj in vars(importlib.import_module(module)).values():
            if isinstance(obj, click.Command) and obj.callback.__module__ == module:
                defined[obj.name] = obj
    assert sorted(main.commands) == sorted(defined) == main.list_commands(None)
    for name, command in defined.items():
        assert main.commands[name] is command
    help_text = CliRunner().invoke(main, ["--help"]).output
    for name, command in defined.items():
        assert re.search(rf"^  {name} +{re.escape(command.short_help.split()[0])} ", help_text, re.M)
