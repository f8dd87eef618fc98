#!/usr/bin/env bash
# One farm task = one manifest shot: usdgaze batch MANIFEST --task-index INDEX.
# Any scheduler with array jobs can call this with the task index (or let usdgaze write the job files:
# usdgaze batch MANIFEST --emit deadline|opencue|slurm DIR).
# Exit codes pass through: 0 done or skipped (up to date), 2 bad input (do not retry), 1 internal error.
set -euo pipefail
# ${1:-}: under set -u a bare $1 ended a call without arguments with bash's "unbound variable" and
# exit 1, which a farm retries; a missing argument is bad input (2), said with the usage line.
manifest="${1:-}"
index="${2:-${SLURM_ARRAY_TASK_ID:-}}"
if [ -z "$manifest" ] || [ -z "$index" ]; then
  echo "usage: array_task.sh MANIFEST INDEX (or set SLURM_ARRAY_TASK_ID)" >&2
  exit 2
fi
exec "${USDGAZE:-usdgaze}" batch "$manifest" --task-index "$index"
