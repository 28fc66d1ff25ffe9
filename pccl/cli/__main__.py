"""``python -m pccl.cli``: the ``pccl`` command."""

from pccl.cli import main

if __name__ == "__main__":
    main()
