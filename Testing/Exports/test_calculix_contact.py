#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""CalculiX (Debian calculix-ccx) solves a contact step on the phantom meshed with
contact_pairs=4:1: its cartilage cap (label 4, soft) is split from the cortical bone (label 1)
under it. First the export itself: the report and the CLI name the pair; the INP has the two
element-face surfaces, the interaction and the *CONTACT PAIR (dependent surface first); the two
sides share no node except on lines where a third material (the implant) touches both; every
cartilage contact node has a bone copy at the same place; meshio still reads the .vtu and .msh.
Then a driver deck *INCLUDEs the export and adds one nonlinear static step: the bone and implant
nodes at the far end of the shaft fixed, the top of the cartilage cap pushed down by 0.02 mm in
one increment.
ccx must converge without *ERROR, the contact pressure must be positive, the reaction at the
fixed end must balance the force that pushes, and the cartilage must not pass through the bone:
at every contact node the gap along the bone's outward normal stays >= -tolerance (the overlap a
penalty contact allows at the largest pressure, and under a fifth of the push).
The same again with element_order=2: C3D10 elements, the contact surfaces made of their quadratic
faces (element-face surfaces S1..S4, surface-to-surface contact, which CalculiX supports for
quadratic faces), the mid-edge nodes of both sides curved onto the same smooth interface, meshed on
the phantom cut below its femoral head (phantom_head) to halve the unknowns.

Why the C3D10 solve used to take minutes (measured 2026-11-25 on 2 cores, whole phantom, C3D10 with
edge_length_factor=4.5: 26293 nodes, 73428 equations). One linear solve of that deck (contact
removed) takes ccx 4.6 s, so the size alone is not the cost. The cost was the contact iterations:
the step ran in 4 increments (0.25, 0.25, 0.375, 0.125) of 10-11 iterations each, 43 SPOOLES
factorisations of about 6.7 s, 288 s in all here (more than 16 minutes in a fresh-clone run).
CalculiX's surface-to-surface contact freezes the match of the slave and master faces at the start
of every increment, integrating over the triangulated overlaps of the two meshes (quadratic faces cut
into linear pieces): here 12540 contact elements at the first iteration, 41000-45000 at the first
iteration of the later increments, of which Newton sheds the open ones over about ten iterations,
in every increment again. The problem is small-strain linear elastic and frictionless, so the load
path does not matter: the push is applied in one increment (ccx still cuts back by itself if an
increment fails), which finds the contact zone once (11 iterations) and gives the same reactions
(37.98 N against 37.92 N in four increments). With the cut phantom (16392 nodes, 43485 equations)
the C3D10 solve took ccx 30-38 s in one increment of 11 iterations; the C3D4 solve of the whole
phantom 3.6 s (14 s in four increments)."""
import gzip
import os
import re
import shutil
import tempfile

import meshio
import numpy as np

from exports_common import CLI, IN_CI, Checker, InpModel, dat_blocks, mesh_volume, node_lines, run, run_ccx

check = Checker()
ccx = shutil.which("ccx")
if not ccx:
    check(not IN_CI and False, "ccx (Debian package calculix-ccx) is installed")
    check.finish()

PUSH = 0.02  # mm, downwards (-z) at the top of the cartilage cap


def phantom_head(z_from, pad=2):
    """The phantom written by `femesher phantom`, cut below its femoral head: the slices from
    voxel row `z_from` up (cartilage cap, head and the top of the shaft with the stem), with `pad`
    empty slices under the cut so that the bone ends on a flat face of its own, not on the box.
    Returns the path of the cut label map (raw NRRD, same spacing and labels)."""
    tmp = tempfile.mkdtemp(prefix="phantom_head_", dir=os.environ.get("FEMESHER_TMP"))
    full = os.path.join(tmp, "phantom.nrrd")
    r = run([CLI, "phantom", full])
    if r.returncode != 0:
        raise SystemExit("femesher phantom failed: " + r.stderr)
    raw = open(full, "rb").read()
    end = raw.index(b"\n\n")
    header = raw[:end].decode().split("\n")
    field = dict(l.split(": ", 1) for l in header[1:] if ": " in l and not l.startswith("#"))
    assert field["type"] == "unsigned char" and field["encoding"] in ("gzip", "raw"), field
    sx, sy, sz = (int(x) for x in field["sizes"].split())
    data = raw[end + 2:]
    labels = np.frombuffer(gzip.decompress(data) if field["encoding"] == "gzip" else data,
                           np.uint8).reshape(sz, sy, sx)
    head = np.zeros((sz - z_from + pad, sy, sx), np.uint8)
    head[pad:] = labels[z_from:]
    assert field["space directions"].replace(" ", "") == "(1,0,0)(0,1,0)(0,0,1)", field
    origin = [float(x) for x in field["space origin"].strip("()").split(",")]
    origin[2] += z_from - pad
    out = []
    for l in header:
        key = l.split(":", 1)[0]
        if key == "sizes":
            l = "sizes: %d %d %d" % (sx, sy, head.shape[0])
        elif key == "space origin":
            l = "space origin: (%r,%r,%r)" % tuple(origin)
        elif key == "encoding":
            l = "encoding: raw"
        out.append(l)
    path = os.path.join(tmp, "phantom_head.nrrd")
    with open(path, "wb") as f:
        f.write(("\n".join(out) + "\n\n").encode() + head.tobytes())
    return path


def contact_case(name, order, coarser=(), source=None):
    """Meshes, checks and solves the contact deck of `source` (None = the phantom) with element
    order `order` (and the extra settings `coarser`)."""

    def ck(cond, msg):
        return check(cond, "%s: %s" % (name, msg))

    base, report, _ = mesh_volume(
        name, source, exts=[".inp", ".vtu", ".msh"],
        extra=["--set", "element_order=%d" % order, "--set", "contact_pairs=4:1", "--set", "sizing_scale=1.5", "--set", "default.E=15000",
               "--set", "material.4.E=20", "--set", "material.4.nu=0.4",
               "--set", "material.5.E=110000", "--set", "material.5.nu=0.34"] + list(coarser))
    pairs = report.get("contact_pairs", [])
    ck(len(pairs) == 1 and pairs[0]["labels"] == [4, 1] and pairs[0]["interface_triangles"] > 100
          and pairs[0]["duplicated_nodes"] > 50,
          "the report names the split pair 4:1 with its triangles and duplicated nodes %s" % pairs)
    inp_path = base + ".inp"
    inp = open(inp_path).read()
    ck(re.search(r"^\*SURFACE INTERACTION, NAME=SI_4_1\n\*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR\n"
                    r"[0-9.eE+-]+\n", inp, re.M) is not None,
          "INP: *SURFACE INTERACTION with a linear pressure-overclosure slope")
    ck(re.search(r"^\*CONTACT PAIR, INTERACTION=SI_4_1, TYPE=SURFACE TO SURFACE\nCONTACT_4_1_S, CONTACT_4_1_M\n",
                    inp, re.M) is not None, "INP: *CONTACT PAIR, dependent (cartilage) surface first")
    ck(report.get("box_node_sets") == {} and "NSET=BOX_" not in inp,
          "the phantom does not reach its box: no BOX_ node sets (report %s)" % report.get("box_node_sets"))

    # Parse nodes, elements with their label, and the two contact surfaces.
    model = InpModel(inp)
    nodes, elements, label_of = model.nodes, model.elements, model.label_of
    surfaces = {k: v for k, v in model.surfaces.items() if k.startswith("CONTACT_")}
    corner_ids = {n for el in elements.values() for n in el[:4]}
    ck(len(corner_ids) == int(report["counts"]["vertices"]) and model.types == {"C3D4" if order == 1 else "C3D10"},
          "INP: %s elements on the report's %d vertices (copies included)" % (sorted(model.types), len(corner_ids)))
    FACES = {1: (0, 1, 2), 2: (0, 3, 1), 3: (1, 3, 2), 4: (2, 3, 0)}
    slave, master = surfaces.get("CONTACT_4_1_S", []), surfaces.get("CONTACT_4_1_M", [])
    ck(len(slave) == len(master) == pairs[0]["interface_triangles"] if pairs else False,
          "both contact surfaces have one face per interface triangle (%d, %d)" % (len(slave), len(master)))
    ck(all(label_of[e] == 4 for e, _ in slave) and all(label_of[e] == 1 for e, _ in master),
          "CONTACT_4_1_S holds cartilage faces, CONTACT_4_1_M cortical bone faces")


    def face_nodes(e, s):
        return [elements[e][i] for i in FACES[s]]


    s_nodes = sorted({n for e, s in slave for n in face_nodes(e, s)})
    m_nodes = sorted({n for e, s in master for n in face_nodes(e, s)})
    others = {n for e, el in elements.items() if label_of[e] not in (1, 4) for n in el}
    # A cartilage|bone face stays tied only where the split cannot open it: each of its nodes is
    # also held by a third material touching both sides (ContactSplit.h), a strip of interface
    # one triangle wide between two triple lines. (The phantom had none until 2026-11-27; since
    # the particle system's convergence it has one.)
    tied = model.surfaces.get("IF_1_4", [])
    ck(len(tied) <= max(1, len(slave) // 100)
       and all(set(face_nodes(e, s)) <= others for e, s in tied),
       "INP: tied IF_1_4 faces only where a third material holds all their nodes (%d of %d)"
       % (len(tied), len(slave)))
    shared = set(s_nodes) & set(m_nodes)
    ck(len(shared) < len(s_nodes) // 5 and shared <= others,
          "the sides share %d of %d contact nodes, all on a third material (the implant)" % (len(shared), len(s_nodes)))
    # Each cartilage contact node has a bone contact node at the same place.
    m_xyz = np.array([nodes[n] for n in m_nodes])
    partner = {}
    for n in s_nodes:
        d = np.linalg.norm(m_xyz - nodes[n], axis=1)
        if d.min() < 1e-9:
            partner[n] = m_nodes[int(d.argmin())]
    ck(len(partner) == len(s_nodes), "every cartilage contact node has a coincident bone node (%d of %d)"
          % (len(partner), len(s_nodes)))
    for ext in (".vtu", ".msh"):
        m = meshio.read(base + ext)
        ck(len(m.points) == len(nodes), "meshio reads the %s with its %d points" % (ext, len(m.points)))

    # The bone's outward normal at each bone contact node (area-weighted, from its contact faces).
    normal = {n: np.zeros(3) for n in m_nodes}
    for e, s in master:
        a, b, c = (nodes[n] for n in face_nodes(e, s))
        d = nodes[elements[e][({0, 1, 2, 3} - set(FACES[s])).pop()]]
        nrm = np.cross(b - a, c - a) / 2
        if np.dot(nrm, a - d) < 0:
            nrm = -nrm
        for n in face_nodes(e, s):
            normal[n] += nrm
    for n in normal:
        normal[n] /= np.linalg.norm(normal[n])

    # Loads: bone and implant fixed at the far (bottom) end, top of the cartilage cap pushed down.
    bone_nodes = sorted({n for e, el in elements.items() if label_of[e] != 4 for n in el})
    cart_nodes = sorted({n for e, el in elements.items() if label_of[e] == 4 for n in el})
    zb = np.array([nodes[n][2] for n in bone_nodes])
    fixed = sorted(n for n in bone_nodes if nodes[n][2] < zb.min() + 5.0)
    # The top is that of the cartilage's own nodes (not on the contact or a third material): a
    # junction node with the implant may stand higher than the cap and leave nothing within 1.5 mm.
    free = [n for n in cart_nodes if n not in others and n not in partner]
    zc = np.array([nodes[n][2] for n in cart_nodes])
    zf = max(nodes[n][2] for n in free)
    top = sorted(n for n in free if nodes[n][2] > zf - 1.5)
    ck(zc.min() > zb.min() + 20 and len(fixed) >= 10 and len(top) >= 10,
          "cartilage sits on the head, far from the %d fixed shaft nodes; %d nodes pushed" % (len(fixed), len(top)))
    work = os.path.dirname(base)
    contact = sorted(set(s_nodes) | set(m_nodes))
    deck = ("*INCLUDE, INPUT=%s\n" % os.path.basename(inp_path) + "*NSET, NSET=FIXED\n" + node_lines(fixed) +
            "*NSET, NSET=PUSHED\n" + node_lines(top) + "*NSET, NSET=CNODES\n" + node_lines(contact) +
            "*BOUNDARY\nFIXED, 1, 3, 0.0\nPUSHED, 1, 2, 0.0\n*STEP, INC=200\n*STATIC\n1.0, 1.0, 1e-5, 1.0\n"
            "*BOUNDARY\nPUSHED, 3, 3, %g\n" % -PUSH +
            "*NODE PRINT, NSET=CNODES\nU\n*NODE PRINT, NSET=FIXED, TOTALS=ONLY\nRF\n"
            "*NODE PRINT, NSET=PUSHED, TOTALS=ONLY\nRF\n*CONTACT PRINT\nCSTR\n*END STEP\n")
    job = "contact_step_" + name
    with open(os.path.join(work, job + ".inp"), "w") as f:
        f.write(deck)
    disp, totals = run_ccx(ccx, work, job, check, timeout=1500)
    dat_path = os.path.join(work, job + ".dat")
    blocks = dat_blocks(open(dat_path).read()) if os.path.exists(dat_path) else []
    sta = os.path.join(work, job + ".sta")
    increments = [l.split() for l in open(sta).read().splitlines()[2:] if l.strip()] if os.path.exists(sta) else []
    print("%s: ccx took %d increment(s), %s iterations" % (job, len(increments), "+".join(r[3] for r in increments)))
    times = [float(h.split()[-1]) for h, _ in blocks]
    ck(times and abs(max(times) - 1.0) < 1e-9, "ccx reached the end of the step (time %s)" % (max(times) if times else None))
    last = [(h, b) for (h, b), t in zip(blocks, times) if t == max(times)] if times else []


    def rows(kind):
        for h, b in last:
            if h.startswith(kind):
                return [l.split() for l in b.strip().splitlines() if l.strip()]
        return []


    u = {int(r[0]): np.array([float(x) for x in r[1:4]]) for r in rows("displacements")}
    ck(len(u) == len(contact), "displacements of the %d contact nodes printed" % len(u))
    rf_fixed = rf_pushed = None
    for h, b in last:
        if h.startswith("total force"):
            v = np.array([float(x) for x in b.split()[:3]])
            if "set FIXED" in h:
                rf_fixed = v
            elif "set PUSHED" in h:
                rf_pushed = v
    stress = [[float(x) for x in r[2:5]] for r in rows("contact stress")]
    press = np.array([r[0] for r in stress]) if stress else np.zeros(1)
    ck(rf_fixed is not None and rf_pushed is not None and rf_pushed[2] < 0
          and np.linalg.norm(rf_fixed + rf_pushed) < 1e-3 * abs(rf_pushed[2]),
          "pushing takes a force and the fixed end balances it (RF pushed %s N, fixed %s N)"
          % (None if rf_pushed is None else np.round(rf_pushed, 4), None if rf_fixed is None else np.round(rf_fixed, 4)))
    ck(len(stress) > 0 and press.max() > 0 and (press > 0).sum() >= 10,
          "contact pressure: %d of %d contact points in contact, max %.4g MPa, mean of those %.4g MPa"
          % ((press > 0).sum(), len(stress), press.max(), press[press > 0].mean() if (press > 0).any() else 0))
    # The gap at each node pair, along the bone's outward normal (positive = apart). A penalty
    # contact lets the surfaces overlap by pressure / slope: never more than that (with a margin for
    # the pressure between integration points and nodes), and far less than the push.
    slope = float(re.search(r"PRESSURE-OVERCLOSURE=LINEAR\n([0-9.eE+-]+)", inp).group(1))
    gaps = [np.dot(nodes[s] + u[s] - nodes[m] - u[m], normal[m])
            for s, m in partner.items() if s != m and s in u and m in u]
    penetration = max(0.0, -min(gaps)) if gaps else float("nan")
    tolerance = 1.5 * press.max() / slope
    if gaps:
        print("gap: min %.3g mm, max %.3g mm; penalty slope %.4g MPa/mm" % (min(gaps), max(gaps), slope))
    ck(len(gaps) > 100 and penetration <= tolerance,
          "the surfaces overlap no more than the penalty allows: penetration %.3g mm <= 1.5 x max pressure / "
          "slope = %.3g mm" % (penetration, tolerance))
    ck(penetration < 0.2 * PUSH,
          "the cartilage does not pass through the bone: penetration %.3g mm < 0.2 x the %.3g mm push"
          % (penetration, PUSH))


contact_case("contact", 1)
# C3D10 on a coarser mesh (edge_length_factor 4.5 instead of 3; the thin cartilage holds the size
# near the contact) of the phantom cut 50 mm above its volume's bottom: the cartilage cap, the head
# and 16 mm of the shaft under it with the stem, fixed at the cut.
contact_case("contact_c3d10", 2, ["--set", "edge_length_factor=4.5"], phantom_head(50))
check.finish()
