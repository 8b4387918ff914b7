#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Curved 10-node tets (element_order=2) on the built-in phantom and on a real volume
(spheres_argmax.nrrd, four mutually touching materials filling the whole box), judged from the
written files with code of this test's own (quadratic_common.py):
- the report counts curved mid-edge nodes and its Jacobian figures are those of the file;
- every element of the .inp (read as text) and of the .msh (read by meshio) has a positive Jacobian
  determinant at its 4 corners, 6 mid-edge nodes and centroid, at least the stated fraction (0.2)
  of its straight-sided value;
- conformal: every edge has one mid-edge node, shared by the elements of both materials;
- the .inp, .msh, .vtu, .vtk and .feb hold the same node positions;
- interior edges keep their midpoint; the nodes of interface and boundary edges are closer to the
  smooth interface than the straight midpoints: the reference is a fine linear mesh of the same
  label map (facet_distance 0.1 voxel, edge_length_factor 1.5: its interface triangles lie within
  0.1 voxel of the same smooth interfaces f_a = f_b, the run's indicator functions), the distance
  that of each node from the reference's triangles of its material pair;
- on the phantom, against its analytic spheres (femoral head radius 14 mm, inner head 11.5 mm,
  cartilage cap 16.5 mm), the mean radial offset of the straight midpoints from their edge ends
  (the chord's sag) is mostly gone for the curved nodes. (The mean |r - R| itself is not smaller:
  the smooth interface of the voxel map deviates from the analytic sphere by about 0.1 mm, as
  much as the sag; the curved nodes follow the smooth interface, as the vertices do.);
- on spheres_argmax every node stays in the volume's box and nodes of edges on a box face stay
  exactly in its plane."""
import os
import re
import xml.etree.ElementTree as ET

import meshio
import numpy as np

from exports_common import DATA, Checker, InpModel, mesh_volume
from quadratic_common import (SurfaceDistance, Tet10Mesh, interface_triangles, jacobian_figures, straight_dets,
                              tet10_dets)

check = Checker()
FRACTION = 0.2  # QuadraticCurvingParameters::minJacobianFraction
EXTS = [".inp", ".msh", ".vtu", ".vtk", ".feb"]


def inp_mesh(path):
    m = InpModel(open(path).read())
    ids = sorted(m.nodes)
    index = {n: i for i, n in enumerate(ids)}
    pts = np.array([m.nodes[n] for n in ids])
    eids = sorted(m.elements)
    cells = np.array([[index[n] for n in m.elements[e]] for e in eids])
    labels = np.array([m.label_of[e] for e in eids])
    return Tet10Mesh(pts, cells, labels)


def feb_points(path):
    root = ET.parse(path).getroot()
    nodes = root.find("Mesh").find("Nodes")
    return np.array([[float(v) for v in n.text.split(",")] for n in nodes])


def judge(name, source, extra=()):
    base, report, _ = mesh_volume(name, source, ["--set", "element_order=2"] + list(extra), exts=EXTS)
    counts = report["counts"]
    print("%s counts: %s" % (name, {k: v for k, v in counts.items() if k.startswith("quadratic_")}))
    check(counts.get("quadratic_curved_nodes", 0) > 50,
          "%s: the report counts %s curved mid-edge nodes (%s partly, %s kept straight of %s on surfaces)"
          % (name, counts.get("quadratic_curved_nodes"), counts.get("quadratic_partly_curved_nodes"),
             counts.get("quadratic_straight_kept"), counts.get("quadratic_surface_nodes")))
    mesh = inp_mesh(base + ".inp")
    x = mesh.points[mesh.cells]
    dets, straight = tet10_dets(x), straight_dets(x)
    fraction, scaled = jacobian_figures(x)
    check(bool((dets > 0).all()), "%s .inp: det J > 0 at the 11 points of all %d elements (%d not)"
          % (name, len(x), int((dets <= 0).any(axis=1).sum())))
    check(fraction >= FRACTION - 1e-9, "%s .inp: smallest det J / straight det J %.4f >= %.2f"
          % (name, fraction, FRACTION))
    check(abs(fraction - counts["quadratic_min_jacobian_fraction"]) < 1e-6
          and abs(scaled - counts["quadratic_worst_scaled_jacobian"]) < 1e-6,
          "%s: the report's Jacobian figures are the file's (fraction %.4f, worst scaled Jacobian %.4f)"
          % (name, fraction, scaled))
    m = meshio.read(base + ".msh")
    cells = np.concatenate([c.data for c in m.cells if c.type == "tetra10"])
    f2, _ = jacobian_figures(np.asarray(m.points)[cells])
    check(len(cells) == len(x) and f2 >= FRACTION - 1e-9,
          "%s .msh via meshio: %d tetra10, smallest det J / straight %.4f" % (name, len(cells), f2))
    # Conformal: one mid-edge node per edge, whatever material the element.
    shared = [e for e, p in mesh.edge_pairs.items() if any(a > 0 for a, b in p)]
    check(all(len(s) == 1 for s in mesh.mid.values()) and len(shared) > 100,
          "%s: every edge has one mid-edge node, the %d interface edges too" % (name, len(shared)))
    # Every format holds the same nodes.
    ref = mesh.points
    for ext in (".msh", ".vtu", ".vtk"):
        p = np.asarray(meshio.read(base + ext).points, float)
        check(p.shape == ref.shape and np.abs(p - ref).max() < 1e-9 * max(1, np.abs(ref).max()),
              "%s: %s has the .inp's %d nodes" % (name, ext, len(ref)))
    p = feb_points(base + ".feb")
    check(p.shape == ref.shape and np.abs(p - ref).max() < 1e-6 * max(1, np.abs(ref).max()),
          "%s: .feb has the .inp's %d nodes" % (name, len(ref)))
    # Interior edges straight; surface ones moved by less than a third of their length.
    moved = []
    interior_err = 0.0
    for (a, b), nodes in mesh.mid.items():
        d = np.linalg.norm(mesh.points[next(iter(nodes))] - 0.5 * (mesh.points[a] + mesh.points[b]))
        if (a, b) in mesh.edge_pairs:
            moved.append(d / np.linalg.norm(mesh.points[a] - mesh.points[b]))
        else:
            interior_err = max(interior_err, d)
    check(interior_err < 1e-9 and max(moved) <= 0.5,
          "%s: interior mid-edge nodes at their midpoint (max %.2g mm); surface ones moved at most %.3f "
          "edge lengths" % (name, interior_err, max(moved)))
    # Closer to the smooth interface than the straight midpoints: distance to a fine reference mesh.
    fine, _, _ = mesh_volume(name + "_reference", source, ["--set", "facet_distance=0.1", "--set", "edge_length_factor=1.5"],
                             exts=[".vtu"])
    f = meshio.read(fine + ".vtu")
    fcells = np.concatenate([c.data for c in f.cells if c.type == "tetra"])
    flabels = np.concatenate([d for c, d in zip(f.cells, f.cell_data["labels"]) if c.type == "tetra"])
    distance = SurfaceDistance(interface_triangles(np.asarray(f.points, float), fcells, flabels))
    straight_d, node_d = [], []
    for (a, b), pairs in mesh.edge_pairs.items():
        if len(pairs) != 1:
            continue
        pair = next(iter(pairs))
        s = distance(0.5 * (mesh.points[a] + mesh.points[b]), pair)
        n = distance(mesh.points[next(iter(mesh.mid[(a, b)]))], pair)
        if np.isfinite(s) and np.isfinite(n):
            straight_d.append(s)
            node_d.append(n)
    s, n = np.mean(straight_d), np.mean(node_d)
    print("%s: %d interface edges: mean distance from the reference interface: straight %.4f mm, curved %.4f mm"
          % (name, len(straight_d), s, n))
    check(len(straight_d) > 500 and n < 0.75 * s,
          "%s: mid-edge nodes closer to the smooth interface than straight midpoints (mean %.4f vs %.4f mm, "
          "%d edges)" % (name, n, s, len(straight_d)))
    return mesh, report


# The phantom, and its analytic spheres (LPS: voxel centre i at origin + i; the phantom's own
# coordinates put voxel centre i at i + 0.5, so its head centre (32, 32, 74) is (-0.5, -0.5, 83.5)).
mesh, _ = judge("phantom", None)
centre = np.array([-0.5, -0.5, 83.5])
spheres = {(1, 4): 14.0, (0, 4): 16.5, (1, 2): 11.5}
for pair, R in spheres.items():
    ends, straight, curved = [], [], []
    for (a, b), pairs in mesh.edge_pairs.items():
        if pairs != {pair}:
            continue
        pa, pb = mesh.points[a], mesh.points[b]
        if min(pa[2], pb[2]) < centre[2] + 4 or abs(np.linalg.norm(pa - centre) - R) > 0.6:
            continue  # away from the shaft, the stem and the cap's rim
        node = mesh.points[next(iter(mesh.mid[(a, b)]))]
        ends.append(0.5 * (np.linalg.norm(pa - centre) + np.linalg.norm(pb - centre)) - R)
        straight.append(np.linalg.norm(0.5 * (pa + pb) - centre) - R)
        curved.append(np.linalg.norm(node - centre) - R)
    e, s, c = np.mean(ends), np.mean(straight), np.mean(curved)
    print("sphere %s R=%.1f: %d edges; mean r - R: edge ends %.4f, straight %.4f, curved %.4f mm; mean |r - R|: "
          "straight %.4f, curved %.4f mm" % (pair, R, len(ends), e, s, c, np.mean(np.abs(straight)),
                                             np.mean(np.abs(curved))))
    check(len(ends) > 20 and abs(c - e) < abs(s - e),
          "phantom %s sphere R=%.1f mm: the chord's sag (straight midpoints %.4f mm inside their ends) is "
          "reduced to %.4f mm by curving" % (pair, R, e - s, e - c))

# A real volume with no background: every material reaches the box.
source = os.path.join(DATA, "spheres_argmax.nrrd")
mesh, report = judge("spheres_argmax", source)
lo, hi = -0.5, 27.5  # the box of 28^3 unit voxels, origin 0
check(mesh.points.min() >= lo - 1e-9 and mesh.points.max() <= hi + 1e-9,
      "spheres_argmax: every node in the volume's box [%g, %g] (min %.6g, max %.6g)"
      % (lo, hi, mesh.points.min(), mesh.points.max()))
off_plane = 0
on_plane = 0
for (a, b), nodes in mesh.mid.items():
    pa, pb, pm = mesh.points[a], mesh.points[b], mesh.points[next(iter(nodes))]
    for axis in range(3):
        for plane in (lo, hi):
            if abs(pa[axis] - plane) < 1e-9 and abs(pb[axis] - plane) < 1e-9:
                on_plane += 1
                off_plane += abs(pm[axis] - plane) > 1e-9
check(on_plane > 100 and off_plane == 0,
      "spheres_argmax: the %d mid-edge nodes of edges on a box face stay in its plane (%d do not)"
      % (on_plane, off_plane))
check(report["counts"].get("quadratic_box_plane_nodes", 0) > 0,
      "spheres_argmax: interface nodes on the box faces moved along the interface's trace (%s)"
      % report["counts"].get("quadratic_box_plane_nodes"))
check.finish()
