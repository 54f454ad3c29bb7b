#!/usr/bin/env bash
# Submit a sharded run: an array of SHARDS simulate tasks, then the join once all succeeded.
#   PIPELINE_HOME=/path/to/project DATASET=natural SHARDS=8 examples/slurm/submit.sh
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
export PIPELINE_HOME="${PIPELINE_HOME:?set PIPELINE_HOME to the project folder (the one holding configs/)}"
export DATASET="${DATASET:-natural}"
array=$(sbatch --parsable --export=ALL --array="1-${SHARDS:-8}" "$here/simulate_array.sbatch")
sbatch --parsable --export=ALL --dependency="afterok:${array%%;*}" "$here/join.sbatch"
