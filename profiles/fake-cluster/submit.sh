#!/usr/bin/env bash
# Fake `sbatch`: run the job script (last argument) locally in the background; print a job id.
# The job's exit status is stored in .fake-cluster/<id>.status for status.sh.
set -euo pipefail
jobscript="${@: -1}"
dir=.fake-cluster
mkdir -p "$dir"
id="fake$$_$RANDOM"
echo "$jobscript" > "$dir/$id.script"
( bash "$jobscript" > "$dir/$id.out" 2>&1; echo $? > "$dir/$id.rc" ) &
echo "$id"
