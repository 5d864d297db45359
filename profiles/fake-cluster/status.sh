#!/usr/bin/env bash
# Fake `squeue/sacct`: report running|success|failed for a job id given by submit.sh.
id="$1"
rc_file=".fake-cluster/$id.rc"
if [ ! -f "$rc_file" ]; then echo running; exit 0; fi
if [ "$(cat "$rc_file")" = "0" ]; then echo success; else echo failed; fi
