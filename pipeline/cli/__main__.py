"""``python -m pipeline.cli``: the console entry point."""

from pipeline.cli.boundary import main

main()
