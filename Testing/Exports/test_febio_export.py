# SPDX-License-Identifier: GPL-3.0-or-later
"""The FEBio export (.feb, format 4.0) checked with a real XML parser against facts computed
independently here from the Gmsh export of the same run (read with meshio): ids, domains,
materials with the user's properties, every interface and outer-boundary surface face for face
(vertex sets, counts, orientation), node sets. The structure follows FEBio's user manual, format
4.0 (Free Format Overview: Module, Control, Material, Mesh and MeshDomains are required; Material
Section: id and name; Mesh Section: Nodes, Elements with type and a unique name, NodeSet,
Surface; MeshDomains Section: SolidDomain name/mat) and FEBio's 4.0 reader
(FEBioXML/FEBioMeshSection4.cpp, FEBioMeshDomainsSection4.cpp, FEBioMaterialSection.cpp)."""
import os
import re
import sys
import xml.etree.ElementTree as ET

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from exports_common import Checker, mesh_volume  # noqa: E402

import meshio  # noqa: E402

check = Checker()
IDENT = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")

# The phantom's labels: 1 cortical bone, 2 trabecular bone, 3 marrow, 4 cartilage, 5 implant.
# Properties for 1, 4, 5; names: 5 from --set, the rest are the phantom's own.
PROPS = {1: (17000.0, 0.3, 1.9e-9), 4: (10.0, 0.45, 1.1e-9), 5: (110000.0, 0.34, 4.4e-9)}
extra = []
for label, (E, nu, rho) in PROPS.items():
    extra += ["--set", "material.%d.E=%r" % (label, E), "--set", "material.%d.nu=%r" % (label, nu),
              "--set", "material.%d.density=%r" % (label, rho)]
extra += ["--set", "material.5.name=Ti-6Al-4V stem (uncemented)"]
base, report, _ = mesh_volume("febio", None, extra)

# --- independent facts from the .msh (meshio) --------------------------------------------------
msh = meshio.read(base + ".msh")
P = msh.points
T = np.concatenate([c.data for c in msh.cells if c.type == "tetra"])
L = np.concatenate([d for c, d in zip(msh.cells, msh.cell_data["gmsh:physical"]) if c.type == "tetra"])
labels = sorted(set(L.tolist()))
report_names = {l["id"]: l["name"] for l in report["input"]["labels"] if l["in_mesh"]}
print("== phantom: %d points, %d tets, labels %s" % (len(P), len(T), report_names))
check(report_names.get(5) == "Ti-6Al-4V stem (uncemented)", "report names label 5 as the user did (%s)" % report_names.get(5))

faces = {}
for t, tet in enumerate(T):
    for f in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)):
        faces.setdefault(tuple(sorted(tet[list(f)])), []).append(t)
expected = {}  # (labelA, labelB or 'boundary') -> set of sorted faces
for key, owners in faces.items():
    ls = sorted(int(L[t]) for t in owners)
    if len(owners) == 1:
        expected.setdefault((ls[0], "boundary"), set()).add(key)
    elif ls[0] != ls[1]:
        expected.setdefault((ls[0], ls[1]), set()).add(key)
check(all(len(o) <= 2 for o in faces.values()), "no face of the .msh mesh has more than two tets")

# --- the .feb ----------------------------------------------------------------------------------
root = ET.parse(base + ".feb").getroot()
check(root.tag == "febio_spec" and root.get("version") == "4.0", "febio_spec version 4.0 (%s)" % root.get("version"))
sections = [c.tag for c in root]
check(sections and sections[0] == "Module" and root.find("Module").get("type") == "solid",
      "first section is Module type=solid (%s)" % sections[:1])
for s in ("Control", "Material", "Mesh", "MeshDomains"):
    check(sections.count(s) == 1, "one %s section (required by FEBio 4.0)" % s)
ctrl = root.find("Control")
check(ctrl is not None and ctrl.findtext("analysis") == "STATIC" and ctrl.find("solver") is not None
      and int(ctrl.findtext("time_steps")) > 0 and float(ctrl.findtext("step_size")) > 0,
      "Control: a static step with time_steps, step_size and a solver")

mats = root.findall("./Material/material")
check([int(m.get("id")) for m in mats] == list(range(1, len(mats) + 1)), "material ids 1..%d in order" % len(mats))
mat_names = [m.get("name") for m in mats]
check(len(set(mat_names)) == len(mat_names), "material names unique %s" % mat_names)
check(all(IDENT.match(n) and "__" not in n for n in mat_names), "material names XML-safe identifiers")
mat_by_name = {m.get("name"): m for m in mats}

nodes = root.findall("./Mesh/Nodes/node")
nid = [int(n.get("id")) for n in nodes]
check(nid == list(range(1, len(P) + 1)), "node ids 1..%d increasing" % len(P))
X = np.array([[float(v) for v in n.text.split(",")] for n in nodes])
check(X.shape == P.shape and np.abs(X - P).max() <= 1e-12 * max(1.0, np.abs(P).max()),
      "node coordinates = .msh points")

blocks = root.findall("./Mesh/Elements")
all_ids, feb_tets, domain_label = [], [], {}
ok_refs = True
for b in blocks:
    check(b.get("type") == "tet4", "Elements %s type tet4" % b.get("name"))
    ids = [int(e.get("id")) for e in b.findall("elem")]
    check(ids == sorted(ids), "element ids increase within %s" % b.get("name"))
    conn = np.array([[int(v) for v in e.text.split(",")] for e in b.findall("elem")])
    ok_refs &= bool(((conn >= 1) & (conn <= len(P))).all())
    all_ids += ids
    # The domain's label: the .msh label of its tets (all one label).
    pos = {tuple(sorted(t)): i for i, t in enumerate(T)}
    idx = [pos.get(tuple(sorted(c - 1))) for c in conn]
    found = [i for i in idx if i is not None]
    dl = sorted(set(int(L[i]) for i in found))
    check(len(found) == len(conn) and len(dl) == 1, "domain %s: every tet is a .msh tet of one label %s" % (b.get("name"), dl))
    if dl:
        domain_label[b.get("name")] = dl[0]
    feb_tets.append(conn - 1)
check(ok_refs, "every node id an element refers to exists")
check(sorted(all_ids) == list(range(1, len(T) + 1)) and len(set(all_ids)) == len(all_ids),
      "element ids unique over the file and exactly 1..%d" % len(T))
check(sorted(domain_label.values()) == labels, "one domain per label %s" % labels)
Tf = np.concatenate(feb_tets)
a, b_, c, d = (X[Tf[:, k]] for k in range(4))
vol = np.einsum("ij,ij->i", b_ - a, np.cross(c - a, d - a))
check(bool((vol > 0).all()), "every tet4 positively oriented in FEBio's node order (%d not)" % int((vol <= 0).sum()))

doms = root.findall("./MeshDomains/SolidDomain")
check(sorted(d.get("name") for d in doms) == sorted(domain_label), "a SolidDomain per Elements block")
name_to_label = dict(domain_label)
for d in doms:
    check(d.get("mat") in mat_by_name, "SolidDomain %s: its material %s exists" % (d.get("name"), d.get("mat")))
    lab = domain_label.get(d.get("name"))
    m = mat_by_name.get(d.get("mat"))
    if m is None or lab is None:
        continue
    E, nu, rho = PROPS.get(lab, (1000.0, 0.3, 1e-9))
    got = (float(m.findtext("E")), float(m.findtext("v")), float(m.findtext("density")))
    check(got == (E, nu, rho), "label %d: material %s has E, v, density %s = %s" % (lab, m.get("name"), got, (E, nu, rho)))
    # The material's name comes from the material's name (sanitised), the domain's too.
    want = re.sub(r"[^A-Za-z0-9]+", "_", report_names[lab]).strip("_")
    check(m.get("name").startswith(want[:40]), "label %d: material named after '%s' (%s)" % (lab, report_names[lab], m.get("name")))

# Surfaces: names <a>__<b> / <a>__boundary, faces exactly the interface faces, outward from a.
surfs = root.findall("./Mesh/Surface")
snames = [s.get("name") for s in surfs]
check(len(set(snames)) == len(snames) and all(IDENT.match(n) for n in snames), "surface names unique, XML-safe")
got_keys = set()
for s in surfs:
    parts = s.get("name").split("__")
    la = name_to_label.get(parts[0])
    lb = "boundary" if len(parts) == 2 and parts[1] == "boundary" else name_to_label.get(parts[1]) if len(parts) == 2 else None
    key = (la, lb)
    got_keys.add(key)
    tris = np.array([[int(v) for v in f.text.split(",")] for f in s.findall("tri3")]) - 1
    check(all(f.tag == "tri3" for f in s) and [int(f.get("id")) for f in s] == list(range(1, len(tris) + 1)),
          "surface %s: tri3 faces with ids 1..%d" % (s.get("name"), len(tris)))
    fs = [tuple(sorted(t)) for t in tris]
    want = expected.get(key, set())
    check(len(fs) == len(set(fs)) == len(want) and set(fs) == want,
          "surface %s = the %d mesh faces of %s (has %d)" % (s.get("name"), len(want), key, len(fs)))
    # Every face is a face of a tet of material a, and points away from it.
    bad = 0
    for tri, f in zip(tris, fs):
        owner = [t for t in faces.get(f, []) if int(L[t]) == la]
        if len(owner) != 1:
            bad += 1
            continue
        tet = T[owner[0]]
        apex = [v for v in tet if v not in f][0]
        n = np.cross(P[tri[1]] - P[tri[0]], P[tri[2]] - P[tri[0]])
        bad += int(np.dot(n, P[apex] - P[tri[0]]) >= 0)
    check(bad == 0, "surface %s: every face belongs to a tet of label %s and is oriented outward from it (%d not)" % (s.get("name"), la, bad))
check(got_keys == set(expected), "a surface for every interface and outer boundary: %d of %d" % (len(got_keys & set(expected)), len(expected)))

# Node sets: per material, per interface, per outer boundary.
nsets = {n.get("name"): set(int(v) - 1 for v in re.split(r"[,\s]+", n.text.strip()) if v) for n in root.findall("./Mesh/NodeSet")}
check(all(IDENT.match(n) for n in nsets), "node-set names XML-safe")
for name, lab in name_to_label.items():
    want = set(T[L == lab].ravel().tolist())
    check(nsets.get("nodes__" + name) == want, "node set nodes__%s = the %d nodes of label %d" % (name, len(want), lab))
for s in snames:
    parts = s.split("__")
    key = (name_to_label.get(parts[0]), "boundary" if parts[1] == "boundary" else name_to_label.get(parts[1]))
    want = set(v for f in expected.get(key, ()) for v in f)
    check(nsets.get("nodes__" + s) == want, "node set nodes__%s = the %d nodes of its faces" % (s, len(want)))
check(len(nsets) == len(name_to_label) + len(expected), "no other node sets (%d)" % len(nsets))

# The default-properties warning names the materials the user gave nothing for (2 and 3).
warns = [w for w in report.get("warnings", []) if "built-in default" in w]
check(len(warns) == 2 and all("label 2 (" in w and "label 3 (" in w and "label 1 (" not in w for w in warns),
      "report warns (once per deck: .inp, .feb) about labels 2 and 3 only: %s" % warns)

# --- element_order=2: tet10 elements, tri6 surfaces, node sets with the mid-edge nodes ------------
# FEBio's tet10 (FETet10 shape functions: H[4..9] = 4ru, 4rs, 4su, 4tu, 4rt, 4st) puts nodes 5..10
# on edges 1-2, 2-3, 3-1, 1-4, 2-4, 3-4; tri6 (FETri6) nodes 4..6 on edges 1-2, 2-3, 3-1. meshio
# reads the .msh tetra10 in that (VTK) order too, so the elements must match node for node.
base2, report2, _ = mesh_volume("febio_tet10", None, extra + ["--set", "element_order=2"], exts=[".msh", ".feb"])
msh2 = meshio.read(base2 + ".msh")
P2 = msh2.points
T2 = np.concatenate([c.data for c in msh2.cells if c.type == "tetra10"])
L2 = np.concatenate([d for c, d in zip(msh2.cells, msh2.cell_data["gmsh:physical"]) if c.type == "tetra10"])
root2 = ET.parse(base2 + ".feb").getroot()
X2 = np.array([[float(v) for v in n.text.split(",")] for n in root2.findall("./Mesh/Nodes/node")])
check(len(T2) == len(T) and X2.shape == P2.shape and np.abs(X2 - P2).max() <= 1e-12 * max(1.0, np.abs(P2).max()),
      "tet10: as many elements as tet4 (%d) and node coordinates = .msh points (%d nodes)" % (len(T2), len(P2)))
EDGES = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]
blocks2 = root2.findall("./Mesh/Elements")
check(all(b.get("type") == "tet10" for b in blocks2), "tet10: every Elements block has type tet10")
conn2 = np.concatenate([np.array([[int(v) for v in e.text.split(",")] for e in b.findall("elem")]) for b in blocks2]) - 1
ids2 = [int(e.get("id")) for b in blocks2 for e in b.findall("elem")]
check(conn2.shape == (len(T2), 10) and ids2 == list(range(1, len(T2) + 1)), "tet10: 10 nodes per element, ids 1..%d" % len(T2))
check(set(map(tuple, conn2.tolist())) == set(map(tuple, T2.tolist())),
      "tet10: every element = a .msh tetra10 node for node (FEBio order = meshio's VTK order)")
x = X2[conn2]
# Edges on a face of one element or between two materials: their nodes are curved onto the smooth
# interfaces (test_quadratic_curved.py), within half the edge of the midpoint; others at it.
surface_edges = set()
owners2 = {}
for t, tet in enumerate(conn2):
    for f in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)):
        owners2.setdefault(tuple(sorted(tet[list(f)])), []).append(int(L2[t]))
for f, ls in owners2.items():
    if len(ls) == 1 or ls[0] != ls[1]:
        surface_edges.update({(f[0], f[1]), (f[1], f[2]), (f[0], f[2])})
err, ratio = 0.0, 0.0
for k, (a, b) in enumerate(EDGES):
    d = np.linalg.norm(x[:, 4 + k] - 0.5 * (x[:, a] + x[:, b]), axis=1) / np.linalg.norm(x[:, a] - x[:, b], axis=1)
    on = np.array([(min(c[a], c[b]), max(c[a], c[b])) in surface_edges for c in conn2])
    err = max(err, float(d[~on].max(initial=0)))
    ratio = max(ratio, float(d[on].max(initial=0)))
check(err <= 1e-9 and ratio <= 0.5,
      "tet10: nodes 5..10 on edges 1-2, 2-3, 3-1, 1-4, 2-4, 3-4: interior ones at the midpoints (%.3g), "
      "interface ones within %.3f edge lengths" % (err, ratio))
vol = np.einsum("ij,ij->i", x[:, 1] - x[:, 0], np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 0]))
check(bool((vol > 0).all()), "tet10: every element positively oriented (%d not)" % int((vol <= 0).sum()))
mid_of = {}
for c in conn2:
    for k, (a, b) in enumerate(EDGES):
        mid_of.setdefault((min(c[a], c[b]), max(c[a], c[b])), set()).add(int(c[4 + k]))
check(all(len(v) == 1 for v in mid_of.values()) and len(P2) == len(np.unique(conn2[:, :4])) + len(mid_of),
      "tet10: one mid-edge node per unique edge, shared by all elements around it")
faces2 = {}
for t, tet in enumerate(T2):
    for f in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)):
        faces2.setdefault(tuple(sorted(tet[list(f)])), []).append(t)
expected2 = {}
for key, owners in faces2.items():
    ls = sorted(int(L2[t]) for t in owners)
    if len(owners) == 1:
        expected2.setdefault((ls[0], "boundary"), set()).add(key)
    elif ls[0] != ls[1]:
        expected2.setdefault((ls[0], ls[1]), set()).add(key)
name_to_label2 = {}
for b in blocks2:
    first = [int(v) - 1 for v in b.find("elem").text.split(",")]
    idx = [i for i, t in enumerate(T2) if list(t) == first]
    name_to_label2[b.get("name")] = int(L2[idx[0]]) if idx else None
surfs2 = root2.findall("./Mesh/Surface")
bad_faces, bad_sets, keys2 = 0, 0, set()
nsets2 = {n.get("name"): set(int(v) - 1 for v in re.split(r"[,\s]+", n.text.strip()) if v) for n in root2.findall("./Mesh/NodeSet")}
for sf in surfs2:
    parts = sf.get("name").split("__")
    key = (name_to_label2.get(parts[0]), "boundary" if parts[1] == "boundary" else name_to_label2.get(parts[1]))
    keys2.add(key)
    check(len(sf) > 0 and all(f.tag == "tri6" for f in sf), "tet10: surface %s has tri6 faces" % sf.get("name"))
    tri = np.array([[int(v) for v in f.text.split(",")] for f in sf]) - 1
    fs = set(tuple(sorted(t[:3])) for t in tri)
    # Nodes 4..6: the elements' mid-edge nodes of edges 1-2, 2-3, 3-1.
    e = sum(mid_of.get((min(t[a], t[b]), max(t[a], t[b]))) != {int(t[3 + k])}
            for t in tri for k, (a, b) in enumerate([(0, 1), (1, 2), (2, 0)]))
    bad_faces += int(fs != expected2.get(key, set()) or e > 0)
    bad_sets += int(nsets2.get("nodes__" + sf.get("name")) != set(tri.ravel().tolist()))
check(keys2 == set(expected2) and bad_faces == 0,
      "tet10: a tri6 surface per interface and boundary, corners = the mesh faces, nodes 4..6 the elements' mid-edge nodes (%d wrong)" % bad_faces)
check(bad_sets == 0, "tet10: every surface's NodeSet holds its faces' 6 nodes (%d wrong)" % bad_sets)
for name, lab in name_to_label2.items():
    want = set(T2[L2 == lab].ravel().tolist())
    check(nsets2.get("nodes__" + name) == want, "tet10: node set nodes__%s = the %d nodes (corners and mid-edge) of label %s" % (name, len(want), lab))

check.finish()
