# pccl.semantics and pccl.blackboxes live in the top-level semantics/ and
# blackboxes/ folders (pyproject.toml's package-dir).  In the editable install
# the README gives (editable_mode=strict), they are reached through setuptools'
# link tree build/__editable__.pccl-*/pccl/, which this line adds to the
# package's path when pccl itself is imported from the checkout (the current
# directory is first on sys.path there).  A wheel has one pccl folder, which
# this leaves alone.
__path__ = __import__("pkgutil").extend_path(__path__, __name__)
