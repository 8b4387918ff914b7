#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""CalculiX (Debian calculix-ccx) solves the C3D10 export (element_order=2) of the phantom with
the load case of test_calculix_solves.py, and agrees with the C3D4 export of the same mesh: the
phantom is meshed twice with the same settings (same seed: the same mesh, checked node by node),
written as C3D4 and as C3D10. A driver deck *INCLUDEs each export unchanged: the BOUNDARY nodes of
the bottom face fixed (the mid-edge nodes there too), 1 kN *CLOAD pushing the top face's boundary
nodes down. Both runs must end without *ERROR, with finite displacements, reactions balancing the
load, and the mean and the largest downward displacement of the top corner nodes (the same nodes
in both decks) within 20 % of each other (C3D4 is the stiffer element, so C3D10 moves as much
or somewhat more; measured on 2026-11-24: 2.3 % apart). The C3D10 deck is curved: its interface
and boundary mid-edge nodes are on the smooth interfaces (element_order 2 always curves them;
the report counts them and the deck's nodes are off their edges' midpoints), so CalculiX solves
curved elements."""
import math
import os
import shutil

import numpy as np

from exports_common import IN_CI, Checker, InpModel, mesh_volume, node_lines, run_ccx

check = Checker()
ccx = shutil.which("ccx")
if not ccx:
    check(not IN_CI and False, "ccx (Debian package calculix-ccx) is installed")
    check.finish()

SETTINGS = ["--set", "sizing_scale=1.5", "--set", "material.5.E=110000", "--set", "material.5.nu=0.34",
            "--set", "default.E=15000"]


def parse(inp):
    m = InpModel(inp)
    return m.nodes, m.elements, set(m.nsets.get("BOUNDARY", [])), m.types


def solve(inp_path, job, nodes, boundary, n_vertices):
    """Bottom boundary nodes fixed, 1 kN down on the top boundary nodes; returns the uz of the top
    corner nodes (ids <= n_vertices) and the reaction total."""
    zs = np.array([nodes[n][2] for n in boundary])
    zmin, zmax = zs.min(), zs.max()
    tol = 0.02 * (zmax - zmin)
    bottom = sorted(n for n in boundary if nodes[n][2] < zmin + tol)
    top = sorted(n for n in boundary if nodes[n][2] > zmax - tol)
    top_corners = [n for n in top if n <= n_vertices]
    per_node = -1000.0 / len(top)
    work = os.path.dirname(inp_path)
    text = ("*INCLUDE, INPUT=%s\n" % os.path.basename(inp_path) + "*NSET, NSET=FIXED\n" + node_lines(bottom) +
            "*NSET, NSET=CORNERS\n" + node_lines(top_corners) + "*BOUNDARY\nFIXED, 1, 3, 0.0\n*STEP\n*STATIC\n*CLOAD\n" +
            "".join("%d, 3, %.10g\n" % (n, per_node) for n in top) +
            "*NODE PRINT, NSET=CORNERS\nU\n*NODE PRINT, NSET=FIXED, TOTALS=ONLY\nRF\n*NODE FILE\nU\n*END STEP\n")
    with open(os.path.join(work, job + ".inp"), "w") as f:
        f.write(text)
    disp, totals = run_ccx(ccx, work, job, check, timeout=3000)
    frd = os.path.join(work, job + ".frd")
    check(os.path.exists(frd) and "DISP" in open(frd).read(), "%s: ccx wrote displacements to %s.frd" % (job, job))
    uz = [row[3] for row in disp[0]] if disp else []
    check(len(uz) == len(top_corners) and len(uz) >= 3,
          "%s: displacements of the %d top corner nodes printed (%d)" % (job, len(top_corners), len(uz)))
    check(all(math.isfinite(u) for u in uz) and any(u != 0 for u in uz), "%s: displacements finite, not all zero" % job)
    rf = np.array(totals[0][0]) if totals and totals[0] else np.full(3, np.nan)
    check(abs(rf[2] - 1000.0) < 1.0 and abs(rf[0]) < 1.0 and abs(rf[1]) < 1.0,
          "%s: the reaction balances the 1 kN load (RF = %s N)" % (job, np.round(rf, 4)))
    return (sum(uz) / len(uz) if uz else float("nan")), min(uz, default=float("nan"))


base1, report1, _ = mesh_volume("c3d4", extra=SETTINGS, exts=[".inp"])
base2, report2, _ = mesh_volume("c3d10", extra=SETTINGS + ["--set", "element_order=2"], exts=[".inp"])
n1, e1, b1, t1 = parse(open(base1 + ".inp").read())
n2, e2, b2, t2 = parse(open(base2 + ".inp").read())
nv = int(report1["counts"]["vertices"])
check(t1 == {"C3D4"} and t2 == {"C3D10"}, "element types %s and %s" % (sorted(t1), sorted(t2)))
check(len(e1) == len(e2) == int(report1["counts"]["tets"]) and all(len(c) == 10 for c in e2.values()),
      "both decks have the %d tets of the report, the second with 10 nodes each" % len(e1))
check(len(n1) == nv and len(n2) > nv and all(np.array_equal(n1[i], n2[i]) for i in n1)
      and all(e1[k] == e2[k][:4] for k in e1),
      "the same mesh: C3D10 corner nodes and corners = the C3D4 nodes and elements")
check(b1 <= b2 and all(n > nv for n in b2 - b1), "BOUNDARY of the C3D10 deck = the C3D4 one plus mid-edge nodes")
EDGES = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]
off = {el[4 + k] for el in e2.values() for k, (a, b) in enumerate(EDGES)
       if np.linalg.norm(n2[el[4 + k]] - 0.5 * (n2[el[a]] + n2[el[b]])) > 1e-6}
curved = int(report2["counts"].get("quadratic_curved_nodes", 0) + report2["counts"].get("quadratic_partly_curved_nodes", 0))
check(curved > 100 and 0.99 * curved <= len(off) <= curved,
      "the C3D10 deck is curved: %d mid-edge nodes more than 1e-6 mm off their edge's midpoint, of the "
      "report's %d curved nodes" % (len(off), curved))
mean4, min4 = solve(base1 + ".inp", "static_c3d4", n1, b1, nv)
mean10, min10 = solve(base2 + ".inp", "static_c3d10", n2, b2, nv)
print("mean uz of the top corner nodes: C3D4 %.6g mm, C3D10 %.6g mm; min C3D4 %.6g, C3D10 %.6g"
      % (mean4, mean10, min4, min10))
check(mean4 < 0 and mean10 < 0, "both decks move the top down")
check(abs(mean10 - mean4) <= 0.2 * abs(mean4),
      "C3D10 and C3D4 agree within 20 %% on the mean top displacement (%.4g vs %.4g mm, %.1f %%)"
      % (mean10, mean4, 100 * (mean10 - mean4) / mean4 if mean4 else float("nan")))
check(abs(min10 - min4) <= 0.2 * abs(min4),
      "C3D10 and C3D4 agree within 20 %% on the largest top displacement (%.4g vs %.4g mm)" % (min10, min4))
check.finish()
