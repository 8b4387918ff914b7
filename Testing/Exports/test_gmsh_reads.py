#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Gmsh itself (Debian gmsh) loads the MSH 4.1 export, re-saves it, and keeps every element and
physical group."""
import os
import shutil
import subprocess

import meshio

from exports_common import IN_CI, Checker, mesh_volume

check = Checker()
gmsh = shutil.which("gmsh")
if not gmsh:
    check(not IN_CI and False, "gmsh is installed")
    check.finish()

base, report, _ = mesh_volume("gmsh")
n_tets = int(report["counts"]["tets"])
out = base + "_resaved.msh"
r = subprocess.run([gmsh, "-0", base + ".msh", "-format", "msh41", "-save_all", "-o", out],
                   capture_output=True, text=True, timeout=600, stdin=subprocess.DEVNULL)
check(r.returncode == 0, "gmsh loads and re-saves the mesh (rc=%d %s)" % (r.returncode, r.stderr[-300:]))
check("Error" not in r.stdout + r.stderr, "gmsh reports no error")
check(os.path.exists(out), "gmsh wrote its copy")
if os.path.exists(out):
    m = meshio.read(out)
    tets = sum(len(b.data) for b in m.cells if b.type == "tetra")
    check(tets == n_tets, "gmsh kept all %d tets (got %d)" % (n_tets, tets))
    phys = sorted({int(x) for b, d in zip(m.cells, m.cell_data["gmsh:physical"]) if b.type == "tetra" for x in d})
    in_mesh = sorted(l["id"] for l in report["input"]["labels"] if l["in_mesh"])
    check(phys == in_mesh, "gmsh kept one physical volume per material %s" % phys)
# Gmsh's own statistics on the original file.
r = subprocess.run([gmsh, "-0", base + ".msh", "-v", "4"], capture_output=True, text=True, timeout=600,
                   stdin=subprocess.DEVNULL)
check(r.returncode == 0, "gmsh -0 on the export exits 0")
check.finish()
