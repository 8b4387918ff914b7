#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""femesher as 3D Slicer runs it as a CLI module, from its own `femesher --xml`.

What Slicer does with the XML (read in SlicerExecutionModel's ModuleDescriptionParser.cxx and
Slicer's Base/QTCLI/qSlicerCLIModuleUIHelper.cxx, vtkSlicerCLIModuleLogic.cxx and
Libs/MRML/CLI/vtkMRMLCommandLineModuleNode.cxx), emulated here:
  - <name> and <longflag> (leading dashes stripped) may hold only letters, digits and '_', else
    the whole description is rejected; <index> parameters have no flag.
  - Command line: every flagged parameter in document order, then the <index> ones in index
    order. A boolean is a bare `--flag` when true and left out when false. A number is
    `--flag value`: an <integer> with <constraints> is a slider whose value is printed as a
    double (C++ ostream, 6 significant digits: '%g'), one without is a spin box printed as an
    int; a <double> is printed with '%g'; an enumeration as its text.
  - Panel: an integer's default/minimum/maximum are read with QString::toInt (a plain integer
    or nothing); a double's minimum/maximum with toFloat (float32), and it shows as many
    decimals as the default (2 when it has no '.'), minimum, maximum or step has after '.'.
Checks: (c) the XML against the parameter registry (`femesher parameters --json`), (a) the
command line Slicer builds at the defaults succeeds and gives the same mesh as `femesher mesh`,
(b) turning every boolean's checkbox on flips that parameter (run report), and the command-line
forms of booleans stay backward compatible."""
import json
import os
import re
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

import meshio
import numpy as np

CLI = os.environ["FEMESHER_CLI"]
TMP = tempfile.mkdtemp(prefix="slicer_cli_", dir=os.environ.get("FEMESHER_TMP"))
INT32_MAX = 2 ** 31 - 1

failures, passes = [], []


def check(cond, msg):
    (passes if cond else failures).append(msg)
    print(("ok:   " if cond else "FAIL: ") + msg, flush=True)
    return cond


def run(*args):
    return subprocess.run([CLI, *args], capture_output=True, text=True, stdin=subprocess.DEVNULL)


SCALAR_TAGS = {"integer", "double", "float", "boolean", "string-enumeration", "string"}
FILE_TAGS = {"image", "geometry"}
VALID_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
PLAIN_INT = re.compile(r"^-?[0-9]+$")
PLAIN_DECIMAL = re.compile(r"^-?[0-9]+(\.[0-9]+)?$")


def text(e, tag):
    c = e.find(tag)
    return None if c is None or c.text is None else c.text.strip()


def decimals(s):
    return len(s) - s.index(".") - 1 if s and "." in s else 0


def f32(x):
    return float(np.float32(float(x)))


# --- (c) the XML against the registry ---------------------------------------------------------
r = run("--xml")
check(r.returncode == 0 and r.stdout.startswith('<?xml version="1.0" encoding="utf-8"?>'),
      "--xml starts with the XML declaration ModuleDescriptionParser requires")
root = ET.fromstring(r.stdout)
r = run("parameters", "--json")
check(r.returncode == 0, "parameters --json exits 0")
registry = {d["key"]: d for d in json.loads(r.stdout)}
sem = {k.replace(".", "_"): k for k in registry}

params = [e for group in root.findall("parameters") for e in group if e.tag in SCALAR_TAGS | FILE_TAGS]
seen = {}
for e in params:
    name, flag = text(e, "name"), text(e, "longflag")
    check(name and VALID_NAME.match(name), "<name> %s: letters, digits, '_' only" % name)
    if e.tag in FILE_TAGS:
        check(flag is None and text(e, "flag") is None and PLAIN_INT.match(text(e, "index") or ""),
              "%s: an <index> parameter without a flag" % name)
        continue
    check(flag is not None and VALID_NAME.match(flag.lstrip("-")) and flag.lstrip("-") == name,
          "%s: <longflag> %s is --<name> with letters, digits, '_' only" % (name, flag))
    key = sem.get(name)
    inverted = False
    if key is None and name.startswith("no_") and name[3:] in sem:
        key, inverted = sem[name[3:]], True
    if not check(key in registry, "%s is a registry parameter" % name):
        continue
    check(key not in seen, "%s appears once" % key)
    seen[key] = (e, inverted)
    d = registry[key]
    default = text(e, "default")
    mn, mx, step = (text(e, "constraints/" + t) for t in ("minimum", "maximum", "step"))
    if d["type"] == "bool":
        check(e.tag == "boolean" and default == "false",
              "%s: <boolean> with default false (Slicer can pass only a bare flag for true)" % name)
        check(inverted == d["default"], "%s: %s" % (name, "on by default, so offered as its negation"
                                                    if d["default"] else "off by default, offered as itself"))
    elif d["type"] == "choice":
        check(e.tag == "string-enumeration" and default == d["default"]
              and [c.text for c in e.findall("element")] == d["choices"],
              "%s: string-enumeration %s of %s" % (name, default, d["choices"]))
    elif d["type"] == "string":
        check(e.tag == "string" and (default or "") == d["default"] and e.find("constraints") is None,
              "%s: <string> with default '%s' = registry '%s'" % (name, default or "", d["default"]))
    elif d["type"] == "int":
        check(e.tag == "integer" and PLAIN_INT.match(default or "") and int(default) == d["default"],
              "%s: <integer> default %s = registry %s" % (name, default, d["default"]))
        slider_exact = max(abs(d["minimum"]), abs(d["maximum"])) <= 10 ** 6
        check((e.find("constraints") is not None) == slider_exact,
              "%s: constraints only where Slicer's slider prints every value exactly (range %s..%s)"
              % (name, d["minimum"], d["maximum"]))
        if e.find("constraints") is not None:
            check(all(PLAIN_INT.match(v or "") and abs(int(v)) <= INT32_MAX for v in (mn, mx, step))
                  and int(mn) == d["minimum"] and int(mx) == d["maximum"] and int(step) == 1,
                  "%s: min %s max %s step %s read by QString::toInt = registry %s..%s"
                  % (name, mn, mx, step, d["minimum"], d["maximum"]))
        check(float("%g" % d["default"]) == d["default"],
              "%s: the default as Slicer prints it (%s) is the registry default" % (name, "%g" % d["default"]))
    else:
        check(e.tag == "double", "%s: <double>" % name)
        ok = all(PLAIN_DECIMAL.match(v or "") for v in (default, mn, mx, step))
        check(ok, "%s: default %s, min %s, max %s, step %s in plain decimal notation" % (name, default, mn, mx, step))
        if not ok:
            continue
        check(float(default) == d["default"] and float(mn) == d["minimum"] and float(mx) == d["maximum"],
              "%s: default/min/max read back = registry %r/%r/%r" % (name, d["default"], d["minimum"], d["maximum"]))
        dec = max(decimals(default) if "." in default else 2, decimals(mn), decimals(mx), decimals(step))
        check(round(d["default"], dec) == d["default"] and round(f32(mn), dec) == d["minimum"]
              and round(f32(mx), dec) == d["maximum"],
              "%s: Slicer's widget (%d decimals, float range) holds the registry default and range" % (name, dec))
        check(float(step) > 0 and max(abs(d["minimum"]), abs(d["maximum"])) / float(step) <= INT32_MAX,
              "%s: step %s fits the slider's integer positions" % (name, step))
        check(float("%g" % d["default"]) == d["default"],
              "%s: the default as Slicer prints it (%s) is the registry default" % (name, "%g" % d["default"]))
check(set(seen) == set(registry), "every registry parameter is in the XML (missing: %s)" % sorted(set(registry) - set(seen)))
check(root.find(".//*[name='preset']") is None,
      "no preset selector (Slicer passes every parameter, which would override it)")
optional_files = [e for group in root.findall("parameters") for e in group if e.tag == "file"]
check([text(e, "name") for e in optional_files] == ["labelNames"], "one optional input file: the label names table")
for e in optional_files:
    flag = text(e, "longflag") or ""
    check(VALID_NAME.match(flag.lstrip("-")) and text(e, "index") is None and text(e, "channel") == "input",
          "%s: an optional input file with <longflag> %s (letters, digits, '_'), no <index>"
          % (text(e, "name"), flag))
indexed = sorted((int(text(e, "index")), e) for e in params if e.tag in FILE_TAGS)
check([(i, e.tag, text(e, "channel")) for i, e in indexed] == [(0, "image", "input"), (1, "geometry", "output")],
      "index 0 = input label map, 1 = output model")


def slicer_command(inputs, flip_booleans=False):
    """The argument list vtkSlicerCLIModuleLogic builds from the XML with every widget at its
    default (booleans ticked when `flip_booleans`), then the index parameters."""
    args, bare = [], []
    for e in params:
        flag = text(e, "longflag")
        if flag is None:
            continue
        flag = "--" + flag.lstrip("-")
        default = text(e, "default")
        if e.tag == "boolean":
            if flip_booleans or default == "true":
                args.append(flag)
                bare.append(flag)
        elif e.tag == "integer":
            args += [flag, "%g" % float(default) if e.find("constraints") is not None else str(int(default))]
        elif e.tag == "double":
            args += [flag, "%g" % float(default)]
        elif e.tag == "string":
            if default:  # Slicer leaves an empty text field off the command line
                args += [flag, default]
        else:
            args += [flag, default]
    return args + inputs, bare


def read_mesh(path):
    m = meshio.read(path)
    tets = [i for i, b in enumerate(m.cells) if b.type == "tetra"]
    cells = np.concatenate([m.cells[i].data for i in tets])
    labels = np.concatenate([np.asarray(m.cell_data["labels"][i]).reshape(-1) for i in tets])
    return m.points, cells, labels


phantom = os.path.join(TMP, "phantom.nrrd")
check(run("phantom", phantom).returncode == 0, "phantom written")

# --- (a) Slicer's command line at the defaults = the plain default run --------------------------
slicer_vtu, plain_vtu = os.path.join(TMP, "slicer.vtu"), os.path.join(TMP, "plain.vtu")
args, bare = slicer_command([phantom, slicer_vtu])
check(bare == [], "at the defaults Slicer passes no boolean flag (every XML boolean defaults to false)")
print("Slicer-style:", " ".join(args))
r = run(*args)
check(r.returncode == 0 and os.path.exists(slicer_vtu),
      "Slicer's command line at the defaults succeeds (rc=%d %s)" % (r.returncode, r.stderr.strip()[-300:]))
check("<filter-progress>" in r.stdout and "<filter-end>" in r.stdout, "it reports progress in Slicer's protocol")
r = run("mesh", phantom, "-o", plain_vtu, "-q")
check(r.returncode == 0, "plain default run: " + r.stderr.strip()[-200:])
if os.path.exists(slicer_vtu) and os.path.exists(plain_vtu):
    Ps, Ts, Ls = read_mesh(slicer_vtu)
    Pp, Tp, Lp = read_mesh(plain_vtu)
    check(len(Ts) > 1000 and np.array_equal(Ps, Pp) and np.array_equal(Ts, Tp) and np.array_equal(Ls, Lp),
          "same mesh as `femesher mesh` (%d points, %d tets; points, tets and labels equal)" % (len(Ps), len(Ts)))

# --- (a') a label names table picked in the file widget: Slicer passes --label_names FILE --------
table = os.path.join(TMP, "names.ctbl")
with open(table, "w") as f:
    f.write("# Slicer colour table\n1 Phantom_one 255 0 0 255\n2 Phantom_two 0 255 0 255\n")
named_report = os.path.join(TMP, "named.json")
args, _ = slicer_command([phantom, os.path.join(TMP, "named.vtu")])
r = run("--report", named_report, "--label_names", table, *args)
named = open(named_report).read() if os.path.exists(named_report) else ""
check(r.returncode == 0 and "Phantom_one" in named and "Phantom_two" in named,
      "--label_names FILE (as Slicer passes the file widget) names the materials (rc=%d %s)"
      % (r.returncode, r.stderr.strip()[-300:]))

# --- (b) every checkbox ticked: each boolean flips ----------------------------------------------
report = os.path.join(TMP, "flipped.json")
flipped_vtu = os.path.join(TMP, "flipped.vtu")
args, bare = slicer_command([phantom, flipped_vtu], flip_booleans=True)
print("bare flags:", bare)
r = run("--report", report, *args)  # --report only to read the effective parameters back
check(r.returncode == 0 and os.path.exists(flipped_vtu),
      "every boolean as a bare flag: the run succeeds (rc=%d %s)" % (r.returncode, r.stderr.strip()[-300:]))
got = json.load(open(report))["parameters"] if os.path.exists(report) else {}
booleans = {k: inv for k, (e, inv) in seen.items() if e.tag == "boolean"}
check(len(booleans) == len([d for d in registry.values() if d["type"] == "bool"]) and len(bare) == len(booleans),
      "%d booleans, each passed as a bare flag" % len(booleans))
for key, inverted in sorted(booleans.items()):
    check(got.get(key) is (not registry[key]["default"]),
          "ticking %s sets %s = %s (report: %s)" % (("no_" if inverted else "") + key, key,
                                                   not registry[key]["default"], got.get(key)))
others = {k: d["default"] for k, d in registry.items() if d["type"] in ("int", "double", "choice", "string")}
check(all(got.get(k) == v for k, v in others.items()),
      "every other parameter stays at its default: %s" % {k: got.get(k) for k, v in others.items() if got.get(k) != v})

# --- the command-line forms of booleans (backward compatible) -----------------------------------
ball = os.path.join(TMP, "p.json")


def saved(*extra):
    if os.path.exists(ball):
        os.remove(ball)
    r = run("mesh", phantom, "--save-parameters", ball, *extra)
    return r, (json.load(open(ball)) if r.returncode == 0 and os.path.exists(ball) else None)


for extra, key, want in [
        (("--voxel-refinement", "false"), "voxel_refinement", False),
        (("--voxel-refinement", "off"), "voxel_refinement", False),
        (("--voxel-refinement=false",), "voxel_refinement", False),
        (("--set", "voxel_refinement=false"), "voxel_refinement", False),
        (("--no-voxel-refinement",), "voxel_refinement", False),
        (("--no_voxel_refinement",), "voxel_refinement", False),
        (("--no-voxel-refinement", "false"), "voxel_refinement", True),
        (("--preset", "coarse", "--voxel-refinement"), "voxel_refinement", True),
        (("--preset", "coarse", "--voxel_refinement", "yes"), "voxel_refinement", True),
        (("--volume-sizing",), "volume_sizing", True),
        (("--volume_sizing", "--compute-fidelity", "0"), "compute_fidelity", False),
        (("--target_edge_length", "1.5"), "target_edge_length", 1.5),
        (("--target-edge-length", "1.5"), "target_edge_length", 1.5),
        (("--default_E", "2000"), "default.E", 2000),
        (("--min_voxels", "1e+06"), "min_voxels", 1000000),
        (("--contact_pairs", "4:1"), "contact_pairs", "4:1"),
        (("--contact-pairs", " 4:1 , 2:5"), "contact_pairs", "4:1,2:5"),
        (("--set", "contact_pairs=4:1", "--contact_pairs", ""), "contact_pairs", "")]:
    r, p = saved(*extra)
    check(p is not None and p.get(key) == want,
          "%s -> %s = %s (%s)" % (" ".join(extra), key, want, r.stderr.strip()[-200:] or (p or {}).get(key)))
# A bare flag before a positional argument does not swallow it.
r = run("mesh", "--volume_sizing", phantom, "--save-parameters", ball)
check(r.returncode == 0 and json.load(open(ball)).get("volume_sizing") is True,
      "`mesh --volume_sizing IN`: bare flag, IN stays the input (%s)" % r.stderr.strip()[-200:])
r, _ = saved("--voxel-refinement", "true", "--no-voxel-refinement")
check(r.returncode == 2 and "contradict" in r.stderr,
      "--voxel-refinement true with --no-voxel-refinement: exit 2, says they contradict (%s)" % r.stderr.strip()[-200:])
r, _ = saved("--voxel-refinement", "maybe")
check(r.returncode == 2, "--voxel-refinement maybe: exit 2 (%d %s)" % (r.returncode, r.stderr.strip()[-200:]))
r, _ = saved("--contact_pairs", "4-1")
check(r.returncode == 2 and "contact_pairs" in r.stderr and "A:B" in r.stderr,
      "--contact_pairs 4-1: exit 2 saying how to write pairs (%s)" % r.stderr.strip()[-200:])
bad_out = os.path.join(TMP, "bad_pair.vtu")
r = run("mesh", phantom, "-o", bad_out, "--contact_pairs", "4:9", "-q")
check(r.returncode == 2 and "no label 9" in r.stderr and not os.path.exists(bad_out),
      "--contact_pairs 4:9: exit 2 naming the label the phantom lacks (%s)" % r.stderr.strip()[-200:])
r, _ = saved("--min_voxels", "2000000")
check(r.returncode == 2 and "min_voxels" in r.stderr and "1000000" in r.stderr,
      "min_voxels above its range: exit 2 naming the range (%s)" % r.stderr.strip()[-200:])

print("checks: %d passed, %d failed" % (len(passes), len(failures)))
sys.exit(1 if failures else 0)
