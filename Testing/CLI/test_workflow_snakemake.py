#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""The Snakemake workflow (Resources/Workflow/Snakefile, issue 16 items 3 and 4b) run locally with
--cores 2 on three cases (mickey, the phantom, spheres_argmax: a folder as input): one `mesh` job
per case with the memory of its estimate, the summary by `femesher batch --summarise-only`; every
mesh readable by meshio with the summary's tet count; a second run has nothing to do. With
CI=true a missing snakemake is a failure."""
import os
import re
import shutil
import tempfile

from workflow_common import (Checker, check_outputs, expected_memory, job_memory, make_cases,
                             need_tools, snakemake)

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
    check_outputs(check, os.path.join(TMP, "cohort"))
    p = snakemake(TMP, "in", "cohort", "--cores", "2")
    check(p.returncode == 0 and "Nothing to be done" in p.stdout + p.stderr,
          "a second run has nothing to do")
if not check.failures:
    shutil.rmtree(TMP, ignore_errors=True)
check.finish()
