#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""meshio (Debian python3-meshio) reads the legacy VTK, Gmsh MSH and Medit exports of the phantom
and of a real volume: same points, same tets, same per-tet labels, materials as in the run report.

The .vtu carries Slicer's coordinate-system tag as a string field array (SPACE = LPS), which
meshio cannot parse ("Illegal data type 'String'", meshio 5); the .vtu is read back by VTK's own
reader through `femesher quality` instead, and the legacy .vtk (Slicer's "SPACE=LPS" header) is
the meshio-readable VTK file."""
import json
import os
import subprocess

import meshio
import numpy as np

from exports_common import CLI, DATA, Checker, mesh_volume

check = Checker()


def tets_of(m):
    blocks = [b.data for b in m.cells if b.type == "tetra"]
    return np.concatenate(blocks) if blocks else np.zeros((0, 4), dtype=int)


def labels_of(m, key):
    parts = [np.asarray(v).reshape(-1).astype(int) for b, v in zip(m.cells, m.cell_data[key]) if b.type == "tetra"]
    return np.concatenate(parts) if parts else None


for name, source in (("phantom", None), ("spheres", os.path.join(DATA, "spheres_argmax.nrrd"))):
    base, report, _ = mesh_volume(name, source)
    n_tets = int(report["counts"]["tets"])
    n_pts = int(report["counts"]["vertices"])
    in_mesh = sorted(l["id"] for l in report["input"]["labels"] if l["in_mesh"])

    # VTU through VTK's reader.
    r = subprocess.run([CLI, "quality", base + ".vtu", "--json"], capture_output=True, text=True,
                       stdin=subprocess.DEVNULL)
    ok = r.returncode == 0
    q = json.loads(r.stdout) if ok else {}
    check(ok and q["quality"]["all"]["tets"] == n_tets and q["quality"]["inverted_tets"] == 0,
          "%s: VTU read back by VTK (femesher quality): %d tets, none inverted" % (name, n_tets))
    check(ok and sorted(m["label"] for m in q["quality"]["per_material"]) == in_mesh,
          "%s: VTU labels per material = report" % name)
    head = open(base + ".vtu", "rb").read(4096)
    check(b'Name="SPACE"' in head or b"SPACE" in open(base + ".vtu", "rb").read(),
          "%s: VTU field data SPACE present" % name)

    vtu = meshio.read(base + ".vtk")
    tv = tets_of(vtu)
    lv = labels_of(vtu, "labels")
    check(len(vtu.points) == n_pts and len(tv) == n_tets, "%s: legacy VTK (meshio) has %d points, %d tets" % (name, n_pts, n_tets))
    check(sorted(set(lv.tolist())) == in_mesh, "%s: VTK labels %s = report %s" % (name, sorted(set(lv.tolist())), in_mesh))
    check(open(base + ".vtk", "rb").read(200).find(b"SPACE=LPS") > 0, "%s: legacy VTK header says SPACE=LPS" % name)
    # Orientation: every tet positive in the VTU.
    p = vtu.points
    vol = np.einsum("ij,ij->i", p[tv[:, 1]] - p[tv[:, 0]], np.cross(p[tv[:, 2]] - p[tv[:, 0]], p[tv[:, 3]] - p[tv[:, 0]]))
    check(bool((vol > 0).all()), "%s: all tets positively oriented" % name)

    # Per-tet comparison by centroid (formats may reorder cells).
    def keyed(m, tets, labels):
        c = m.points[tets].mean(axis=1)
        order = np.lexsort((c[:, 2], c[:, 1], c[:, 0]))
        return np.round(c[order], 6), labels[order]

    cv, lv_sorted = keyed(vtu, tv, lv)
    msh = meshio.read(base + ".msh")
    tm = tets_of(msh)
    lm = labels_of(msh, "gmsh:physical")
    check(len(msh.points) == n_pts and len(tm) == n_tets, "%s: MSH has the same points and tets" % name)
    cm, lm_sorted = keyed(msh, tm, lm)
    check(np.allclose(cv, cm) and (lv_sorted == lm_sorted).all(), "%s: MSH physical volumes = VTK labels per tet" % name)
    names = msh.field_data if hasattr(msh, "field_data") else {}
    vol_names = [k for k, v in names.items() if int(v[1]) == 3]
    surf_names = [k for k, v in names.items() if int(v[1]) == 2]
    check(len(vol_names) == len(in_mesh), "%s: MSH names a physical volume per material (%s)" % (name, vol_names))
    check(any(k.startswith("interface_") for k in surf_names) and any(k.startswith("boundary_") for k in surf_names),
          "%s: MSH names interface and boundary surfaces" % name)

    med = meshio.read(base + ".mesh")
    tmed = tets_of(med)
    lmed = labels_of(med, "medit:ref")
    check(len(tmed) == n_tets, "%s: Medit has the same tets" % name)
    cmed, lmed_sorted = keyed(med, tmed, lmed)
    check(np.allclose(cv, cmed) and (lv_sorted == lmed_sorted).all(), "%s: Medit refs = VTK labels per tet" % name)

    # FEBio: well-formed XML with every tet once.
    import xml.etree.ElementTree as ET
    feb = ET.parse(base + ".feb").getroot()
    elems = feb.findall(".//Elements/elem")
    check(len(elems) == n_tets and len(feb.findall(".//Material/material")) == len(in_mesh),
          "%s: FEBio file lists every tet and a material per label" % name)
    stl = open(base + ".stl").read()
    check(stl.count("solid interface_") >= 1 and stl.count("endsolid") >= len(in_mesh),
          "%s: STL has a solid per interface" % name)

check.finish()
