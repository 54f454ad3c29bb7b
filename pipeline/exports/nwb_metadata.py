"""Who and what an NWB export describes (``pipeline export nwb --metadata FILE`` and flags):
experimenter, institution, lab, session, keywords and subject, as DANDI and nwbinspector ask.

A YAML file, e.g.::

    experimenter: ["Doe, Jane", "Roe, Richard"]     # "Last, First"
    institution: University of Somewhere
    lab: Whisker Lab
    session_description: natural statistics of rock piles for the 2027 grant
    keywords: [touch, natural scenes]               # added to the export's own keywords
    subject:                                        # default: the simulated animal
      subject_id: model-rat                         # default: model-<animal of the morphology>
      species: Rattus norvegicus                    # default: the morphology's species
      sex: U
      age: P0D/

Resolution: the file < environment (``PIPELINE_NWB_*``) < flags. Fields not given keep the
export's defaults (a simulated session has no experimenter or institution unless given).
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

from pydantic import Field, field_validator

from pipeline.config.loader import load_config
from pipeline.config.physics import StrictModel

ENV_PREFIX = "PIPELINE_NWB_"


class SubjectMetadata(StrictModel):
    """The NWB subject; ``subject_id`` and ``species`` not given describe the simulated animal of
    the dataset's morphology (not an animal: the model rat or the model mouse)."""

    subject_id: Optional[str] = Field(None, min_length=1, description="no slashes (DANDI)")
    species: Optional[str] = Field(None, description="Latin binomial or NCBI taxonomy URL")
    sex: str = Field("U", pattern="^(M|F|U|O)$", description="M, F, U (unknown) or O (other)")
    age: str = Field("P0D/", description="ISO 8601 duration or range, e.g. P90D or P60D/P90D")
    strain: Optional[str] = None
    description: Optional[str] = None

    @field_validator("subject_id")
    @classmethod
    def _no_slash(cls, value: str | None) -> str | None:
        if value is not None and "/" in value:
            raise ValueError("must not contain '/' (DANDI names files after it)")
        return value


class NwbMetadata(StrictModel):
    """What an NWB export says about its session beyond the dataset (module docstring)."""

    experimenter: list[str] = Field(default_factory=list, description='people, "Last, First"')
    institution: Optional[str] = None
    lab: Optional[str] = None
    session_description: Optional[str] = Field(None, min_length=1)
    experiment_description: Optional[str] = Field(None, min_length=1)
    keywords: list[str] = Field(default_factory=list)
    subject: SubjectMetadata = SubjectMetadata()


def load_nwb_metadata(path: str | Path | None = None, overrides: dict | None = None) -> NwbMetadata:
    """The metadata of ``path`` (YAML, optional) < ``PIPELINE_NWB_*`` < ``overrides`` (flags;
    None = not given); a bad value is a UserError naming its source and field."""
    return load_config(NwbMetadata, path, env_prefix=ENV_PREFIX, overrides=overrides)[0]
