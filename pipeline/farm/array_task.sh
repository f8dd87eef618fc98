#!/usr/bin/env bash
# One farm task = one manifest job. Any scheduler with array jobs can call this with the task index:
#   SLURM:    sbatch --array=0-$((N-1)) pipeline/farm/slurm.sbatch MANIFEST
#   Deadline: a Command Line job, frames 0..N-1, chunk size 1, arguments: MANIFEST <STARTFRAME>
#   OpenCue:  a layer with range 0-(N-1), command: array_task.sh MANIFEST #IFRAME#
# Exit codes pass through: 0 done, 2 bad input (do not retry), 1 internal error (worth a retry).
set -euo pipefail
manifest="$1"
index="${2:-${SLURM_ARRAY_TASK_ID:-}}"
if [ -z "$index" ]; then
  echo "usage: array_task.sh MANIFEST INDEX (or set SLURM_ARRAY_TASK_ID)" >&2
  exit 2
fi
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
report_dir="${USDGAZE_REPORT_DIR:-$(dirname "$manifest")/out/reports}"
mkdir -p "$report_dir"
exec "${PYTHON:-python3}" "$here/../batch.py" "$manifest" --task-index "$index" \
  --report "$report_dir/task_${index}.json"
