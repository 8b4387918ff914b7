#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""CalculiX (Debian calculix-ccx) solves the Abaqus INP export of the phantom. A driver deck
*INCLUDEs the export unchanged and adds two linear static steps:
  1. the BOUNDARY nodes of the bottom face fixed, a 1 kN *CLOAD pushing the top face nodes down:
     the run must end without *ERROR, displacements finite, not all zero, the top moving down,
     and the reaction at the fixed nodes balancing the load;
  2. (a second deck) a uniform pressure *DLOAD on every OUTER_<label> element surface (together
     the closed outer boundary), the body held by a statically determinate 3-2-1 support on three
     interior nodes: a closed surface under uniform pressure has zero resultant, so the support
     reaction must be ~0 relative to pressure x area; wrong face numbers (S1..S4) or a missing
     patch would break that."""
import math
import os
import re
import shutil

import numpy as np

from exports_common import IN_CI, Checker, InpModel, mesh_volume, node_lines, run_ccx

check = Checker()
ccx = shutil.which("ccx")
if not ccx:
    check(not IN_CI and False, "ccx (Debian package calculix-ccx) is installed")
    check.finish()

# A coarser sizing keeps the solve quick; materials differ per label.
base, report, _ = mesh_volume("ccx", extra=["--set", "sizing_scale=1.5", "--set", "material.5.E=110000",
                                            "--set", "material.5.nu=0.34", "--set", "default.E=15000"])
inp_path = base + ".inp"
inp = open(inp_path).read()
check(re.search(r"^\*STEP", inp, re.M | re.I) is None, "the export is model data only (no *STEP)")
check("*SOLID SECTION" in inp and "*ELASTIC" in inp and "*DENSITY" in inp, "INP has sections and materials")
check(re.search(r"\*ELASTIC\n110000, 0\.34\n", inp) is not None, "per-material E and nu reach the INP")
check("*SURFACE, NAME=IF_" in inp and "*NSET, NSET=BOUNDARY" in inp, "INP has interface surfaces and the boundary node set")

# Nodes, BOUNDARY, element connectivity and the OUTER_ surfaces.
model = InpModel(inp)
nodes, elements = model.nodes, model.elements
boundary = set(model.nsets.get("BOUNDARY", []))
outer = {k: v for k, v in model.surfaces.items() if k.startswith("OUTER_")}
n_tets = int(report["counts"]["tets"])
check(len(nodes) == int(report["counts"]["vertices"]) and len(elements) == n_tets,
      "INP has %d nodes and %d elements as in the report" % (len(nodes), len(elements)))
zs = np.array([nodes[n][2] for n in boundary])
zmin, zmax = zs.min(), zs.max()
tol = 0.02 * (zmax - zmin)
bottom = sorted(n for n in boundary if nodes[n][2] < zmin + tol)
top = sorted(n for n in boundary if nodes[n][2] > zmax - tol)
check(len(bottom) >= 3 and len(top) >= 3, "found %d bottom and %d top boundary nodes" % (len(bottom), len(top)))

# Outer boundary area (from the element faces the INP names) for the pressure check.
FACES = {1: (0, 1, 2), 2: (0, 3, 1), 3: (1, 3, 2), 4: (2, 3, 0)}
area, resultant = 0.0, np.zeros(3)
for name, faces in outer.items():
    for e, s in faces:
        el = elements[e]
        a, b, c = (nodes[el[i]] for i in FACES[s])
        d = nodes[el[({0, 1, 2, 3} - set(FACES[s])).pop()]]
        nrm = np.cross(b - a, c - a) / 2
        if np.dot(nrm, a - d) < 0:
            nrm = -nrm  # outward from the element
        area += np.linalg.norm(nrm)
        resultant += nrm
check(area > 0 and np.linalg.norm(resultant) < 1e-6 * area,
      "the OUTER_ surfaces close the body (|sum of outward area vectors| %.3g vs area %.4g mm^2)"
      % (np.linalg.norm(resultant), area))

work = os.path.dirname(base)
pressure = 0.01  # MPa


def solve(job, text):
    with open(os.path.join(work, job + ".inp"), "w") as f:
        f.write("*INCLUDE, INPUT=%s\n" % os.path.basename(inp_path) + text)
    return run_ccx(ccx, work, job, check, timeout=1500)


# 1. Bottom fixed, top pushed down.
per_node = -1000.0 / len(top)  # 1 kN downwards (-z) in total
disp, totals = solve("static", "*NSET, NSET=FIXED\n" + node_lines(bottom) + "*NSET, NSET=LOADED\n" +
                     node_lines(top) + "*BOUNDARY\nFIXED, 1, 3, 0.0\n*STEP\n*STATIC\n*CLOAD\n" +
                     "".join("%d, 3, %.10g\n" % (n, per_node) for n in top) +
                     "*NODE PRINT, NSET=LOADED\nU\n*NODE PRINT, NSET=FIXED, TOTALS=ONLY\nRF\n*END STEP\n")
uz = [row[3] for row in disp[0]] if disp else []
check(len(uz) == len(top), "displacements printed for the %d loaded nodes (got %d)" % (len(top), len(uz)))
check(all(math.isfinite(u) for u in uz), "all displacements are finite")
check(any(abs(u) > 0 for u in uz), "displacements are not all zero")
mean_uz = sum(uz) / max(1, len(uz))
check(mean_uz < 0, "the loaded face moves in the load direction (mean uz %.3g mm)" % mean_uz)
check(len(totals) == 1 and len(totals[0]) == 1 and len(totals[0][0]) == 3, "ccx printed the reaction total")
if totals and totals[0]:
    rf = np.array(totals[0][0])
    check(abs(rf[2] - 1000.0) < 1.0 and abs(rf[0]) < 1.0 and abs(rf[1]) < 1.0,
          "the reaction balances the 1 kN load (RF = %s N)" % np.round(rf, 4))

# 2. Uniform pressure on the closed outer boundary, 3-2-1 support on interior nodes.
interior = sorted(set(nodes) - boundary)
xyz = np.array([nodes[n] for n in interior])
a = interior[int(xyz[:, 0].argmin())]
b = interior[int(xyz[:, 0].argmax())]
c = interior[int(np.abs(np.cross(xyz - nodes[a], nodes[b] - nodes[a])).sum(axis=1).argmax())]
check(len({a, b, c}) == 3, "three interior support nodes %s" % [a, b, c])
disp, totals = solve("pressure", "*NSET, NSET=SUPPORT\n%d, %d, %d\n*BOUNDARY\n%d, 1, 3\n%d, 2, 3\n%d, 3, 3\n"
                     % (a, b, c, a, b, c) + "*STEP\n*STATIC\n*DLOAD\n" +
                     "".join("%s, P, %g\n" % (nm, pressure) for nm in sorted(outer)) +
                     "*NODE PRINT, NSET=SUPPORT, TOTALS=ONLY\nRF\n*NODE PRINT, NSET=SUPPORT\nU\n*END STEP\n")
check(len(totals) == 1 and len(totals[0]) == 1, "ccx printed the support reaction")
if totals and totals[0]:
    rf = np.array(totals[0][0])
    check(np.linalg.norm(rf) < 1e-6 * pressure * area,
          "uniform pressure on the OUTER_ surfaces has zero resultant (|RF| %.3g N vs p*A %.4g N)"
          % (np.linalg.norm(rf), pressure * area))
check.finish()
