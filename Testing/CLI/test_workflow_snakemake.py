#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""The Snakemake workflow (Resources/Workflow/Snakefile, issue 16 items 3 and 4b) run locally with
--cores 2 on three cases (mickey, the phantom, spheres_argmax: a folder as input): one `mesh` job
per case with the memory of its estimate, the summary by `femesher batch --summarise-only`; every
mesh readable by meshio with the summary's tet count; a second run has nothing to do. Then a
broken case with --keep-going: listed as failed (exit code, error) in the summary the onerror
handler writes; after the repair a rerun lists it as ok. With
CI=true a missing snakemake is a failure."""
import json
import os
import re
import shutil
import tempfile

from workflow_common import (Checker, check_outputs, expected_memory, expected_request, job_memory,
                             job_resource, make_cases, need_tools, snakemake)

check = Checker()
TMP = tempfile.mkdtemp(prefix="workflow_local_", dir=os.environ.get("FEMESHER_TMP"))
if need_tools(check, ["snakemake"]) and make_cases(check, os.path.join(TMP, "in")):
    p = snakemake(TMP, "in", "cohort", "--cores", "2")
    print(p.stdout[-3000:] + p.stderr[-6000:])
    check(p.returncode == 0, "snakemake --cores 2 exits 0 (got %d)" % p.returncode)
    log = p.stdout + p.stderr
    check(len(re.findall(r"^rule mesh:", log, re.M)) == 3, "three mesh jobs ran")
    check(job_memory(log) == expected_memory(os.path.join(TMP, "in")),
          "each mesh job asks for the memory of its estimate: %s MB" % job_memory(log))
    runtimes = job_resource(log, "runtime")
    check(runtimes == expected_request(os.path.join(TMP, "in"), "request_runtime_min") and
          all(m >= 10 for m in runtimes.values()),
          "each mesh job asks for the minutes of its time estimate: %s" % runtimes)
    check_outputs(check, os.path.join(TMP, "cohort"))
    p = snakemake(TMP, "in", "cohort", "--cores", "2")
    check(p.returncode == 0 and "Nothing to be done" in p.stdout + p.stderr,
          "a second run has nothing to do")

    # A broken case with --keep-going: the good case is meshed, Snakemake exits non-zero, and the
    # summary (written by the workflow's onerror handler) lists the broken case with femesher's
    # exit code and its error. Once the file is repaired, a rerun meshes it and the summary says
    # ok (the failed run's record is gone).
    bad = os.path.join(TMP, "bad")
    os.makedirs(bad)
    shutil.copy(os.path.join(TMP, "in", "mickey.nrrd"), bad)
    with open(os.path.join(bad, "broken.nrrd"), "w") as f:
        f.write("NRRD0004\ntype: short\ndimension: 3\nsizes: 10 10\n")
    p = snakemake(TMP, "bad", "badcohort", "--cores", "2", "--keep-going")
    print(p.stdout[-2000:] + p.stderr[-3000:])
    check(p.returncode != 0, "a failed case makes snakemake exit non-zero (got %d)" % p.returncode)
    summary = os.path.join(TMP, "badcohort", "summary.json")
    if check(os.path.exists(summary), "the summary is written although a case failed"):
        with open(summary) as f:
            s = {c["case"]: c for c in json.load(f)["cases"]}
        b = s.get("broken", {})
        check(b.get("status") == "failed" and b.get("exit_code") == 4 and
              "cannot be read" in b.get("error", ""),
              "the broken case is listed as failed with exit 4 and the reader's error: %s" % b)
        check(s.get("mickey", {}).get("status") in ("ok", "poor_elements") and
              os.path.exists(os.path.join(TMP, "badcohort", "mickey", "mickey.vtu")),
              "the good case is meshed: %s" % s.get("mickey"))
    shutil.copy(os.path.join(TMP, "in", "spheres_argmax.nrrd"), os.path.join(bad, "broken.nrrd"))
    p = snakemake(TMP, "bad", "badcohort", "--cores", "2", "--keep-going")
    check(p.returncode == 0, "after the repair the rerun exits 0 (got %d)" % p.returncode)
    if os.path.exists(summary):
        with open(summary) as f:
            s = {c["case"]: c for c in json.load(f)["cases"]}
        check(s.get("broken", {}).get("status") in ("ok", "poor_elements") and
              s["broken"].get("exit_code") == 0,
              "the repaired case is ok in the new summary: %s" % s.get("broken"))
if not check.failures:
    shutil.rmtree(TMP, ignore_errors=True)
check.finish()
