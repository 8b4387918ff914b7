# SPDX-License-Identifier: GPL-3.0-or-later
"""Shared by the Snakemake workflow tests (test_workflow_snakemake.py, test_workflow_slurm.py):
three cases in a folder, running the workflow, and checking its outputs and summary."""
import json
import os
import re
import shutil
import subprocess
import sys

CLI = os.environ["FEMESHER_CLI"]
DATA = os.environ.get("FEMESHER_DATA_DIR", "")
SOURCE = os.environ.get("FEMESHER_SOURCE_DIR") or os.path.join(os.path.dirname(__file__), "..", "..")
WORKFLOW = os.path.join(SOURCE, "Resources", "Workflow")
IN_CI = os.environ.get("CI") == "true"
CASES = ["mickey", "phantom", "spheres_argmax"]
FORMATS = ["vtu", "inp"]


class Checker:
    def __init__(self):
        self.failures = []

    def __call__(self, cond, msg):
        print(("ok:   " if cond else "FAIL: ") + msg, flush=True)
        if not cond:
            self.failures.append(msg)
        return cond

    def finish(self):
        if self.failures:
            print("%d check(s) failed" % len(self.failures))
            sys.exit(1)
        print("all checks passed")
        sys.exit(0)


def need_tools(check, tools):
    """False (and a failure in CI, a skip outside) when a tool is missing."""
    missing = [t for t in tools if not shutil.which(t)]
    if missing:
        check(not IN_CI, "tools installed (Debian packages snakemake, slurm-wlm, munge): "
                         "missing %s" % missing)
        if not IN_CI:
            print("skipped outside CI: missing %s" % missing)
    return not missing


def make_cases(check, folder):
    """The three label maps of the test in `folder`; False when data is missing."""
    os.makedirs(folder, exist_ok=True)
    for n in ("mickey.nrrd", "spheres_argmax.nrrd"):
        src = os.path.join(DATA, n)
        if not os.path.exists(src):
            check(not IN_CI, "data file %s present" % src)
            return False
        shutil.copy(src, folder)
    subprocess.run([CLI, "phantom", os.path.join(folder, "phantom.nrrd")], check=True,
                   capture_output=True)
    return True


def snakemake(workdir, cases, outdir, *extra, env=None, timeout=1200):
    """Runs the workflow in `workdir`; femesher's folder first on PATH."""
    e = dict(os.environ, **(env or {}))
    e["PATH"] = os.path.dirname(CLI) + os.pathsep + e.get("PATH", "")
    args = ["snakemake", "-s", os.path.join(WORKFLOW, "Snakefile"), "--config",
            "cases=" + cases, "outdir=" + outdir, "formats=" + ",".join(FORMATS),
            "femesher=" + CLI, "threads=1", "min_mem_mb=1", *extra]
    print("$ " + " ".join(args), flush=True)
    return subprocess.run(args, cwd=workdir, capture_output=True, text=True, timeout=timeout,
                          env=e, stdin=subprocess.DEVNULL)


def job_resource(log, name="mem_mb"):
    """{case: resource `name`} of the mesh jobs in Snakemake's output."""
    jobs = {}
    for block in re.split(r"^\[[^\]]+\]$", log, flags=re.M):
        case = re.search(r"^\s+wildcards: case=(\S+)", block, re.M)
        value = re.search(r"^\s+resources: .*\b%s=(\d+)" % name, block, re.M)
        if re.search(r"^rule mesh:", block, re.M) and case and value:
            jobs[case.group(1)] = int(value.group(1))
    return jobs


def job_memory(log):
    """{case: mem_mb} of the mesh jobs in Snakemake's output."""
    return job_resource(log, "mem_mb")


def expected_request(folder, key="request_mem_mb"):
    """{case: the estimate's `key`}: `femesher mesh --memory-estimate --threads 1`."""
    out = {}
    for case in CASES:
        p = subprocess.run([CLI, "mesh", os.path.join(folder, case + ".nrrd"), "--threads", "1",
                            "--memory-estimate"], capture_output=True, text=True, check=True)
        out[case] = max(1, json.loads(p.stdout)[key])
    return out


def expected_memory(folder):
    """{case: MB}: `femesher mesh --memory-estimate --threads 1`'s request (min_mem_mb=1)."""
    return expected_request(folder, "request_mem_mb")


def check_outputs(check, outdir):
    """Every case's meshes (read by meshio), report and a summary listing the three as ok."""
    try:
        import meshio
    except ImportError:
        check(False, "python3-meshio is installed")
        return
    summary = os.path.join(outdir, "summary.json")
    if not check(os.path.exists(summary), "summary.json written"):
        return
    with open(summary) as f:
        s = {c["case"]: c for c in json.load(f)["cases"]}
    check(sorted(s) == CASES, "the summary lists the three cases: %s" % sorted(s))
    for case in CASES:
        c = s.get(case, {})
        check(c.get("status") in ("ok", "poor_elements") and c.get("exit_code") == 0,
              "%s: status %s, exit %s" % (case, c.get("status"), c.get("exit_code")))
        for fmt in FORMATS:
            path = os.path.join(outdir, case, case + "." + fmt)
            try:
                m = meshio.read(path)
                tets = sum(len(b.data) for b in m.cells if b.type == "tetra")
                check(tets == c.get("tets") and tets > 0,
                      "%s: meshio reads %s: %d tets, as the summary says" % (case, fmt, tets))
            except Exception as e:
                check(False, "%s: meshio reads %s (%s)" % (case, path, e))
    for name in ("summary.csv", "summary.html"):
        check(os.path.exists(os.path.join(outdir, name)), name + " written")
