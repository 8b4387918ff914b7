#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Second-order exports (element_order=2) of the built-in phantom read back by meshio (Debian
python3-meshio): the .inp (C3D10), .msh (Gmsh type 11), .vtu and .vtk (VTK_QUADRATIC_TETRA) give
meshio's `tetra10` cells, one per tet of the run report, and the same 10 node positions per element
in every format once each format's node order is undone (meshio itself turns Gmsh's order into
VTK's). Independently of meshio the raw files are checked against each format's documented order:
C3D10 / VTK / FEBio mid-edge nodes on edges 1-2, 2-3, 3-1, 1-4, 2-4, 3-4 (Abaqus manual, C3D10;
vtkQuadraticTetra), Gmsh's tet10 with the last two swapped (node 9 on edge 3-4, node 10 on edge
2-4, Gmsh manual "Node ordering"). One mid-edge node per unique edge, at its
midpoint, shared by all tets around the edge; the .mesh and .stl refuse element order 2 (exit 2,
no file)."""
import os
import re

import meshio
import numpy as np

from exports_common import CLI, Checker, mesh_volume, run

check = Checker()
EDGES = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]  # C3D10 / VTK / FEBio
GMSH_EDGES = [(0, 1), (1, 2), (2, 0), (0, 3), (2, 3), (1, 3)]  # Gmsh tet10 nodes 5..10

base, report, source = mesh_volume("tet10", None, ["--set", "element_order=2"],
                                   exts=[".vtu", ".vtk", ".inp", ".msh"])
n_tets = int(report["counts"]["tets"])
n_vertices = int(report["counts"]["vertices"])


def tetra10(m):
    cells = [c.data for c in m.cells if c.type == "tetra10"]
    others = sorted(set(c.type for c in m.cells) - {"tetra10", "triangle6"})
    return (np.concatenate(cells) if cells else np.zeros((0, 10), int)), others


def by_corners(points, cells):
    """{sorted corner coordinates: the 10 node coordinates} (order-independent element key;
    coordinates rounded to 1e-9 mm in the key: the .inp holds at most 20 characters a number)."""
    out = {}
    for c in cells:
        x = points[c]
        out[tuple(sorted(tuple(np.round(p, 9)) for p in x[:4]))] = x
    return out


per_format = {}
for ext in (".inp", ".msh", ".vtu", ".vtk"):
    m = meshio.read(base + ext)
    cells, others = tetra10(m)
    check(len(cells) == n_tets and not others,
          "%s: meshio reads %d tetra10 cells (report: %d tets; other volume types %s)" % (ext, len(cells), n_tets, others))
    pts = np.asarray(m.points, dtype=float)
    used = np.unique(cells)
    corners = np.unique(cells[:, :4])
    mids = np.unique(cells[:, 4:])
    check(len(corners) == n_vertices and not set(corners.tolist()) & set(mids.tolist()),
          "%s: %d corner nodes (report: %d vertices), none of them a mid-edge node" % (ext, len(corners), n_vertices))
    edges = set()
    for c in cells:
        for a, b in EDGES:
            edges.add((min(c[a], c[b]), max(c[a], c[b])))
    check(len(mids) == len(edges) and len(used) == len(pts),
          "%s: one mid-edge node per unique edge (%d nodes, %d edges), no unused node" % (ext, len(mids), len(edges)))
    owner = {}
    for c in cells:
        for k, (a, b) in enumerate(EDGES):
            owner.setdefault((min(c[a], c[b]), max(c[a], c[b])), set()).add(int(c[4 + k]))
    check(all(len(s) == 1 for s in owner.values()), "%s: every tet around an edge has the same mid-edge node" % ext)
    x = pts[cells]
    err = max(np.abs(x[:, 4 + k] - 0.5 * (x[:, a] + x[:, b])).max() for k, (a, b) in enumerate(EDGES))
    check(err <= 1e-9 * max(1.0, np.abs(pts).max()),
          "%s: in meshio's (VTK) order every mid-edge node is its edge's midpoint (max error %.3g)" % (ext, err))
    vol = np.einsum("ij,ij->i", x[:, 1] - x[:, 0], np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 0]))
    check(bool((vol > 0).all()), "%s: every element positively oriented (%d not)" % (ext, int((vol <= 0).sum())))
    per_format[ext] = by_corners(pts, cells)

ref = per_format[".vtu"]
for ext, elems in per_format.items():
    if ext == ".vtu":
        continue
    same = elems.keys() == ref.keys()
    diff = max((np.abs(elems[k] - ref[k]).max() for k in ref if k in elems), default=np.inf)
    check(same and diff <= 1e-9 * max(1.0, max(np.abs(v).max() for v in ref.values())),
          "%s and .vtu: the same elements with the same 10 node positions in order (max diff %.3g)" % (ext, diff))

# The raw .msh, without meshio: type 11 elements in Gmsh's order, 6-node triangles (type 9).
text = open(base + ".msh").read()
nodes_sec = text[text.index("$Nodes"):text.index("$EndNodes")].split("\n")
nn = int(nodes_sec[1].split()[1])
xyz = np.array([[float(v) for v in l.split()] for l in nodes_sec[3 + nn:3 + 2 * nn]])
elems_sec = text[text.index("$Elements"):text.index("$EndElements")].split("\n")[2:]
i, raw_tets, raw_tris, types = 0, [], [], set()
while i < len(elems_sec) and elems_sec[i].strip():
    dim, tag, typ, count = (int(v) for v in elems_sec[i].split())
    types.add((dim, typ))
    rows = [[int(v) for v in l.split()][1:] for l in elems_sec[i + 1:i + 1 + count]]
    (raw_tets if typ == 11 else raw_tris if typ == 9 else []).extend(rows)
    i += count + 1
check(types == {(2, 9), (3, 11)}, ".msh: only 6-node triangles (9) and 10-node tets (11): %s" % sorted(types))
T = np.array(raw_tets) - 1
err = max(np.abs(xyz[T[:, 4 + k]] - 0.5 * (xyz[T[:, a]] + xyz[T[:, b]])).max() for k, (a, b) in enumerate(GMSH_EDGES))
check(len(T) == n_tets and err <= 1e-9 * max(1.0, np.abs(xyz).max()),
      ".msh raw: nodes 5..10 of every tet at the midpoints of edges 1-2, 2-3, 3-1, 1-4, 3-4, 2-4 (Gmsh) (max error %.3g)" % err)
F = np.array(raw_tris) - 1
err = max(np.abs(xyz[F[:, 3 + k]] - 0.5 * (xyz[F[:, a]] + xyz[F[:, b]])).max() for k, (a, b) in enumerate([(0, 1), (1, 2), (2, 0)]))
check(len(F) > 0 and err <= 1e-9 * max(1.0, np.abs(xyz).max()),
      ".msh raw: %d interface triangles with nodes 4..6 on edges 1-2, 2-3, 3-1 (max error %.3g)" % (len(F), err))

# The raw .inp: C3D10 in the Abaqus order.
inp = open(base + ".inp").read()
check("TYPE=C3D10" in inp and "TYPE=C3D4" not in inp, ".inp: C3D10 elements only")

# Formats without 10-node tets: exit 2, a message naming the file, and no file.
tmp = os.path.dirname(base)
for ext in (".mesh", ".stl"):
    out = os.path.join(tmp, "refused" + ext)
    r = run([CLI, "mesh", source, "-o", out, "--set", "element_order=2", "-q"])
    check(r.returncode == 2 and out in r.stderr and "10-node" in r.stderr and not os.path.exists(out),
          "%s with element_order=2: exit 2, a clear message, no file (exit %d: %s)" % (ext, r.returncode, r.stderr.strip()[:200]))
r = run([CLI, "mesh", source, "-o", os.path.join(tmp, "bad.inp"), "--element-order", "3", "-q"])
check(r.returncode == 2 and "element_order" in r.stderr, "--element-order 3: exit 2 (%s)" % r.stderr.strip()[:200])
check.finish()
