#!/usr/bin/env bash
# Fake `sbatch`: run the job script (last argument) locally in the background and print a job id.
# The job's exit status goes to .fake-cluster/<id>.rc (in the workflow's working directory) for status.sh.
set -euo pipefail
jobscript="${@: -1}"
dir=.fake-cluster
mkdir -p "$dir"
id="fake$$_$RANDOM"
echo "$jobscript" > "$dir/$id.script"
# detach completely: the submitting Snakemake reads our stdout until EOF
( bash "$jobscript" > "$dir/$id.out" 2>&1; echo $? > "$dir/$id.rc" ) < /dev/null > /dev/null 2>&1 &
echo "$id"
