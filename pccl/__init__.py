# pccl.semantics and pccl.blackboxes are the top-level folders semantics/ and
# blackboxes/ (pyproject.toml's package-dir).  The README's editable install
# (editable_mode=strict) reaches them through setuptools' link tree,
# build/__editable__.pccl-*/pccl/, which is on sys.path after the checkout
# when Python runs from the checkout: the pkgutil idiom below then adds the
# link tree's pccl/ to this package's path.  In a wheel, or without a link
# tree, there is one pccl/ folder and this changes nothing.
from pkgutil import extend_path

__path__ = extend_path(__path__, __name__)
