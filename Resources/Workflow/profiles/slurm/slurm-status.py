#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Snakemake's --cluster-status for Slurm: prints running, success or failed for a job id.
`scontrol show job` knows a job until MinJobAge after it ends; `sacct` (when Slurm keeps
accounting) knows it afterwards. A job neither knows is reported failed: Snakemake then says so
instead of waiting for ever."""
import subprocess
import sys

job = sys.argv[1].split(";")[0].strip()
RUNNING = {"PENDING", "CONFIGURING", "RUNNING", "COMPLETING", "SUSPENDED", "REQUEUED", "RESIZING",
           "STAGE_OUT", "SIGNALING", "PREEMPTED"}


def answer(state):
    state = state.split()[0].rstrip("+") if state else ""
    if state == "COMPLETED":
        return "success"
    if state in RUNNING:
        return "running"
    return "failed" if state else None


state = None
p = subprocess.run(["scontrol", "show", "job", "-o", job], capture_output=True, text=True)
if p.returncode == 0:
    for field in p.stdout.split():
        if field.startswith("JobState="):
            state = answer(field.split("=", 1)[1])
if state is None:
    p = subprocess.run(["sacct", "-n", "-X", "-P", "-j", job, "-o", "State"],
                       capture_output=True, text=True)
    if p.returncode == 0 and p.stdout.strip():
        state = answer(p.stdout.strip().splitlines()[0])
print(state or "failed")
