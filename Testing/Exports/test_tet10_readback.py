#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""10-node meshes read back (round trip): the phantom written with element_order=2 as .vtu, .vtk,
.msh and .inp is read by `femesher quality` (quality of the corner tets, said so, the same figures
as the run report's linear quality, plus the quadratic Jacobian figures of the report) and by
`femesher optimize` (linear output by default, with a note saying the mid-edge nodes were dropped;
10-node output with --set element_order=2, curved anew, every element valid). Files FEMesher
cannot take get a clear error, not a crash: 4-node and 10-node tets mixed (exit 4), an edge with two
different mid-edge nodes (exit 5), an element type other than C3D4/C3D10 (exit 4)."""
import json
import os
import re

import meshio
import numpy as np

from exports_common import CLI, Checker, mesh_volume, run
from quadratic_common import jacobian_figures

check = Checker()
base, report, source = mesh_volume("readback", None, ["--set", "element_order=2"],
                                   exts=[".vtu", ".vtk", ".msh", ".inp"])
counts = report["counts"]
tmp = os.path.dirname(base)

for ext in (".vtu", ".vtk", ".msh", ".inp"):
    r = run([CLI, "quality", base + ext, "--json"])
    ok = r.returncode == 0
    check(ok, "quality %s --json: exit 0 (%d: %s)" % (ext, r.returncode, r.stderr.strip()[:200]))
    if not ok:
        continue
    q = json.loads(r.stdout)
    quad = q.get("quadratic", {})
    check(q.get("element_order") == 2 and quad.get("quality_of") == "corner tets",
          "quality %s: element order 2, quality of the corner tets" % ext)
    check(abs(quad.get("worst_scaled_jacobian", -9) - counts["quadratic_worst_scaled_jacobian"]) < 1e-6
          and abs(quad.get("min_jacobian_fraction", -9) - counts["quadratic_min_jacobian_fraction"]) < 1e-6
          and quad.get("folded_elements") == 0,
          "quality %s: the quadratic Jacobian figures of the run report (%s)" % (ext, quad))
    mine, theirs = q["quality"]["all"], report["quality"]["all"]
    same = mine["tets"] == theirs["tets"] and abs(mine["min_dihedral"]["min"] - theirs["min_dihedral"]["min"]) < 1e-6
    check(same, "quality %s: %s corner tets, worst dihedral %.4f deg: the run's linear mesh (%s, %.4f)"
          % (ext, mine["tets"], mine["min_dihedral"]["min"], theirs["tets"], theirs["min_dihedral"]["min"]))
r = run([CLI, "quality", base + ".msh"])
check(r.returncode == 0 and "corner (4-node) tets" in r.stdout and "worst scaled Jacobian" in r.stdout,
      "quality (text): says the figures are of the corner tets and gives the quadratic Jacobian")

# optimize: linear output unless element_order=2 asks for 10-node tets.
out1 = os.path.join(tmp, "optimized.vtu")
r = run([CLI, "optimize", base + ".msh", "--labels", source, "-o", out1, "-q"], timeout=900)
check(r.returncode == 0 and "10-node" in r.stderr and "linear (4-node)" in r.stderr,
      "optimize .msh -> .vtu: exit 0 and a note that the output is linear (%d: %s)"
      % (r.returncode, r.stderr.strip()[:300]))
if os.path.exists(out1):
    m = meshio.read(out1)
    check({c.type for c in m.cells} == {"tetra"}, "optimize: the .vtu holds 4-node tets (%s)" % {c.type for c in m.cells})
out2 = os.path.join(tmp, "optimized.msh")
rep2 = os.path.join(tmp, "optimized.json")
r = run([CLI, "optimize", base + ".inp", "--labels", source, "-o", out2, "--report", rep2,
         "--set", "element_order=2", "-q"], timeout=900)
check(r.returncode == 0 and "new mid-edge nodes" in r.stderr,
      "optimize .inp -> .msh with element_order=2: exit 0 and a note (%d: %s)" % (r.returncode, r.stderr.strip()[:300]))
if os.path.exists(out2) and os.path.exists(rep2):
    m = meshio.read(out2)
    cells = np.concatenate([c.data for c in m.cells if c.type == "tetra10"])
    fraction, scaled = jacobian_figures(np.asarray(m.points)[cells])
    c2 = json.load(open(rep2))["counts"]
    check({c.type for c in m.cells} <= {"tetra10", "triangle6"} and c2.get("quadratic_curved_nodes", 0) > 50
          and fraction >= 0.2 - 1e-9,
          "optimize: 10-node output, %s nodes curved again, smallest det J / straight %.4f"
          % (c2.get("quadratic_curved_nodes"), fraction))

# Clear errors for what FEMesher cannot read.
inp = open(base + ".inp").read()
bad = inp.replace("*NSET, NSET=BOUNDARY", "*ELEMENT, TYPE=C3D4, ELSET=M1_EXTRA\n999999, 1, 2, 3, 4\n*NSET, NSET=BOUNDARY", 1)
path = os.path.join(tmp, "mixed.inp")
open(path, "w").write(bad)
r = run([CLI, "quality", path])
check(r.returncode == 4 and "mixes 4-node and 10-node" in r.stderr and path in r.stderr,
      "4-node and 10-node tets mixed: exit 4, a clear message (%d: %s)" % (r.returncode, r.stderr.strip()[:200]))
m = re.search(r"^\*ELEMENT, TYPE=C3D10[^\n]*\n(\d+), (\d+), (\d+), (\d+), (\d+), (\d+), (\d+)", inp, re.M)
line = m.group(0).split("\n")[1]
fields = line.split(", ")
fields[5], fields[6] = fields[6], fields[5]  # mid-edge nodes of edges 1-2 and 2-3 swapped
path = os.path.join(tmp, "swapped.inp")
open(path, "w").write(inp.replace(line + ",", ", ".join(fields) + ",", 1) if line + "," in inp else inp.replace(line, ", ".join(fields), 1))
r = run([CLI, "quality", path])
check(r.returncode == 5 and "different mid-edge nodes" in r.stderr,
      "an edge with two different mid-edge nodes: exit 5, a clear message (%d: %s)" % (r.returncode, r.stderr.strip()[:200]))
path = os.path.join(tmp, "c3d20.inp")
open(path, "w").write(inp.replace("TYPE=C3D10", "TYPE=C3D20", 1))
r = run([CLI, "quality", path])
check(r.returncode == 4 and "C3D4 and C3D10" in r.stderr,
      "an .inp of C3D20 elements: exit 4, a clear message (%d: %s)" % (r.returncode, r.stderr.strip()[:200]))
check.finish()
