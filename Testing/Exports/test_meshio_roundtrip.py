#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""The exports of the CLI read back by real readers, for the built-in phantom and a real volume
(spheres_argmax.nrrd): meshio (Debian python3-meshio) reads the .vtu, legacy .vtk, .msh, .mesh and
.inp (and the .stl); every reader must give the very same points (bit for bit), the same tets and
the same per-tet labels as the .vtu, and the materials of the run report. The .vtu field data
(material ids and names, version, provenance) is decoded independently of VTK too.

meshio cannot parse VTK's string arrays ("Illegal data type 'String'", meshio issue #1370), so the
.vtu holds none: text is written as 0-terminated UTF-8 bytes in UInt8 arrays, and there is no
SPACE tag (3D Slicer reads it only as a string array; without it Slicer takes the file as LPS).
meshio must read the .vtu as it is, material names included."""
import os
import re
import xml.etree.ElementTree as ET

import meshio
import numpy as np

from exports_common import DATA, Checker, mesh_volume
from vtu_decode import read_vtu

check = Checker()


def text_list(values):
    """Strings of a text field array: UTF-8 bytes (UInt8), each string followed by a 0 byte."""
    if values is None:
        return None
    raw = bytes(np.asarray(values, dtype=np.uint8).reshape(-1))
    if not raw.endswith(b"\0"):
        return ["<not 0-terminated>"]
    return [s.decode("utf-8") for s in raw[:-1].split(b"\0")]


def blocks(m, kind, key=None):
    """Concatenated cells of type `kind` (and their cell data `key`)."""
    idx = [i for i, b in enumerate(m.cells) if b.type == kind]
    cells = np.concatenate([m.cells[i].data for i in idx]) if idx else np.zeros((0, 3 if kind == "triangle" else 4), int)
    if key is None:
        return cells
    data = np.concatenate([np.asarray(m.cell_data[key][i]).reshape(-1) for i in idx]).astype(np.int64) if idx else None
    return cells, data


def align(ref_tets, tets):
    """Permutation p with tets[p] == ref_tets up to the vertex order within each tet (None if the
    tet sets differ)."""
    def order(t):
        s = np.sort(t, axis=1)
        return np.lexsort(s.T[::-1]), s
    ro, rs = order(ref_tets)
    to, ts = order(tets)
    if len(rs) != len(ts) or not np.array_equal(rs[ro], ts[to]):
        return None
    p = np.empty(len(ref_tets), int)
    p[ro] = to
    return p


def face_keys(tets, n):
    """Sorted-vertex keys of the 4 faces of each tet, shape (T, 4)."""
    f = np.stack([tets[:, [1, 2, 3]], tets[:, [0, 2, 3]], tets[:, [0, 1, 3]], tets[:, [0, 1, 2]]], axis=1)
    f = np.sort(f, axis=2).astype(np.int64)
    return (f[..., 0] * n + f[..., 1]) * n + f[..., 2]


def tri_keys(tris, n):
    s = np.sort(tris, axis=1).astype(np.int64)
    return (s[:, 0] * n + s[:, 1]) * n + s[:, 2]


for name, source in (("phantom", None), ("spheres", os.path.join(DATA, "spheres_argmax.nrrd"))):
    base, report, src = mesh_volume(name, source)
    n_tets = int(report["counts"]["tets"])
    n_pts = int(report["counts"]["vertices"])
    mats = sorted((l["id"], l["name"]) for l in report["input"]["labels"] if l["in_mesh"])
    ids = [i for i, _ in mats]
    print("== %s: %d points, %d tets, materials %s" % (name, n_pts, n_tets, mats))

    # --- .vtu: independent decoder (field data) and meshio ------------------------------------
    root, arrays, field = read_vtu(base + ".vtu")
    types = {a.get("Name"): a.get("type") for a in root.iter("DataArray")}
    check("String" not in types.values(), "%s: no String array in the VTU (%s)" % (name, types))
    check("SPACE" not in field, "%s: no SPACE tag in the VTU field data" % name)
    check(list(map(int, field.get("MaterialIds", []))) == ids, "%s: VTU MaterialIds = report %s" % (name, ids))
    check(text_list(field.get("MaterialNames")) == [n for _, n in mats],
          "%s: VTU MaterialNames = report (%s)" % (name, text_list(field.get("MaterialNames"))))
    check(text_list(field.get("FEMesherVersion")) == [report["femesher_version"]], "%s: VTU FEMesherVersion" % name)
    prov = text_list(field.get("Provenance"))
    check(len(prov) == 1 and os.path.basename(src) in prov[0], "%s: VTU Provenance names the input (%s)" % (name, prov))
    check(bool((arrays["types"] == 10).all()), "%s: VTU cells are all VTK_TETRA" % name)
    check(arrays["labels"].dtype.itemsize == 4 and arrays["labels"].dtype.kind == "i", "%s: VTU labels are int32" % name)
    # meshio's own VTU reader, on the file as written (meshio.read prints and exits on an error).
    try:
        vtu = meshio.vtu.read(base + ".vtu")
    except meshio.ReadError as e:
        check(False, "%s: meshio reads the VTU (%s)" % (name, e))
        continue
    P = vtu.points
    T, L = blocks(vtu, "tetra", "labels")
    check(len(P) == n_pts and len(T) == n_tets, "%s: meshio reads the VTU: %d points, %d tets" % (name, len(P), len(T)))
    check(list(map(int, np.asarray(vtu.field_data.get("MaterialIds", [])).reshape(-1))) == ids
          and text_list(vtu.field_data.get("MaterialNames")) == [n for _, n in mats],
          "%s: meshio's VTU field data: material ids %s and names %s" % (
              name, ids, text_list(vtu.field_data.get("MaterialNames"))))
    check(np.array_equal(P, arrays["Points"]) and np.array_equal(T.reshape(-1), arrays["connectivity"]),
          "%s: meshio and the independent decoder agree on the VTU" % name)
    check(sorted(set(L.tolist())) == ids, "%s: VTU label set %s = report" % (name, sorted(set(L.tolist()))))
    check(bool(np.isfinite(P).all()), "%s: coordinates finite" % name)
    vol = np.einsum("ij,ij->i", P[T[:, 1]] - P[T[:, 0]], np.cross(P[T[:, 2]] - P[T[:, 0]], P[T[:, 3]] - P[T[:, 0]]))
    check(bool((vol > 0).all()), "%s: every tet positively oriented (%d not)" % (name, int((vol <= 0).sum())))
    n = len(P) + 1

    # --- legacy .vtk (meshio) ------------------------------------------------------------------
    vtk = meshio.read(base + ".vtk")
    Tk, Lk = blocks(vtk, "tetra", "labels")
    check(np.array_equal(vtk.points, P) and np.array_equal(Tk, T) and np.array_equal(Lk, L),
          "%s: legacy VTK = VTU (points, tets, labels)" % name)
    check(open(base + ".vtk", "rb").read(200).find(b"SPACE=LPS") > 0, "%s: legacy VTK header says SPACE=LPS" % name)

    # --- .msh (meshio) ---------------------------------------------------------------------------
    msh = meshio.read(base + ".msh")
    Tm, Lm = blocks(msh, "tetra", "gmsh:physical")
    check(np.array_equal(msh.points, P), "%s: MSH points = VTU points, bit for bit" % name)
    p = align(T, Tm)
    check(p is not None, "%s: MSH has the same %d tets" % (name, len(Tm)))
    if p is not None:
        check(np.array_equal(Tm[p], T), "%s: MSH keeps each tet's vertex order (orientation)" % name)
        check(np.array_equal(Lm[p], L), "%s: MSH physical volume of every tet = VTU label" % name)
    phys = {k: (int(v[0]), int(v[1])) for k, v in msh.field_data.items()}
    vol_names = sorted((t, k) for k, (t, d) in phys.items() if d == 3)
    check(vol_names == [(i, nm) for i, nm in mats], "%s: MSH physical volumes named by material %s" % (name, vol_names))
    surf = {t: k for k, (t, d) in phys.items() if d == 2}
    check(all(re.fullmatch(r"(interface_-?\d+_-?\d+|boundary_-?\d+)", k) for k in surf.values())
          and any(k.startswith("interface_") for k in surf.values()) and any(k.startswith("boundary_") for k in surf.values()),
          "%s: MSH physical surfaces interface_a_b / boundary_a (%d)" % (name, len(surf)))
    tris, tlab = blocks(msh, "triangle", "gmsh:physical")
    # Every interface triangle is a face of one tet of each side; boundary ones of one tet.
    fk = face_keys(T, n)
    owner_label = np.repeat(L, 4)
    order = np.argsort(fk.reshape(-1), kind="stable")
    fsorted = fk.reshape(-1)[order]
    tk = tri_keys(tris, n)
    lo = np.searchsorted(fsorted, tk, "left")
    hi = np.searchsorted(fsorted, tk, "right")
    ok = True
    for t, i, j in zip(tlab, lo, hi):
        lab_name = surf[t]
        m_ = re.fullmatch(r"interface_(-?\d+)_(-?\d+)", lab_name)
        sides = sorted(owner_label[order[i:j]].tolist())
        want = sorted([int(m_.group(1)), int(m_.group(2))]) if m_ else [int(lab_name.split("_")[1])]
        if sides != want:
            ok = False
            print("   triangle of %s has tets of labels %s" % (lab_name, sides))
            break
    check(ok, "%s: every MSH interface triangle lies between tets of its two materials (%d triangles)" % (name, len(tris)))
    # Conversely, every face between two materials (or on the boundary) is an MSH triangle.
    uk, first, counts = np.unique(fsorted, return_index=True, return_counts=True)
    lab_first = owner_label[order[first]]
    lab_last = owner_label[order[first + counts - 1]]
    expected = int((counts == 1).sum() + ((counts == 2) & (lab_first != lab_last)).sum())
    check(expected == len(tris), "%s: MSH has all %d interface/boundary faces (has %d)" % (name, expected, len(tris)))
    boundary_nodes = set(np.unique(tris[np.array([surf[t].startswith("boundary_") for t in tlab])]).tolist())

    # --- .mesh (meshio, Medit) -----------------------------------------------------------------
    med = meshio.read(base + ".mesh")
    Td, Ld = blocks(med, "tetra", "medit:ref")
    check(np.array_equal(med.points, P), "%s: Medit points = VTU points, bit for bit" % name)
    check(np.array_equal(Td, T) and np.array_equal(Ld, L), "%s: Medit tets and refs = VTU tets and labels" % name)
    check(len(blocks(med, "triangle")) == len(tris), "%s: Medit has the %d interface triangles" % (name, len(tris)))

    # --- .inp (meshio, Abaqus) -----------------------------------------------------------------
    inp = meshio.read(base + ".inp")
    Ti = blocks(inp, "tetra")
    # CalculiX reads at most 20 characters per field: tiny coordinates lose their last digits.
    same_shape = inp.points.shape == P.shape
    err = np.abs(inp.points - P).max() / max(1.0, np.abs(P).max()) if same_shape else np.inf
    check(err <= 1e-14, "%s: INP nodes = VTU points to 1e-14 relative (20-character fields; %.3g)" % (name, err))
    check(align(T, Ti) is not None, "%s: INP has the same tets" % name)
    elsets = sorted(k for k in inp.cell_sets if k.startswith("M"))
    check(len(elsets) == len(ids), "%s: INP has an element set per material %s" % (name, elsets))
    check(set(int(i) for i in inp.point_sets.get("BOUNDARY", [])) == boundary_nodes,
          "%s: INP NSET BOUNDARY = nodes of the MSH boundary triangles (%d)" % (name, len(boundary_nodes)))

    # --- .feb (FEBio XML, format 4.0; its full check is test_febio_export.py) ------------------
    feb = ET.parse(base + ".feb").getroot()
    check(feb.tag == "febio_spec" and feb.get("version") == "4.0", "%s: FEBio 4.0 document" % name)
    elems = feb.findall("./Mesh/Elements/elem")
    check([int(e.get("id")) for e in elems] == list(range(1, n_tets + 1)), "%s: FEBio element ids 1..%d over all domains" % (name, n_tets))
    check(len(feb.findall("./Mesh/Nodes/node")) == n_pts, "%s: FEBio nodes" % name)
    fm = feb.findall("./Material/material")
    check(len(fm) == len(mats) and len(set(m.get("name") for m in fm)) == len(mats), "%s: FEBio material per label, names unique" % name)
    doms = feb.findall("./Mesh/Elements")
    per_label = sorted(int((L == i).sum()) for i in ids)
    check(sorted(len(d.findall("elem")) for d in doms) == per_label, "%s: FEBio domain sizes = tets per label" % name)
    check(len(feb.findall("./Mesh/Surface")) == len(surf), "%s: FEBio has a surface per MSH surface (%d)" % (name, len(surf)))

    # --- .stl ------------------------------------------------------------------------------------
    text = open(base + ".stl").read()
    solids = re.findall(r"^solid (\S+)", text, re.M)
    check(sorted(solids) == sorted(surf.values()), "%s: STL has one solid per MSH surface" % name)
    check(text.count("facet normal") == len(tris), "%s: STL has the %d interface triangles" % (name, len(tris)))
    stl = meshio.read(base + ".stl")
    check(len(blocks(stl, "triangle")) == len(tris), "%s: meshio reads the STL" % name)

check.finish()
