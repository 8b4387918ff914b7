#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""CalculiX (Debian calculix-ccx) solves the Abaqus INP export of the phantom: a linear static step
with the nodes of the bottom face fixed and the top face loaded. Displacements must be finite and
not all zero, and the top must move in the load direction."""
import math
import os
import re
import shutil
import subprocess

from exports_common import IN_CI, Checker, mesh_volume

check = Checker()
ccx = shutil.which("ccx")
if not ccx:
    check(not IN_CI and False, "ccx (calculix-ccx) is installed")
    check.finish()

base, report, _ = mesh_volume("ccx", extra=["--set", "material.5.E=110000", "--set", "material.5.nu=0.34",
                                            "--set", "default.E=15000"])
inp = open(base + ".inp").read()
check("*SOLID SECTION" in inp and "*ELASTIC" in inp, "INP has sections and elastic materials")
check("110000" in inp, "per-material Young's modulus reaches the INP")
check("*SURFACE, NAME=IF_" in inp and "*NSET, NSET=BOUNDARY" in inp, "INP has interface surfaces and the boundary node set")

# Nodes and the boundary set.
nodes = {}
section = None
boundary = set()
for line in inp.splitlines():
    if line.startswith("*"):
        section = line.upper()
        continue
    if section and section.startswith("*NODE"):
        parts = line.split(",")
        nodes[int(parts[0])] = tuple(float(x) for x in parts[1:4])
    elif section and section.startswith("*NSET, NSET=BOUNDARY"):
        boundary.update(int(x) for x in line.replace(",", " ").split())
zs = [nodes[n][2] for n in boundary]
zmin, zmax = min(zs), max(zs)
tol = 1.0
bottom = sorted(n for n in boundary if nodes[n][2] < zmin + tol)
top = sorted(n for n in boundary if nodes[n][2] > zmax - tol)
check(len(bottom) >= 3 and len(top) >= 3, "found %d bottom and %d top boundary nodes" % (len(bottom), len(top)))

work = os.path.dirname(base)
deck = os.path.join(work, "static")
with open(deck + ".inp", "w") as f:
    f.write("*INCLUDE, INPUT=%s\n" % os.path.basename(base + ".inp"))
    f.write("*NSET, NSET=FIXED\n" + "\n".join("%d," % n for n in bottom) + "\n")
    f.write("*NSET, NSET=LOADED\n" + "\n".join("%d," % n for n in top) + "\n")
    f.write("*BOUNDARY\nFIXED, 1, 3, 0.0\n")
    f.write("*STEP\n*STATIC\n*CLOAD\n")
    per_node = -1000.0 / len(top)  # 1 kN downwards (-z) in total
    for n in top:
        f.write("%d, 3, %.10g\n" % (n, per_node))
    f.write("*NODE PRINT, NSET=LOADED\nU\n*END STEP\n")
r = subprocess.run([ccx, "-i", "static"], cwd=work, capture_output=True, text=True, timeout=1500,
                   stdin=subprocess.DEVNULL, env=dict(os.environ, OMP_NUM_THREADS="2"))
out = r.stdout + r.stderr
check(r.returncode == 0, "ccx exits 0")
check("*ERROR" not in out, "ccx reports no *ERROR" + ("" if "*ERROR" not in out else ": " + out[out.find("*ERROR"):][:300]))
dat = os.path.join(work, "static.dat")
uz = []
if os.path.exists(dat):
    for line in open(dat):
        m = re.match(r"\s*(\d+)\s+([-+0-9.Ee]+)\s+([-+0-9.Ee]+)\s+([-+0-9.Ee]+)\s*$", line)
        if m:
            uz.append(float(m.group(4)))
check(len(uz) == len(top), "displacements printed for the %d loaded nodes (got %d)" % (len(top), len(uz)))
check(all(math.isfinite(u) for u in uz), "all displacements are finite")
check(any(abs(u) > 0 for u in uz), "displacements are not all zero")
check(sum(uz) / max(1, len(uz)) < 0, "the loaded face moves in the load direction (mean uz %.3g mm)" % (sum(uz) / max(1, len(uz))))
check.finish()
