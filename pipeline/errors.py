"""Errors a user can fix (bad input, bad config, missing file).

The CLI prints them as one ``error: ...`` line and exits with code 2; anything else
is a bug and keeps its traceback.
"""


class UserError(Exception):
    """A problem with the user's input, stated in one line that names what to fix."""
