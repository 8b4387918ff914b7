#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""The Snakemake workflow through a real single-node Slurm (issue 16, item 4c): as root, this
script writes a slurm.conf for this machine in a temporary folder (free ports, its own state,
spool, logs and munge socket), starts munged, slurmctld and slurmd, waits for the node to be
idle, runs the workflow with the shipped Slurm profile (Resources/Workflow/profiles/slurm) on
three cases, checks the outputs and the summary, and that every mesh job went through Slurm
(the job-completion log slurmctld writes lists one COMPLETED job per case, with the memory the
workflow asked for; slurmctld's log allocated them). The daemons are stopped afterwards, also when
a check fails or the script is interrupted. With CI=true, missing packages, not being root or a
Slurm that does not start are failures, not skips."""
import atexit
import os
import re
import signal
import shutil
import socket
import subprocess
import tempfile
import time

from workflow_common import (IN_CI, WORKFLOW, CASES, Checker, check_outputs, expected_memory,
                             make_cases, need_tools, snakemake)

check = Checker()
TMP = tempfile.mkdtemp(prefix="workflow_slurm_", dir="/tmp")  # short paths: the munge socket
daemons = []


def stop_daemons():
    for name, proc in reversed(daemons):
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        print("stopped %s (exit %s)" % (name, proc.returncode), flush=True)
    daemons.clear()


atexit.register(stop_daemons)
signal.signal(signal.SIGTERM, lambda *_: (stop_daemons(), os._exit(1)))


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start(name, args, env):
    log = open(os.path.join(TMP, name + ".out"), "w")
    proc = subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT, env=env,
                            stdin=subprocess.DEVNULL, start_new_session=True)
    daemons.append((name, proc))
    return proc


def tail(path, n=30):
    try:
        with open(path) as f:
            return "".join(f.readlines()[-n:])
    except OSError:
        return "(no %s)" % path


def start_slurm():
    """munged, slurmctld, slurmd for this host; the environment that reaches them (SLURM_CONF)."""
    host = socket.gethostname().split(".")[0]
    key, sock = os.path.join(TMP, "munge.key"), os.path.join(TMP, "munge.sock")
    with open(key, "wb") as f:
        f.write(os.urandom(1024))
    os.chmod(key, 0o400)
    for d in ("state", "spool", "munge"):
        os.makedirs(os.path.join(TMP, d))
    os.chmod(os.path.join(TMP, "munge"), 0o700)
    env = dict(os.environ, SLURM_CONF=os.path.join(TMP, "slurm.conf"))
    start("munged", ["munged", "-F", "--force", "--key-file", key, "--socket", sock,
                     "--pid-file", os.path.join(TMP, "munge", "munged.pid"),
                     "--log-file", os.path.join(TMP, "munge", "munged.log"),
                     "--seed-file", os.path.join(TMP, "munge", "munged.seed")], env)
    memory = 4000
    conf = """ClusterName=femeshertest
SlurmctldHost={host}(127.0.0.1)
SlurmctldPort={p1}
SlurmdPort={p2}
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket={sock}
SlurmUser=root
SlurmdUser=root
StateSaveLocation={tmp}/state
SlurmdSpoolDir={tmp}/spool
SlurmctldPidFile={tmp}/slurmctld.pid
SlurmdPidFile={tmp}/slurmd.pid
SlurmctldLogFile={tmp}/slurmctld.log
SlurmdLogFile={tmp}/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc={tmp}/jobcomp.log
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
SlurmdParameters=config_overrides
ReturnToService=2
MinJobAge=600
MpiDefault=none
NodeName={host} NodeAddr=127.0.0.1 CPUs=2 RealMemory={memory} State=UNKNOWN
PartitionName=femesher Nodes={host} Default=YES MaxTime=INFINITE State=UP
""".format(host=host, p1=free_port(), p2=free_port(), sock=sock, tmp=TMP, memory=memory)
    with open(env["SLURM_CONF"], "w") as f:
        f.write(conf)
    for _ in range(100):
        if os.path.exists(sock):
            break
        time.sleep(0.1)
    if not check(os.path.exists(sock), "munged started (socket %s)" % sock):
        print(tail(os.path.join(TMP, "munged.out")) + tail(os.path.join(TMP, "munge", "munged.log")))
        return None
    start("slurmctld", ["slurmctld", "-D", "-c", "-f", env["SLURM_CONF"]], env)
    time.sleep(1)
    start("slurmd", ["slurmd", "-D", "-N", host, "-f", env["SLURM_CONF"]], env)
    state = ""
    deadline = time.time() + 90
    while time.time() < deadline:
        p = subprocess.run(["sinfo", "-h", "-N", "-o", "%T"], capture_output=True, text=True,
                           env=env)
        state = p.stdout.strip()
        if state == "idle":
            break
        if any(proc.poll() is not None for _, proc in daemons):
            break
        time.sleep(1)
    if not check(state == "idle", "the Slurm node is idle (sinfo: %r)" % state):
        for log in ("slurmctld.log", "slurmd.log", "slurmctld.out", "slurmd.out"):
            print("--- " + log + "\n" + tail(os.path.join(TMP, log)))
        return None
    return env


def main():
    if os.geteuid() != 0:
        check(not IN_CI, "runs as root (it starts munged, slurmctld and slurmd)")
        if not IN_CI:
            print("skipped outside CI: not root")
        return
    if not need_tools(check, ["snakemake", "munged", "slurmctld", "slurmd", "sbatch", "sinfo",
                              "scontrol"]):
        return
    if not make_cases(check, os.path.join(TMP, "in")):
        return
    env = start_slurm()
    if env is None:
        return
    profile = os.path.join(WORKFLOW, "profiles", "slurm")
    p = snakemake(TMP, "in", "cohort", "--profile", profile, env=env)
    print(p.stdout[-3000:] + p.stderr[-8000:])
    check(p.returncode == 0, "snakemake --profile slurm exits 0 (got %d)" % p.returncode)
    submitted = re.findall(r"Submitted job \d+ with external jobid '(\d+)'", p.stdout + p.stderr)
    check(len(submitted) == 3, "three jobs submitted to Slurm: %s" % submitted)
    check_outputs(check, os.path.join(TMP, "cohort"))
    # The job-completion log: one COMPLETED mesh job per case, with the memory asked for.
    comp = tail(os.path.join(TMP, "jobcomp.log"), 100)
    jobs = re.findall(r"JobId=(\d+) .*?Name=femesher-mesh-\S+ .*?JobState=(\S+)", comp)
    check(sorted(j for j, _ in jobs) == sorted(submitted) and
          all(s == "COMPLETED" for _, s in jobs),
          "Slurm's job-completion log lists the submitted jobs as COMPLETED: %s" % jobs)
    asked = sorted(expected_memory(os.path.join(TMP, "in")).values())
    # jobcomp/filetxt does not hold the memory; scontrol still knows the jobs (MinJobAge 600 s).
    mems = []
    for j in submitted:
        q = subprocess.run(["scontrol", "show", "job", "-o", j], capture_output=True, text=True,
                           env=env).stdout
        m = re.search(r"\bMinMemoryNode=(\d+)M", q) or re.search(r"\bmem=(\d+)M", q)
        mems.append(int(m.group(1)) if m else None)
    check(sorted(x for x in mems if x) == asked and None not in mems,
          "each Slurm job has the memory of its case's estimate: %s MB (expected %s)"
          % (mems, asked))
    allocated = re.findall(r"sched: Allocate JobId=(\d+)", tail(os.path.join(TMP, "slurmctld.log"), 2000))
    check(set(submitted) <= set(allocated), "slurmctld's log allocated every job")


try:
    main()
finally:
    stop_daemons()
if not check.failures:
    shutil.rmtree(TMP, ignore_errors=True)  # kept, with the daemons' logs, when a check failed
check.finish()
