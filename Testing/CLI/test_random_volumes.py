#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""30 seeded random multi-material volumes (Testing/Benchmarks/random_volumes.py, small sizes)
through `femesher mesh`, each written mesh judged by an independent decoder: every run succeeds
or fails with a clear error naming the file (an exit code of the README's table) and writes
nothing; no written mesh has a tet of zero or negative volume; a run whose report says "ok" has
no tet below min_dihedral_warning, one that says "poor_elements" has one, and the CLI's
"Elements:" line says the same status; at least 27 of the 30 reach 5 degrees."""
import os
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "Benchmarks"))
import random_volumes  # noqa: E402

CLI = os.environ["FEMESHER_CLI"]
TMP = tempfile.mkdtemp(prefix="random_volumes_", dir=os.environ.get("FEMESHER_TMP"))
COUNT, SEED, MAX_SIZE = 30, 12, 22
FLOOR = 30
# Exit codes of femesher (README, "Exit codes"): the ones a meshing run may end with.
ERRORS = {10: "meshing-failed", 13: "internal"}

failures = []


def check(cond, msg):
    if not cond:
        failures.append(msg)
        print("FAIL:", msg)


def judge(r):
    name = r["name"]
    if r["exit"] != 0:
        check(r["exit"] == 10, "%s: a failed run exits with meshing-failed (10), got %d: %s"
              % (name, r["exit"], r["stderr"][-300:]))
        check(r["error"].startswith("error [%s]" % ERRORS.get(r["exit"], "?"))
              and os.path.basename(r["path"]) in r["error"],
              "%s: the error names its code and the file: %s" % (name, r["error"]))
        check(not r["written"], "%s: a failed run writes no mesh" % name)
        return
    check(r["tets"] > 0, "%s: the mesh has tets" % name)
    check(r["zero_volume"] == 0, "%s: %d written tets of zero or negative volume"
          % (name, r["zero_volume"]))
    warning = r["warning_deg"]
    if r["status"] == "ok":
        check(r["worst"] >= warning - 1e-6, "%s: status ok but the written mesh's worst angle is "
              "%.4f < min_dihedral_warning %g" % (name, r["worst"], warning))
    else:
        check(r["status"] == "poor_elements" and r["worst"] < warning + 1e-6,
              "%s: status %s with worst angle %.4f (warning %g)" % (name, r["status"], r["worst"],
                                                                     warning))
    check(r["elements_line"].endswith("status " + r["status"]),
          "%s: the CLI's Elements line says the report's status: %r" % (name, r["elements_line"]))
    check(not r["missing"], "%s: labels missing from the mesh: %s" % (name, r["missing"]))



rows = random_volumes.sweep(CLI, COUNT, SEED, MAX_SIZE, TMP)
check(len(rows) == COUNT, "%d runs" % len(rows))
# A volume whose mesh kept flat tets between two boxes (before issue 12's optimiser): the run
# must fail with a clear error, or succeed without them.
name, path = random_volumes.generate(200148, TMP)
extra = random_volumes.mesh_one(CLI, path, TMP)
extra.update(name=name, path=path)
print(name, "exit", extra["exit"], extra.get("error", extra.get("status")))
# A small box-shaped label whose flat tet on the volume's box cuts off specks worth 0.8 % of it,
# beyond its peeling budget (2026-11-27: worst 0.13 degrees until the last resort peels it anyway).
name, path = random_volumes.generate(100292, TMP)
beyond = random_volumes.mesh_one(CLI, path, TMP)
beyond.update(name=name, path=path)
print(name, "exit", beyond["exit"], "worst", beyond.get("worst"))
check(beyond["exit"] == 0 and beyond["worst"] >= beyond["warning_deg"] - 1e-6,
      "%s: its flat tet on the box stays (worst %s)" % (name, beyond.get("worst")))
for r in rows + [extra, beyond]:
    judge(r)
# Regression floor for the optimiser (issue 12): the share of the 30 meshes whose worst tet
# reaches min_dihedral_warning (5 degrees). Measured 2026-11-24: 28 of 30, then 27 after the
# volume-preserving indicators (while 300 volumes went 239 -> 260), then 29 after peeling by the
# facet distance and the peeling budget kept for the flattest tets (300 volumes: 273); the floor
# leaves room for shifts.
reached = sum(1 for r in rows if r["exit"] == 0 and r["worst"] >= r["warning_deg"] - 1e-6)
print("%d of %d meshes reach a worst angle of 5 degrees" % (reached, len(rows)))
check(reached >= FLOOR, "only %d of %d meshes reach 5 degrees (floor %d)" % (reached, len(rows), FLOOR))
print("%d runs, %d failures" % (len(rows) + 2, len(failures)))
sys.exit(1 if failures else 0)
