"""Names a user picks between on the command line (light: the CLI imports this at start-up)."""

from typing import Literal

FitMethod = Literal["optimizer", "grid"]        # least squares from a start, or the paper's grid search
ObjectiveName = Literal["msa", "trajectory"]    # paper eq. 4a/4b tip features, or the tracked points
