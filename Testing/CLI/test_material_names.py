#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Material names and properties from the command line: material.<label>.name, colour tables
(--label-names: 3D Slicer .ctbl, ITK-SNAP label description; the real knee's nine labels), names
in the INP, MSH and FEB exports (read back with meshio and an XML parser), properties for labels
the map does not have rejected, and the warning for solver decks written with the built-in
default stiffness (stderr and the run report)."""
import json
import os
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

import meshio

CLI = os.environ["FEMESHER_CLI"]
DATA = os.environ.get("FEMESHER_DATA_DIR", "")
TMP = tempfile.mkdtemp(prefix="names_", dir=os.environ.get("FEMESHER_TMP"))
IN_CI = os.environ.get("CI") == "true"
failures, passes = [], []


def check(cond, msg):
    (passes if cond else failures).append(msg)
    print(("ok:   " if cond else "FAIL: ") + msg, flush=True)
    return cond


def run(*args, timeout=1800):
    return subprocess.run([CLI, *map(str, args)], capture_output=True, text=True, timeout=timeout,
                          stdin=subprocess.DEVNULL)


def p(name):
    return os.path.join(TMP, name)


phantom = p("phantom.nrrd")
check(run("phantom", phantom).returncode == 0, "phantom written")

# --- properties or a name for a label the map does not have: rejected before meshing ----------
for key in ("material.12.E=5000", "material.12.name=screw"):
    out = p("reject.inp")
    r = run("mesh", phantom, "-o", out, "--set", key, "-q")
    check(r.returncode == 2 and "no label 12" in r.stderr and "1, 2, 3, 4, 5" in r.stderr
          and key.split("=")[0] in r.stderr and "femesher info" in r.stderr and not os.path.exists(out),
          "--set %s: exit 2, names label 12, lists the labels 1..5 and what to do, no output (rc=%d: %s)"
          % (key, r.returncode, r.stderr.strip()[:300]))
r = run("mesh", phantom, "-o", p("reject.inp"), "--set", "material.3.name=", "-q")
check(r.returncode == 2 and "empty" in r.stderr, "an empty material name is rejected")

# --- names from an ITK-SNAP label description, one overridden with --set ------------------------
snap = p("phantom_labels.txt")
with open(snap, "w") as f:
    f.write("################################################\n# ITK-SnAP Label Description File\n"
            "# IDX   -R-  -G-  -B-  -A--  VIS MSH  LABEL\n################################################\n"
            '    0     0    0    0        0  0  0    "Clear Label"\n'
            '    1   241  214  145        1  1  1    "Cortical bone"\n'
            '    2   177  122  101        1  1  1    "Trabecular bone"\n'
            '    3   250  250  225        1  1  1    "Bone marrow"\n'
            '    4   111  184  210        1  1  1    "Articular cartilage"\n'
            '    5   200  200  235        1  1  1    "Implant"\n'
            '   17    10   10   10        1  1  1    "not in this map"\n')
base = p("named")
r = run("mesh", phantom, "--label-names", snap, "--set", "material.5.name=Ti-6Al-4V stem",
        "--preset", "coarse", "-o", base + ".inp", "-o", base + ".msh", "-o", base + ".feb",
        "--report", base + ".json")
check(r.returncode == 0, "mesh with --label-names (ITK-SNAP) and material.5.name (rc=%d %s)" % (r.returncode, r.stderr[-300:]))
want = {1: "Cortical bone", 2: "Trabecular bone", 3: "Bone marrow", 4: "Articular cartilage", 5: "Ti-6Al-4V stem"}
if r.returncode == 0:
    report = json.load(open(base + ".json"))
    got = {l["id"]: l["name"] for l in report["input"]["labels"]}
    check(got == want, "report's label table carries the names %s" % got)
    msh = meshio.read(base + ".msh")
    vol_names = {int(v[0]): k for k, v in msh.field_data.items() if int(v[1]) == 3}
    check(vol_names == want, "MSH physical volume names (meshio) %s" % vol_names)
    inp = meshio.read(base + ".inp")
    sets = sorted(k for k in inp.cell_sets if k.startswith("M"))
    check(sets == ["M1_CORTICAL_BONE", "M2_TRABECULAR_BONE", "M3_BONE_MARROW", "M4_ARTICULAR_CARTILAGE",
                   "M5_TI_6AL_4V_STEM"], "INP element sets (meshio) named after the materials %s" % sets)
    text = open(base + ".inp").read()
    check("*MATERIAL, NAME=MAT_M5_TI_6AL_4V_STEM" in text and "** name 'Ti-6Al-4V stem'" not in text
          and "**     name 'Ti-6Al-4V stem'" in text, "INP material named, original name in a comment")
    feb = ET.parse(base + ".feb").getroot()
    names = [m.get("name") for m in feb.findall("./Material/material")]
    check(names == ["Cortical_bone", "Trabecular_bone", "Bone_marrow", "Articular_cartilage", "Ti_6Al_4V_stem"],
          "FEB materials named after the materials %s" % names)
    doms = sorted(d.get("name") for d in feb.findall("./MeshDomains/SolidDomain"))
    check(doms == sorted(names), "FEB domains named after the materials")
    check(any(s.get("name") == "Cortical_bone__Trabecular_bone" for s in feb.findall("./Mesh/Surface")),
          "FEB interface surface named <a>__<b>")
    # No properties given: both decks warned about, all five materials named.
    warns = [w for w in report["warnings"] if "built-in default" in w]
    check(len(warns) == 2 and all("5 materials" in w and "label 5 (Ti-6Al-4V stem)" in w for w in warns)
          and sum("built-in default" in line for line in r.stderr.splitlines()) == 2
          and (base + ".inp") in r.stderr and (base + ".feb") in r.stderr,
          "default stiffness warned once per deck on stderr and in the report: %s" % warns[:1])

# Every material given properties (or default.E): no warning.
r = run("mesh", phantom, "--preset", "coarse", "-o", p("allprops.inp"), "--report", p("allprops.json"),
        *sum((["--set", "material.%d.E=%d" % (l, 1000 + l)] for l in range(1, 6)), []))
check(r.returncode == 0 and "built-in default" not in r.stderr
      and not any("built-in default" in w for w in json.load(open(p("allprops.json")))["warnings"]),
      "no default-stiffness warning when every material has properties")
r = run("mesh", phantom, "--preset", "coarse", "-o", p("defaultE.inp"), "-o", p("defaultE.vtu"),
        "--set", "default.E=500")
check(r.returncode == 0 and "built-in default" not in r.stderr, "no warning with the user's default.E")
r = run("mesh", phantom, "--preset", "coarse", "-o", p("nodeck.vtu"), "-o", p("nodeck.msh"))
check(r.returncode == 0 and "built-in default" not in r.stderr, "no warning without a solver deck")

# --- colour tables that cannot be used ----------------------------------------------------------
bad = p("bad.ctbl")
with open(bad, "w") as f:
    f.write("# Color table file\n0 Background 0 0 0 0\n1 bone 241 214\nx tissue 1 2 3 255\n")
r = run("info", phantom, "--label-names", bad)
check(r.returncode == 5 and "line 4" in r.stderr and "'x'" in r.stderr,
      "a malformed colour-table line: exit 5 naming the line (%s)" % r.stderr.strip()[:200])
other = p("other.ctbl")
with open(other, "w") as f:
    f.write("# Color table file\n# 2 values\n0 Background 0 0 0 0\n40 liver 221 130 101 255\n41 spleen 157 108 162 255\n")
r = run("mesh", phantom, "-o", p("other.inp"), "--label-names", other)
check(r.returncode == 2 and "names none of the labels" in r.stderr and "40, 41" in r.stderr
      and not os.path.exists(p("other.inp")), "a colour table for another map: exit 2, both label lists")
r = run("info", phantom, "--label-names", p("missing.ctbl"))
check(r.returncode == 3, "a missing colour table: exit 3")
csv = p("phantom.csv")
with open(csv, "w") as f:
    f.write('LabelValue,Name,Color_R,Color_G,Color_B,Color_A\n1,"bone, cortical",241,214,145,255\n'
            "5,Ti\\6Al stem,200,200,235,255\n")
r = run("info", phantom, "--label-names", csv, "--json")
got = {l["id"]: l["name"] for l in json.loads(r.stdout)["labels"]} if r.returncode == 0 else {}
check(got.get(1) == "bone, cortical" and got.get(5) == "Ti\\6Al stem" and got.get(2) == "trabecular bone",
      "Slicer CSV table: info --json stays valid JSON with a comma and a backslash in names %s" % got)

# --- the real knee with a 3D Slicer colour table ------------------------------------------------
knee = os.path.join(DATA, "9135902_00m_WB01.nii.gz")
if not os.path.exists(knee):
    check(not IN_CI, "knee data file present (%s)" % knee)
else:
    ctbl = p("knee.ctbl")
    knee_names = {1: "femoral_bone", 2: "femoral_cartilage", 3: "tibial_bone", 4: "tibial_cartilage",
                  5: "patellar_bone", 6: "patellar_cartilage", 7: "femoral_bone_lesion",
                  8: "tibial_bone_lesion", 9: "patellar_bone_lesion"}
    with open(ctbl, "w") as f:
        f.write("# Color table file %s\n# 10 values\n0 Background 0 0 0 0\n" % ctbl)
        for l, n in knee_names.items():
            f.write("%d %s %d %d %d 255\n" % (l, n, 20 * l, 255 - 20 * l, 100))
    r = run("info", knee, "--label-names", ctbl, "--json")
    got = {l["id"]: l["name"] for l in json.loads(r.stdout)["labels"] if l["id"] != 0} if r.returncode == 0 else {}
    check(got == knee_names, "knee: info --label-names shows the table's names %s" % got)
    kb = p("knee")
    r = run("mesh", knee, "--label-names", ctbl, "--preset", "coarse", "--set", "material.1.E=17000",
            "--set", "material.7.name=femoral lesion (BML)", "-o", kb + ".inp", "-o", kb + ".msh",
            "-o", kb + ".feb", "-q")
    check(r.returncode == 0, "knee meshed with the colour table (rc=%d %s)" % (r.returncode, r.stderr[-300:]))
    if r.returncode == 0:
        want = dict(knee_names)
        want[7] = "femoral lesion (BML)"
        msh = meshio.read(kb + ".msh")
        vol_names = {int(v[0]): k for k, v in msh.field_data.items() if int(v[1]) == 3}
        check(vol_names == want, "knee MSH physical names = table + override %s" % vol_names)
        sets = sorted(k for k in meshio.read(kb + ".inp").cell_sets if k.startswith("M"))
        check("M7_FEMORAL_LESION_BML" in sets and "M2_FEMORAL_CARTILAGE" in sets and len(sets) == 9,
              "knee INP element sets %s" % sets)
        feb = ET.parse(kb + ".feb").getroot()
        mats = {m.get("name"): float(m.findtext("E")) for m in feb.findall("./Material/material")}
        check(mats.get("femoral_bone") == 17000.0 and mats.get("femoral_lesion_BML") == 1000.0 and len(mats) == 9,
              "knee FEB materials named, femoral bone E = 17000 %s" % mats)
        check("label 2 (femoral_cartilage)" in r.stderr and "label 1 (" not in r.stderr,
              "knee: the default-stiffness warning names the other eight, not femoral bone")

print("checks: %d passed, %d failed" % (len(passes), len(failures)))
sys.exit(1 if failures else 0)
