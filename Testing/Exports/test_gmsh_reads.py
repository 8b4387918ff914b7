#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Gmsh itself (Debian gmsh, command line) loads the MSH 4.1 export of the phantom: `gmsh -check`
exits 0 without warnings and counts the nodes and elements FEMesher wrote; Gmsh re-saves it and
its copy keeps every tet, every interface triangle and one physical volume per material."""
import os
import re
import shutil
import subprocess

import meshio
import numpy as np

from exports_common import IN_CI, Checker, mesh_volume

check = Checker()
gmsh = shutil.which("gmsh")
if not gmsh:
    check(not IN_CI and False, "gmsh is installed (Debian package gmsh)")
    check.finish()


def run(args):
    return subprocess.run(args, capture_output=True, text=True, timeout=900, stdin=subprocess.DEVNULL)


base, report, _ = mesh_volume("gmsh")
n_tets = int(report["counts"]["tets"])
n_pts = int(report["counts"]["vertices"])
in_mesh = sorted(l["id"] for l in report["input"]["labels"] if l["in_mesh"])
ours = meshio.read(base + ".msh")
n_tris = sum(len(b.data) for b in ours.cells if b.type == "triangle")
check(n_tris > 0, "the export has %d interface/boundary triangles" % n_tris)

# 1. gmsh -check: loads the file, checks coherence (duplicate nodes/elements, isolated nodes).
r = run([gmsh, "-check", base + ".msh"])
out = r.stdout + r.stderr
check(r.returncode == 0, "gmsh -check exits 0 (rc=%d)" % r.returncode)
bad = [l for l in out.splitlines() if l.startswith(("Warning", "Error"))]
check(not bad, "gmsh -check reports no warning or error %s" % bad[:5])
nodes = re.search(r"Info\s*:\s*(\d+) nodes", out)
elems = re.search(r"Info\s*:\s*(\d+) elements", out)
check(nodes is not None and int(nodes.group(1)) == n_pts,
      "gmsh counts %s nodes (FEMesher wrote %d)" % (nodes.group(1) if nodes else "?", n_pts))
check(elems is not None and int(elems.group(1)) == n_tets + n_tris,
      "gmsh counts %s elements (FEMesher wrote %d tets + %d triangles)" % (elems.group(1) if elems else "?", n_tets, n_tris))
check("Checking mesh coherence" in out and "Done checking mesh coherence" in out, "gmsh ran its coherence check")

# 2. Load and re-save with every element (gmsh's own writer), then read Gmsh's copy.
out_path = base + "_resaved.msh"
r = run([gmsh, "-0", base + ".msh", "-format", "msh41", "-save_all", "-o", out_path])
check(r.returncode == 0, "gmsh loads and re-saves the mesh (rc=%d %s)" % (r.returncode, r.stderr[-300:]))
check(not [l for l in (r.stdout + r.stderr).splitlines() if l.startswith("Error")], "gmsh reports no error on re-save")
check(os.path.exists(out_path), "gmsh wrote its copy")
if os.path.exists(out_path):
    m = meshio.read(out_path)
    tets = [(b, d) for b, d in zip(m.cells, m.cell_data["gmsh:physical"]) if b.type == "tetra"]
    check(sum(len(b.data) for b, _ in tets) == n_tets, "gmsh kept all %d tets" % n_tets)
    check(sum(len(b.data) for b in m.cells if b.type == "triangle") == n_tris, "gmsh kept all %d triangles" % n_tris)
    phys = sorted({int(x) for _, d in tets for x in d})
    check(phys == in_mesh, "gmsh kept one physical volume per material %s" % phys)
    names = sorted(k for k, v in m.field_data.items() if int(v[1]) == 3)
    want = sorted(l["name"] for l in report["input"]["labels"] if l["in_mesh"])
    check(names == want, "gmsh kept the material names %s" % names)
    # Same geometry: total tet volume unchanged.
    def volume(mesh):
        p = mesh.points
        t = np.concatenate([b.data for b in mesh.cells if b.type == "tetra"])
        return np.einsum("ij,ij->i", p[t[:, 1]] - p[t[:, 0]],
                         np.cross(p[t[:, 2]] - p[t[:, 0]], p[t[:, 3]] - p[t[:, 0]])).sum() / 6
    v0, v1 = volume(ours), volume(m)
    check(abs(v0 - v1) <= 1e-9 * abs(v0), "gmsh's copy has the same volume (%.6g vs %.6g mm^3)" % (v1, v0))
check.finish()
