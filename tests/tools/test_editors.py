"""The VS Code extension (editors/vscode/) claims PCCL files and only the
world files the user opts into (issue 44.7: every ``*.toml`` was claimed, and
``pyproject.toml`` got "unknown key 'build-system'")."""

from __future__ import annotations

import fnmatch
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
VSCODE = ROOT / "editors" / "vscode"


def test_world_files_are_claimed_by_an_opt_in_pattern():
    js = (VSCODE / "extension.js").read_text()
    assert '"**/*.toml"' not in js and "worldFiles" in js
    pkg = json.loads((VSCODE / "package.json").read_text())
    setting = pkg["contributes"]["configuration"]["properties"]["pccl.worldFiles"]
    default = setting["default"]
    assert not any(fnmatch.fnmatch("pyproject.toml", p.replace("**/", "")) for p in default)
    assert any(fnmatch.fnmatch("race.world.toml", p.replace("**/", "")) for p in default)


def test_the_extension_declares_the_projects_license():
    pkg = json.loads((VSCODE / "package.json").read_text())
    assert pkg["license"] == "Apache-2.0"
