#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Second-order exports (element_order=2) of the built-in phantom read back by meshio (Debian
python3-meshio): the .inp (C3D10), .msh (Gmsh type 11), .vtu and .vtk (VTK_QUADRATIC_TETRA) give
meshio's `tetra10` cells, one per tet of the run report, and the same 10 node positions per element
in every format once each format's node order is undone (meshio itself turns Gmsh's order into
VTK's). Independently of meshio the raw files are checked against each format's documented order:
C3D10 / VTK / FEBio mid-edge nodes on edges 1-2, 2-3, 3-1, 1-4, 2-4, 3-4 (Abaqus manual, C3D10;
vtkQuadraticTetra), Gmsh's tet10 with the last two swapped (node 9 on edge 3-4, node 10 on edge
2-4, Gmsh manual "Node ordering"). One mid-edge node per unique edge, shared by all tets around
the edge: at its midpoint for an interior edge, within half the edge's length of it for an edge on
an interface or the outer boundary (those are curved onto the smooth interfaces:
test_quadratic_curved.py); the raw .msh gives every edge the node the .inp gives it. The .mesh and
.stl refuse element order 2 (exit 2, no file)."""
import os
import re

import meshio
import numpy as np

from exports_common import CLI, Checker, InpModel, mesh_volume, run

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


def surface_edges(points, cells, labels):
    """Corner edges on a face of one element (outer boundary) or between two materials, as pairs of
    rounded corner coordinates (the same in every format, whatever its node numbering)."""
    faces = {}
    for e, c in enumerate(cells):
        for f in ((1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1)):
            faces.setdefault(tuple(sorted(int(c[i]) for i in f)), []).append(labels[e])
    out = set()
    for f, ls in faces.items():
        if len(ls) == 1 or ls[0] != ls[1]:
            for a, b in ((f[0], f[1]), (f[1], f[2]), (f[0], f[2])):
                out.add(edge_key(points, a, b))
    return out


def edge_key(points, a, b):
    return frozenset((tuple(np.round(points[a], 6)), tuple(np.round(points[b], 6))))


def by_corners(points, cells):
    """{sorted corner coordinates: the 10 node coordinates} (order-independent element key;
    coordinates rounded to 1e-9 mm in the key: the .inp holds at most 20 characters a number)."""
    out = {}
    for c in cells:
        x = points[c]
        out[tuple(sorted(tuple(np.round(p, 9)) for p in x[:4]))] = x
    return out


vtu = meshio.read(base + ".vtu")
vtu_cells, _ = tetra10(vtu)
surface = surface_edges(np.asarray(vtu.points, float), vtu_cells,
                        np.concatenate([d for c, d in zip(vtu.cells, vtu.cell_data["labels"]) if c.type == "tetra10"]))
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
    err, ratio = 0.0, 0.0
    for c, xc in zip(cells, x):
        for k, (a, b) in enumerate(EDGES):
            d = np.linalg.norm(xc[4 + k] - 0.5 * (xc[a] + xc[b]))
            if edge_key(pts, c[a], c[b]) in surface:
                ratio = max(ratio, d / np.linalg.norm(xc[a] - xc[b]))
            else:
                err = max(err, d)
    check(err <= 1e-9 * max(1.0, np.abs(pts).max()) and ratio <= 0.5,
          "%s: in meshio's (VTK) order every interior mid-edge node is its edge's midpoint (max error "
          "%.3g), every interface one within %.3f edge lengths of it" % (ext, err, ratio))
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
# The .inp's elements (C3D10 order) name the mid-edge node of every edge; the writers number nodes
# alike (file order), so the raw .msh must give each edge the same node in Gmsh's order.
inp_model = InpModel(open(base + ".inp").read())
inp_mid = {}
for el in inp_model.elements.values():
    for k, (a, b) in enumerate(EDGES):
        inp_mid[(min(el[a], el[b]) - 1, max(el[a], el[b]) - 1)] = el[4 + k] - 1


def mismatches(E, pairs, first):
    return sum(int(inp_mid.get((min(e[a], e[b]), max(e[a], e[b]))) != e[first + k])
               for e in E for k, (a, b) in enumerate(pairs))


bad = mismatches(T, GMSH_EDGES, 4)
check(len(T) == n_tets and bad == 0,
      ".msh raw: nodes 5..10 of every tet on edges 1-2, 2-3, 3-1, 1-4, 3-4, 2-4 (Gmsh), as the .inp's C3D10 "
      "has them (%d differ)" % bad)
check(mismatches(T, EDGES, 4) > 0, ".msh raw: read in C3D10 order instead, nodes land on the wrong edges")
F = np.array(raw_tris) - 1
bad = mismatches(F, [(0, 1), (1, 2), (2, 0)], 3)
check(len(F) > 0 and bad == 0,
      ".msh raw: %d interface triangles with nodes 4..6 on edges 1-2, 2-3, 3-1 (%d differ)" % (len(F), bad))

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
