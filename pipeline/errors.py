"""Errors the CLI reports in one line instead of a traceback.

A :class:`UserError` (bad input, bad config, missing file) exits with code 2, a
:class:`SimulationError` (physics left the plausible range) with code 1; anything else is
a bug and keeps its traceback.
"""


class UserError(Exception):
    """A problem with the user's input, stated in one line that names what to fix."""


class SimulationError(RuntimeError):
    """The simulation left the physically plausible range; the trial is not usable."""


class RunAborted(UserError):
    """A condition that stops a whole run (not one trial): its unwritten trials stay pending."""
