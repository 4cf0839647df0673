#!/bin/bash
# SPDX-License-Identifier: Apache-2.0
# One task of a frame sequence on any farm scheduler: finds the task index and count in the
# scheduler's environment and hands them to levelforge as --task-index / --task-count (0-based).
#
#   farm-task.sh [levelforge arguments...]      e.g.
#   farm-task.sh run shot.json --frames 1-240 --jobs 2 --report-json reports/task.json
#
# Recognised (first match wins):
#   TASK_INDEX / TASK_COUNT                      explicit, 0-based (any scheduler, or by hand)
#   SGE_TASK_ID, SGE_TASK_FIRST, SGE_TASK_LAST, SGE_TASK_STEPSIZE   Grid Engine (qsub -t 1-N)
#   PBS_ARRAY_INDEX + TASK_COUNT                 PBS Pro (qsub -J 0-N)
#   LSB_JOBINDEX + TASK_COUNT                    LSF (bsub -J "name[1-N]"), 1-based
#   AWS_BATCH_JOB_ARRAY_INDEX + TASK_COUNT       AWS Batch, 0-based
# (Slurm needs no wrapper: levelforge reads SLURM_ARRAY_TASK_ID itself; see slurm-array.sbatch.)
# Tested by setting the variables by hand (tests/tools/TestCliFarm.cc).
set -euo pipefail

LEVELFORGE="${LEVELFORGE:-levelforge}"
index="" count=""
if [ -n "${TASK_INDEX:-}" ]; then
  index="$TASK_INDEX" count="${TASK_COUNT:?TASK_INDEX is set, TASK_COUNT is not}"
elif [ -n "${SGE_TASK_ID:-}" ] && [ "${SGE_TASK_ID}" != "undefined" ]; then
  first="${SGE_TASK_FIRST:-1}" last="${SGE_TASK_LAST:?}" step="${SGE_TASK_STEPSIZE:-1}"
  index=$(( (SGE_TASK_ID - first) / step )) count=$(( (last - first) / step + 1 ))
elif [ -n "${PBS_ARRAY_INDEX:-}" ]; then
  index="$PBS_ARRAY_INDEX" count="${TASK_COUNT:?set TASK_COUNT to the number of array tasks}"
elif [ -n "${LSB_JOBINDEX:-}" ] && [ "${LSB_JOBINDEX}" != "0" ]; then
  index=$(( LSB_JOBINDEX - 1 )) count="${TASK_COUNT:?set TASK_COUNT to the number of array tasks}"
elif [ -n "${AWS_BATCH_JOB_ARRAY_INDEX:-}" ]; then
  index="$AWS_BATCH_JOB_ARRAY_INDEX" count="${TASK_COUNT:?set TASK_COUNT to the array size}"
fi

if [ -n "$index" ]; then
  exec "$LEVELFORGE" "$@" --task-index "$index" --task-count "$count"
fi
exec "$LEVELFORGE" "$@"
