"""``python -m pipeline``: the ``pipeline`` command line."""

from pipeline.cli import main

main()
