#!/bin/sh
# Grade the K-th of N slices of a batch into $GRADES/shard-K (robolab grade --shard K/N).
#
# N is $SHARDS. K comes from the scheduler that started this copy:
#   Kubernetes Indexed Job  JOB_COMPLETION_INDEX, 0 .. completions-1   -> K = index + 1
#   Slurm job array         SLURM_ARRAY_TASK_ID, with sbatch --array=1-N -> K = task id
#   anything else           the first argument (GNU parallel: grade-shard.sh {} ::: 1 2 3)
# Further arguments go to robolab grade (--lab, --timeout, ...).
set -eu
N="${SHARDS:?set SHARDS to the number of slices N}"
if [ -n "${JOB_COMPLETION_INDEX:-}" ]; then
    K=$((JOB_COMPLETION_INDEX + 1))
elif [ -n "${SLURM_ARRAY_TASK_ID:-}" ]; then
    K=$SLURM_ARRAY_TASK_ID
elif [ $# -ge 1 ]; then
    K=$1
    shift
else
    echo "grade-shard.sh: no slice: set JOB_COMPLETION_INDEX or SLURM_ARRAY_TASK_ID, or give K" >&2
    exit 2
fi
SUBMISSIONS="${SUBMISSIONS:-/submissions}"
GRADES="${GRADES:-/grades}"
exec "${ROBOLAB:-robolab}" grade "$SUBMISSIONS"/*.ipynb --shard "$K/$N" \
    --out "$GRADES/shard-$K" -j "${JOBS:-1}" "$@"
