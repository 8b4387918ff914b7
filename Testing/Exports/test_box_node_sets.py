#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""The knee (9135902_00m_WB01, an oblique image: rotated about its third axis) is cut by its scan
box, and its cartilages touch. Meshed (coarse) with contact_pairs=2:4:
  - box-face node sets: the INP *NSETs and FEBio NodeSets BOX_<axis><MIN|MAX> are exactly the
    report's box_node_sets, every node of a set lies on its face of the box in the image's own
    voxel axes (index -0.5 or dims - 0.5, from the report's origin, spacing and direction), every
    mesh node on a box face is in its set, and the femur and tibia are cut at the two ends of the
    third axis (both Z sets hold nodes of those bones);
  - the FEBio contact: two Surfaces of the split pair with one tri3 per interface triangle, each
    face a face of an element of its own side and oriented out of it, coincident with a face of
    the other side, the sides sharing nodes only where a third material touches both; a SurfacePair naming them as primary (2) and secondary (4); a sliding-elastic
    contact on that pair."""
import os
import xml.etree.ElementTree as ET

import numpy as np

from exports_common import DATA, Checker, InpModel, mesh_volume

check = Checker()
knee = os.path.join(DATA, "9135902_00m_WB01.nii.gz")
base, report, _ = mesh_volume("knee_box", knee, exts=[".inp", ".feb"],
                              extra=["--preset", "coarse", "--set", "contact_pairs=2:4"])
geo = report["input"]
dims, spacing = np.array(geo["dims"], float), np.array(geo["spacing"], float)
origin, direction = np.array(geo["origin"], float), np.array(geo["direction"], float).reshape(3, 3)
box_sets = report.get("box_node_sets", {})
check(set(box_sets) >= {"BOX_ZMIN", "BOX_ZMAX"} and all(v > 0 for v in box_sets.values()),
      "the report lists non-empty box sets, Z at both ends %s" % box_sets)

# --- INP: nodes, elements with labels, NSETs ----------------------------------------------------
model = InpModel(open(base + ".inp").read())
nodes, label_of, elements = model.nodes, model.label_of, model.elements
nsets = {k: v for k, v in model.nsets.items() if k.startswith("BOX_")}
check({k: len(v) for k, v in nsets.items()} == box_sets,
      "INP *NSETs BOX_* = the report's sets %s" % {k: len(v) for k, v in nsets.items()})
ids = np.array(sorted(nodes))
xyz = np.array([nodes[i] for i in ids])
# Physical LPS -> continuous voxel index: index = (D^-1 (x - origin)) / spacing.
index = np.linalg.solve(direction, (xyz - origin).T).T / spacing
tol = 1e-3
for a, axis in enumerate("XYZ"):
    for side, plane in (("MIN", -0.5), ("MAX", dims[a] - 0.5)):
        name = "BOX_%s%s" % (axis, side)
        on = set(ids[np.abs(index[:, a] - plane) < tol].tolist())
        got = set(nsets.get(name, []))
        check(got == on, "%s: %d nodes, exactly the %d mesh nodes within %g voxel of index %g on axis %d"
              % (name, len(got), len(on), tol, plane, a))
node_labels = {}
for e, el in elements.items():
    for n in el:
        node_labels.setdefault(n, set()).add(label_of[e])
for name in ("BOX_ZMIN", "BOX_ZMAX"):
    labels = set().union(*(node_labels[n] for n in nsets.get(name, []))) if nsets.get(name) else set()
    check(labels & {1, 3}, "%s holds nodes of a bone the box cuts (labels %s)" % (name, sorted(labels)))

# --- FEBio: NodeSets and the contact --------------------------------------------------------------
feb = ET.parse(base + ".feb").getroot()
mesh = feb.find("Mesh")
feb_sets = {s.get("name"): [int(x) for x in s.text.replace("\n", "").split(",") if x.strip()]
            for s in mesh.findall("NodeSet") if s.get("name", "").startswith("BOX_")}
check({k: sorted(v) for k, v in feb_sets.items()} == {k: sorted(v) for k, v in nsets.items()},
      "FEBio NodeSets BOX_* = the INP's")
fnodes = {int(n.get("id")): np.array([float(x) for x in n.text.split(",")]) for n in mesh.find("Nodes")}
felem, flabel = {}, {}
names = {}
for l in report["input"]["labels"]:
    names[l["id"]] = l["name"]
for block in mesh.findall("Elements"):
    for e in block:
        felem[int(e.get("id"))] = [int(x) for x in e.text.split(",")]
        flabel[int(e.get("id"))] = block.get("name")
pairs = mesh.findall("SurfacePair")
check(len(pairs) == 1, "one SurfacePair")
surfaces = {s.get("name"): s for s in mesh.findall("Surface")}
if pairs:
    p = pairs[0]
    prim, sec = p.findtext("primary"), p.findtext("secondary")
    check(prim in surfaces and sec in surfaces and prim.startswith(p.get("name")) and sec.startswith(p.get("name")),
          "SurfacePair %s: primary %s and secondary %s are Surfaces" % (p.get("name"), prim, sec))
    contacts = feb.findall("./Contact/contact")
    check(len(contacts) == 1 and contacts[0].get("type") == "sliding-elastic"
          and contacts[0].get("surface_pair") == p.get("name"),
          "a sliding-elastic contact on the pair")
    n_tri = report["contact_pairs"][0]["interface_triangles"]
    # Every face of each side: a face of one element of its domain, oriented out of it.
    by_face = {}
    for e, el in felem.items():
        for k in range(4):
            by_face.setdefault(tuple(sorted(el[:k] + el[k + 1:])), []).append(e)
    keys = {}
    for name in (prim, sec):
        faces = [[int(x) for x in t.text.split(",")] for t in surfaces[name]]
        domain = name[len(p.get("name")) + 2:]
        ok_own = ok_out = 0
        keys[name] = set()
        for f in faces:
            owners = [e for e in by_face.get(tuple(sorted(f)), []) if flabel[e] == domain]
            if len(owners) == 1:
                ok_own += 1
                el = felem[owners[0]]
                d = fnodes[(set(el) - set(f)).pop()]
                a, b, c = (fnodes[n] for n in f)
                ok_out += np.dot(np.cross(b - a, c - a), a - d) > 0
            keys[name].add(tuple(sorted(tuple(np.round(fnodes[n], 9)) for n in f)))
        check(len(faces) == n_tri and ok_own == n_tri and ok_out == n_tri,
              "%s: %d tri3, %d faces of one %s element, %d oriented outward (interface triangles %d)"
              % (name, len(faces), ok_own, domain, ok_out, n_tri))
    check(keys[prim] == keys[sec], "the two sides' faces coincide")
    # The sides share no node, except where a third material touches both (it keeps them joined).
    side_nodes = [{int(x) for t in surfaces[n] for x in t.text.split(",")} for n in (prim, sec)]
    third = {n for e, el in felem.items() if flabel[e] not in (prim[len(p.get("name")) + 2:],
                                                              sec[len(p.get("name")) + 2:]) for n in el}
    shared = side_nodes[0] & side_nodes[1]
    check(shared <= third and len(shared) < len(side_nodes[0]) // 10,
          "the two sides share %d of %d nodes, all on a third material" % (len(shared), len(side_nodes[0])))
check.finish()
