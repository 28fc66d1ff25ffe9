"""Issue 48: pccl is Apache-2.0, and every library it runs on has a license
compatible with that (docs/licenses.md lists the runtime ones; this test
holds that list equal to what the installed distributions' metadata say).

The licenses come from ``importlib.metadata``: a distribution's
``License-Expression`` (PEP 639, SPDX), else its ``License`` field when that
is a short name, else its ``License ::`` classifiers.  A dependency whose
license this test cannot read, or reads as something outside the allow-list,
fails it: a new dependency is reviewed, not waved through."""

from __future__ import annotations

import importlib.metadata as md
import re
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parents[2]

#: Licenses under which a library may be a dependency of Apache-2.0 code
#: (permissive ones, and MPL-2.0's file-level copyleft, which binds only
#: changes to the library's own files).  SPDX identifiers, plus ``BSD`` for a
#: classifier that does not say which BSD license (every BSD variant is
#: compatible).
ALLOWED = {"Apache-2.0", "MIT", "MIT-0", "MIT-CMU", "BSD", "BSD-2-Clause", "BSD-3-Clause",
           "0BSD", "ISC", "PSF-2.0", "Python-2.0", "MPL-2.0", "Zlib", "CC0-1.0", "HPND",
           "Unlicense"}

#: Spellings met in ``License`` fields and classifiers, as SPDX identifiers.
SPELLINGS = {
    "mit": "MIT", "mit license": "MIT", "the mit license": "MIT",
    "bsd": "BSD", "bsd license": "BSD", "new bsd license": "BSD-3-Clause",
    "bsd-2-clause": "BSD-2-Clause", "bsd 2-clause": "BSD-2-Clause",
    "bsd-3-clause": "BSD-3-Clause", "bsd 3-clause": "BSD-3-Clause",
    "3-clause bsd license": "BSD-3-Clause", "bsd 3-clause license": "BSD-3-Clause",
    "apache 2.0": "Apache-2.0", "apache-2.0": "Apache-2.0", "apache license 2.0": "Apache-2.0",
    "apache software license": "Apache-2.0", "apache license, version 2.0": "Apache-2.0",
    "apache 2": "Apache-2.0",
    "python software foundation license": "PSF-2.0", "psf": "PSF-2.0", "psf-2.0": "PSF-2.0",
    "mozilla public license 2.0 (mpl 2.0)": "MPL-2.0", "mpl-2.0": "MPL-2.0", "mpl 2.0": "MPL-2.0",
    "isc license (iscl)": "ISC", "isc": "ISC", "isc license": "ISC",
    "mit-cmu": "MIT-CMU", "historical permission notice and disclaimer (hpnd)": "HPND",
    "the unlicense (unlicense)": "Unlicense",
}


def _spdx(text: str) -> str:
    return SPELLINGS.get(text.strip().lower(), text.strip())


def license_of(dist: md.Distribution) -> list[str]:
    """The licenses of ``dist`` as SPDX identifiers: every one it is under at
    once (``A AND B``: all of them; ``A OR B``: the first allowed one)."""
    meta = dist.metadata
    expr = meta.get("License-Expression")
    if expr:
        return _expression(expr)
    field = (meta.get("License") or "").strip()
    if field and "\n" not in field and len(field) <= 40 and field.upper() != "UNKNOWN":
        return _expression(field) if re.search(r"\b(AND|OR)\b", field) else [_spdx(field)]
    found = [_spdx(c.rsplit("::", 1)[1]) for c in meta.get_all("Classifier") or []
             if c.startswith("License ::") and c.count("::") >= 2]
    return found[:1] or ["(none declared)"]


def _expression(expr: str) -> list[str]:
    out = []
    for conj in re.split(r"\s+AND\s+", expr.replace("(", "").replace(")", "")):
        alts = [_spdx(a) for a in re.split(r"\s+OR\s+", conj)]
        out.append(next((a for a in alts if a in ALLOWED), alts[0]))
    return out


def closure(requirements: list[str], extra: str = "") -> dict[str, md.Distribution]:
    """The installed distributions ``requirements`` need, transitively (the
    markers evaluated for this interpreter; ``extra``: that extra's
    requirements too, at the first level)."""
    seen: dict[str, md.Distribution] = {}
    todo = [(r, extra) for r in requirements]
    while todo:
        text, ex = todo.pop()
        req = Requirement(text)
        if req.marker is not None and not req.marker.evaluate({"extra": ex}):
            continue
        name = canonicalize_name(req.name)
        if name in seen:
            continue
        try:
            dist = md.distribution(req.name)
        except md.PackageNotFoundError:
            continue                 # an optional dependency not installed here
        seen[name] = dist
        todo += [(r, e) for r in dist.requires or [] for e in ["", *sorted(req.extras)]]
    return seen


PCCL = md.distribution("pccl")
RUNTIME = closure([r for r in PCCL.requires or [] if "extra ==" not in r])
EXTRAS = ["plot", "physics", "ray", "lsp"]


def documented() -> dict[str, str]:
    """docs/licenses.md's table of runtime dependencies: name -> license."""
    text = (ROOT / "docs" / "licenses.md").read_text()
    table = text.split("<!-- runtime -->", 1)[1].split("<!-- /runtime -->", 1)[0]
    rows = [[c.strip() for c in line.strip().strip("|").split("|")]
            for line in table.splitlines() if line.startswith("|")]
    return {canonicalize_name(r[0].strip("`")): r[1] for r in rows[2:]}


def test_pccl_itself_is_apache_2():
    assert PCCL.metadata["License-Expression"] == "Apache-2.0"
    assert (ROOT / "LICENSE").read_text().split()[:4] == ["Apache", "License", "Version", "2.0,"]
    assert "LICENSE" in (PCCL.metadata.get_all("License-File") or [])


def test_every_runtime_dependency_has_an_allowed_license():
    assert {"lark", "numpy", "click", "shapely"} <= set(RUNTIME)
    bad = {n: license_of(d) for n, d in RUNTIME.items()
           if not set(license_of(d)) <= ALLOWED}
    assert not bad, f"licenses outside the allow-list (review, then list in docs/licenses.md): {bad}"


def test_every_installed_extra_has_an_allowed_license():
    """The extras that are installed here (the test extra installs them all),
    with what they pull in beyond the runtime dependencies."""
    checked = 0
    for extra in EXTRAS:
        reqs = [r for r in PCCL.requires or [] if f'extra == "{extra}"' in r]
        deps = closure(reqs, extra)
        for name, dist in deps.items():
            checked += 1
            assert set(license_of(dist)) <= ALLOWED, (extra, name, license_of(dist))
    assert checked >= 1


def test_the_documented_runtime_list_is_what_is_installed():
    doc = documented()
    assert set(doc) == set(RUNTIME), ("docs/licenses.md's runtime table names "
                                      f"{sorted(set(doc) ^ set(RUNTIME))} differently from the "
                                      "installed dependencies")
    for name, dist in RUNTIME.items():
        assert doc[name] == " AND ".join(license_of(dist)), name


def test_the_license_reader():
    """The reader itself, on the shapes the metadata come in."""
    assert _expression("BSD-3-Clause AND 0BSD AND MIT") == ["BSD-3-Clause", "0BSD", "MIT"]
    assert _expression("Apache-2.0 OR BSD-2-Clause") == ["Apache-2.0"]
    assert _expression("GPL-3.0-only OR MIT") == ["MIT"]
    assert _expression("GPL-3.0-only") == ["GPL-3.0-only"]
    assert not {"GPL-3.0-only", "AGPL-3.0", "(none declared)"} & ALLOWED
    assert _spdx("3-Clause BSD License") == "BSD-3-Clause"
    assert _spdx("Apache 2.0") == "Apache-2.0"
