"""The ``pipeline`` command line: parse, call one library function, print. No logic here.

One module per command group registers its commands on :data:`pipeline.cli.app.app` when
imported; the order of the imports below is the order of ``pipeline --help``. A command imports
the library module it calls inside its body when that module loads numpy or a heavier library,
so that ``pipeline --help`` and a short trial start fast (tests/cli/test_startup.py); cheap modules
(configs, provenance) are imported at module top.
"""

from pipeline.cli import info, workflow, recordings, protocols, meshes, simulate, datasets, exports  # noqa: F401
from pipeline.cli import reports, diagnosis  # noqa: F401
from pipeline.cli.app import app
from pipeline.cli.boundary import main

__all__ = ["app", "main"]
