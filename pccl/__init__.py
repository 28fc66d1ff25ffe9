"""pccl: an interpreter and explicit-state model checker for PCCL.

``__version__`` is the one source of the version number: pyproject.toml reads
it (``[tool.setuptools.dynamic]``, without importing pccl) into the installed
metadata; ``pccl --version`` prints it (CHANGELOG.md, docs/decisions.md
"Versions")."""

__version__ = "0.9.0"

# pccl.semantics and pccl.blackboxes are the top-level folders semantics/ and
# blackboxes/ (pyproject.toml's package-dir).  The README's editable install
# (editable_mode=strict) reaches them through setuptools' link tree,
# build/__editable__.pccl-*/pccl/, which is on sys.path after the checkout
# when Python runs from the checkout: the search below (pkgutil.extend_path's,
# written out: importing pkgutil costs ~10 ms of every `pccl` command's
# start-up) then adds the link tree's pccl/ to this package's path.  In a
# wheel, or without a link tree, there is one pccl/ folder and this changes
# nothing.
import os as _os
import sys as _sys

__path__ = list(__path__) + [
    _d for _d in (_os.path.join(_p, __name__) for _p in _sys.path if isinstance(_p, str) and _p)
    if _d not in __path__ and _os.path.isdir(_d)]
