#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Black-box tests of the femesher CLI: sub-commands, exit codes, progress protocol, Slicer XML,
cancel without partial output. Uses only the Python standard library."""
import json
import os
import re
import signal
import struct
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET

CLI = os.environ["FEMESHER_CLI"]
DATA = os.environ.get("FEMESHER_DATA_DIR", "")
TMP = tempfile.mkdtemp(prefix="cli_", dir=os.environ.get("FEMESHER_TMP"))
IN_CI = os.environ.get("CI") == "true"

# Exit codes of femesher (femesher::ErrorCode).
EXIT = {"ok": 0, "invalid-argument": 2, "file-not-found": 3, "unreadable-file": 4,
        "corrupt-file": 5, "not-a-label-map": 6, "empty-label-map": 7, "too-many-labels": 8,
        "overlapping-segments": 9, "meshing-failed": 10, "write-failed": 11, "canceled": 12}

failures = []
passes = []


def check(cond, msg):
    if not cond:
        failures.append(msg)
        print("FAIL:", msg)
    else:
        passes.append(msg)
        print("ok:  ", msg)


def run(*args, timeout=900):
    return subprocess.run([CLI, *args], capture_output=True, text=True, timeout=timeout,
                          stdin=subprocess.DEVNULL)


def write_nrrd(path, dims, values, type_name="unsigned char", fmt="B", dimension=3):
    header = "NRRD0004\ntype: %s\ndimension: %d\nsizes: %s\n" % (
        type_name, dimension, " ".join(map(str, dims)))
    if dimension == 3:
        header += ("space: left-posterior-superior\n"
                   "space directions: (1,0,0) (0,1,0) (0,0,1)\nspace origin: (0,0,0)\n")
    else:
        header += "spacings: %s\n" % " ".join("1" for _ in range(dimension))
    header += "encoding: raw\nendian: little\n\n"
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(struct.pack("<%d%s" % (len(values), fmt), *values))


def ball_values(n, label=1):
    c = (n - 1) / 2
    vals = []
    for k in range(n):
        for j in range(n):
            for i in range(n):
                r2 = (i - c) ** 2 + (j - c) ** 2 + (k - c) ** 2
                vals.append(label if r2 < (0.35 * n) ** 2 else (2 if r2 < (0.45 * n) ** 2 else 0))
    return vals


# --- help, version, xml ----------------------------------------------------------------------
r = run("--version")
check(r.returncode == 0 and "femesher" in r.stdout, "--version prints the version")
r = run("--xml")
check(r.returncode == 0, "--xml exits 0")
root = ET.fromstring(r.stdout)
check(root.tag == "executable", "--xml is a Slicer <executable> description")
flags = [e.text for e in root.iter("longflag")]
check(len(flags) >= 8, "--xml declares the parameters as long flags (%d)" % len(flags))
check(root.find(".//image[@type='label']") is not None, "--xml declares a label-map input")

# --- phantom and info -------------------------------------------------------------------------
phantom = os.path.join(TMP, "phantom.nrrd")
r = run("phantom", phantom)
check(r.returncode == 0 and os.path.exists(phantom), "phantom writes a label map")
r = run("info", phantom, "--json")
check(r.returncode == 0, "info --json exits 0")
info = json.loads(r.stdout)
check(len([l for l in info["labels"] if l["id"] != 0]) >= 4, "phantom has >= 4 materials")
check(info["quadruple_cells"] >= 1, "phantom has a quadruple point")

# The clinical-size hip phantom, at a quarter of its size (128 x 128 x 100 voxels of 2.8 x 2.8 x 4 mm).
hip = os.path.join(TMP, "hip.nrrd")
r = run("phantom", "--hip", "--scale", "0.25", hip)
check(r.returncode == 0 and "128 x 128 x 100 voxels, 10 materials" in r.stderr,
      "phantom --hip --scale 0.25 writes 128 x 128 x 100 voxels, 10 materials: " + r.stderr.strip())
r = run("info", hip, "--json")
info = json.loads(r.stdout) if r.returncode == 0 else {}
check(info.get("dims") == [128, 128, 100], "hip phantom dims: %s" % info.get("dims"))
check([round(x, 9) for x in info.get("spacing", [])] == [2.8, 2.8, 4.0],
      "hip phantom spacing 0.7 x 0.7 x 1 mm at scale 1: %s" % info.get("spacing"))
names = {l["id"]: l["name"] for l in info.get("labels", [])}
check(sorted(names) == list(range(11)) and names.get(7) == "implant" and names.get(10) == "subchondral bone plate",
      "hip phantom labels 0..10 with their names: %s" % names)
for bad, why in [(["--scale", "0.5"], "--scale without --hip"), (["--hip", "--voxel-size", "2"], "--voxel-size with --hip"),
                 (["--hip", "--scale", "3"], "--scale 3"), (["--hip", "--scale", "0"], "--scale 0")]:
    r = run("phantom", *bad, os.path.join(TMP, "bad_hip.nrrd"))
    check(r.returncode == EXIT["invalid-argument"] and "scale" in r.stderr + r.stdout and
          not os.path.exists(os.path.join(TMP, "bad_hip.nrrd")), "phantom %s is exit 2" % why)
r = run("phantom", "--help")
check("--hip" in r.stdout and "--scale" in r.stdout, "phantom --help lists --hip and --scale")

# --- medial axis and sizing field as images ---------------------------------------------------
ma = os.path.join(TMP, "phantom_ma.nrrd")
r = run("medial-axis", phantom, "-o", ma)
check(r.returncode == 0 and os.path.exists(ma), "medial-axis writes a label image")
r = run("info", ma, "--json")
ids = sorted(l["id"] for l in json.loads(r.stdout)["labels"]) if r.returncode == 0 else []
check(ids and ids[0] == -1 and set(ids) <= {-1, 0, 1, 2, 3, 4, 5} and len(ids) >= 6,
      "medial-axis image holds the labels whose axis passes there (-1 elsewhere): %s" % ids)
r = run("medial-axis", phantom, "-o", os.path.join(TMP, "ma2.nrrd"), "--label", "2", "--prune", "linear", "--gamma", "1.2")
check(r.returncode == 0, "medial-axis --label --prune --gamma")
r = run("medial-axis", phantom, "-o", os.path.join(TMP, "ma3.nrrd"), "--prune", "bogus")
check(r.returncode == EXIT["invalid-argument"] and not os.path.exists(os.path.join(TMP, "ma3.nrrd")),
      "medial-axis rejects an unknown pruning")
size = os.path.join(TMP, "phantom_size.nrrd")
r = run("sizing", phantom, "-o", size, "--set", "sizing_scale=1")
check(r.returncode == 0 and os.path.exists(size) and "target edge length" in r.stderr,
      "sizing writes the sizing field (%s)" % r.stderr.strip()[-120:])
r = run("info", size)
check(r.returncode == EXIT["not-a-label-map"], "the sizing field is a float image in mm (not labels)")

# --- every XML flag is accepted with an explicit value, booleans too (flags, then input, output;
# the exact command line Slicer builds, bare boolean flags included, is in test_slicer_cli.py) ----
small = os.path.join(TMP, "ball.nrrd")
write_nrrd(small, (16, 16, 16), ball_values(16))
args = []
for e in root.iter():
    if e.find("longflag") is None:
        continue
    default = e.find("default")
    args += [e.find("longflag").text, (default.text or "") if default is not None else ""]  # "": contact_pairs
out_vtu = os.path.join(TMP, "slicer_style.vtu")
r = run(*args, small, out_vtu)
check(r.returncode == 0 and os.path.exists(out_vtu),
      "Slicer-style call with every XML flag at its default works (rc=%d %s)" % (r.returncode, r.stderr[-300:]))
# Not a terminal -> Slicer progress protocol on stdout, monotone in [0, 1].
prog = [float(x) for x in re.findall(r"<filter-progress>([0-9.eE+-]+)</filter-progress>", r.stdout)]
check(len(prog) >= 5 and all(0 <= p <= 1 for p in prog), "filter-progress lines in [0,1]")
check(all(b >= a - 1e-9 for a, b in zip(prog, prog[1:])), "filter-progress is monotone")
check("<filter-start>" in r.stdout and "<filter-end>" in r.stdout, "filter-start/end present")

# --- quality with the labels: fidelity and the rasterised mesh ---------------------------------
raster = os.path.join(TMP, "raster.nrrd")
r = run("quality", out_vtu, "--labels", small, "--raster", raster, "--json")
check(r.returncode == 0 and os.path.exists(raster), "quality --labels --raster writes the rasterised mesh")
if r.returncode == 0:
    mats = json.loads(r.stdout)["fidelity"]["materials"]
    dice = {m["label"]: m["dice"] for m in mats}
    centres = {m["label"]: m["voxel_centre_dice"] for m in mats}
    # Volume Dice of a small ball in a thin shell (label 2 is 2-3 voxels thick) and, higher, the
    # voxel-centre agreement the surface refinement aims at.
    check(set(dice) == {1, 2} and min(dice.values()) > 0.8 and min(centres.values()) > 0.9,
          "quality --json reports volume Dice %s and voxel-centre agreement %s per label" % (dice, centres))
    ri = run("info", raster, "--json")
    counts_in = {l["id"]: l["voxels"] for l in json.loads(run("info", small, "--json").stdout)["labels"]}
    counts_r = {l["id"]: l["voxels"] for l in json.loads(ri.stdout)["labels"]} if ri.returncode == 0 else {}
    check(set(counts_r) == set(counts_in) and all(abs(counts_r[k] - counts_in[k]) <= 0.1 * counts_in[k] for k in counts_in),
          "the raster has the input's labels on its grid, voxel counts within 10%%: %s vs %s" % (counts_r, counts_in))
r = run("quality", out_vtu, "--raster", os.path.join(TMP, "raster2.nrrd"))
check(r.returncode == EXIT["invalid-argument"] and "--labels" in r.stderr
      and not os.path.exists(os.path.join(TMP, "raster2.nrrd")), "--raster without --labels is a clear error")

# --- mesh with a report -------------------------------------------------------------------------
report = os.path.join(TMP, "report.json")
out_inp = os.path.join(TMP, "ball.inp")
r = run("mesh", small, "-o", out_inp, "--report", report, "--set", "target_edge_length=1.5")
check(r.returncode == 0, "mesh -o .inp --report exits 0")
rep = json.load(open(report))
check(rep["counts"]["tets"] > 0, "report has counts")
check(rep["status"] == ("poor_elements" if rep["mesh_check"]["tets_below_warning"] else "ok"),
      "report status %s follows mesh_check" % rep["status"])
line = [l for l in r.stderr.splitlines() if l.startswith("Elements: ")]
check(len(line) == 1 and re.search(r"worst dihedral angle [0-9.e+-]+ deg; %d tet\(s\) below "
                                   r"min_dihedral_warning \(5 deg\).*: status %s$"
                                   % (rep["mesh_check"]["tets_below_warning"], rep["status"]),
                                   line[0]),
      "mesh prints one Elements line with the worst angle, the count and the status: %s" % line)
r = run("mesh", small, "-o", os.path.join(TMP, "poor.vtu"), "-q", "--set", "min_dihedral_warning=89")
check(r.returncode == 0 and re.search(r"^Elements: .* below min_dihedral_warning \(89 deg\): "
                                      r"status poor_elements$", r.stderr, re.M),
      "with --quiet the Elements line is still printed when the status is poor_elements: %s"
      % r.stderr.strip()[-200:])
r = run("mesh", small, "-o", os.path.join(TMP, "nowarn.vtu"), "-q", "--set", "min_dihedral_warning=0")
check(r.returncode == 0 and "Elements:" not in r.stderr, "with --quiet and no warning: no Elements line")
check({s["name"] for s in rep["stages"]} >= {"LabelPreprocess", "VolumeMesh"}, "report has stage timings")
check(rep["parameters"]["target_edge_length"] == 1.5, "report records the parameters")
check(rep["input"]["space"] == "LPS", "report records the input geometry in LPS")

# --- optimize an existing mesh -----------------------------------------------------------------
raw = os.path.join(TMP, "ball_raw.vtu")
r = run("mesh", small, "-o", raw, "--set", "target_edge_length=1.5", "--set", "optimize_min_dihedral=0")
check(r.returncode == 0, "mesh without the Optimize stage")
improved = os.path.join(TMP, "ball_improved.msh")
opt_report = os.path.join(TMP, "optimize.json")
r = run("optimize", raw, "--labels", small, "-o", improved, "--report", opt_report, "-q")
check(r.returncode == 0 and os.path.exists(improved), "optimize writes the improved mesh: " + r.stderr[-300:])
orep = json.load(open(opt_report)) if os.path.exists(opt_report) else {}
check([s["name"] for s in orep.get("stages", [])][-3:] == ["Optimize", "Quality", "Fidelity"],
      "optimize runs Optimize, Quality and Fidelity on the given mesh")
check(orep.get("counts", {}).get("optimize_min_dihedral_after", -1) >=
      orep.get("counts", {}).get("optimize_min_dihedral_before", 0), "optimize never lowers the worst angle")
r = run("optimize", raw, "-o", os.path.join(TMP, "nolabels.vtu"))
check(r.returncode == EXIT["invalid-argument"] and not os.path.exists(os.path.join(TMP, "nolabels.vtu")),
      "optimize without --labels is a clear error")

# --- parameter files ---------------------------------------------------------------------------
pfile = os.path.join(TMP, "params.json")
r = run("mesh", small, "--save-parameters", pfile, "--set", "min_voxels=3", "--preset", "coarse")
check(r.returncode == 0 and json.load(open(pfile))["min_voxels"] == 3, "--save-parameters writes JSON")
r = run("mesh", small, "--parameters", pfile, "-o", os.path.join(TMP, "p.vtu"))
check(r.returncode == 0, "--parameters FILE is accepted")

# --- bad input: clear message, distinct exit code, no output file --------------------------------
def expect_error(args, code, what, out=None):
    r = run(*args)
    ok = r.returncode == EXIT[code] and "error" in r.stderr
    if out:
        ok = ok and not os.path.exists(out)
    check(ok, "%s -> exit %d (%s), got %d: %s" % (what, EXIT[code], code, r.returncode, r.stderr.strip()[:200]))


missing = os.path.join(TMP, "does_not_exist.nrrd")
o = os.path.join(TMP, "bad.vtu")
expect_error(["mesh", missing, "-o", o], "file-not-found", "missing input", o)
expect_error(["mesh", small, "-o", os.path.join(TMP, "x.obj")], "invalid-argument", "unsupported output")
expect_error(["mesh", small, "-o", o, "--set", "bogus=1"], "invalid-argument", "unknown parameter", o)
expect_error(["mesh", small, "-o", o, "--set", "min_dihedral_angle=60"], "invalid-argument", "out-of-range parameter", o)
expect_error(["mesh", small, "-o", os.path.join(TMP, "no_dir", "x.vtu")], "write-failed", "missing output folder")
empty = os.path.join(TMP, "empty.nrrd")
write_nrrd(empty, (8, 8, 8), [0] * 512)
expect_error(["mesh", empty, "-o", o], "empty-label-map", "background-only map", o)
ct = os.path.join(TMP, "ct.nrrd")
write_nrrd(ct, (8, 8, 8), [0.5 + i * 0.25 for i in range(512)], "float", "f")
expect_error(["mesh", ct, "-o", o], "not-a-label-map", "float CT", o)
flat = os.path.join(TMP, "flat.nrrd")
write_nrrd(flat, (8, 8), [1] * 64, dimension=2)
expect_error(["mesh", flat, "-o", o], "not-a-label-map", "2-D image", o)
trunc = os.path.join(TMP, "trunc.nrrd")
write_nrrd(trunc, (16, 16, 16), ball_values(16))
with open(trunc, "rb") as f:
    data = f.read()
with open(trunc, "wb") as f:
    f.write(data[:-1000])
expect_error(["mesh", trunc, "-o", o], "corrupt-file", "truncated file", o)
junk = os.path.join(TMP, "junk.nrrd")
with open(junk, "w") as f:
    f.write("this is not an image\n")
expect_error(["info", junk], "unreadable-file", "not an image")
frog_mhd = os.path.join(DATA, "orig", "frogtissue.mhd")
if os.path.exists(frog_mhd):
    expect_error(["info", frog_mhd], "corrupt-file", "MetaImage header that lies about its data")
elif IN_CI:
    check(False, "missing data file %s" % frog_mhd)

many = os.path.join(TMP, "many_labels.nrrd")
write_nrrd(many, (50, 50, 30), list(range(1, 75001)), "int", "i")
expect_error(["info", many], "too-many-labels", "more than 65,535 labels")


def write_seg(path, layers, names):
    # Slicer .seg.nrrd: a 4-D NRRD, layer axis first ("list"), one segment per layer.
    n = 8
    vals = []
    for k in range(n):
        for j in range(n):
            for i in range(n):
                for layer in layers:
                    vals.append(layer(i, j, k))
    header = ("NRRD0004\ntype: unsigned char\ndimension: 4\nsizes: %d %d %d %d\n"
              "kinds: list domain domain domain\nspace: left-posterior-superior\n"
              "space directions: none (1,0,0) (0,1,0) (0,0,1)\nspace origin: (0,0,0)\n"
              "encoding: raw\nendian: little\n") % (len(layers), n, n, n)
    for idx, (name, value) in enumerate(names):
        header += ("Segment%d_ID:=Segment_%d\nSegment%d_Name:=%s\nSegment%d_Color:=0.1 0.2 0.3\n"
                   "Segment%d_LabelValue:=%d\nSegment%d_Layer:=%d\n") % (idx, idx, idx, name, idx, idx, value, idx, idx)
    with open(path, "wb") as f:
        f.write((header + "\n").encode())
        f.write(bytes(vals))


seg_ok = os.path.join(TMP, "two.seg.nrrd")
write_seg(seg_ok, [lambda i, j, k: 1 if i < 4 and 1 < j < 7 and 1 < k < 7 else 0,
                   lambda i, j, k: 2 if i >= 4 and 1 < j < 7 and 1 < k < 7 else 0],
          [("femur", 1), ("tibia", 2)])
r = run("info", seg_ok, "--json")
ok = r.returncode == 0
names = {l["id"]: l["name"] for l in json.loads(r.stdout)["labels"]} if ok else {}
check(ok and names.get(1) == "femur" and names.get(2) == "tibia",
      ".seg.nrrd segment names become the material table (%s %s)" % (names, r.stderr.strip()[:200]))
seg_bad = os.path.join(TMP, "overlap.seg.nrrd")
write_seg(seg_bad, [lambda i, j, k: 1 if i < 5 else 0, lambda i, j, k: 2 if i >= 3 else 0],
          [("femur", 1), ("tibia", 2)])
expect_error(["info", seg_bad], "overlapping-segments", "overlapping segments in a .seg.nrrd")

# --- cancel (SIGINT) leaves no output ------------------------------------------------------------
big = os.path.join(TMP, "big.nrrd")
write_nrrd(big, (120, 120, 120), ball_values(120))
out_big = os.path.join(TMP, "big.vtu")
p = subprocess.Popen([CLI, "mesh", big, "-o", out_big, "--set", "target_edge_length=1"],
                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
time.sleep(1.5)
p.send_signal(signal.SIGINT)
try:
    _, err = p.communicate(timeout=600)
except subprocess.TimeoutExpired:
    p.kill()
    err = "timeout"
check(p.returncode in (EXIT["canceled"], 0), "SIGINT ends the run (rc=%s)" % p.returncode)
if p.returncode == EXIT["canceled"]:
    check(not os.path.exists(out_big), "canceled run leaves no output file")
leftovers = [f for f in os.listdir(TMP) if ".tmp" in f]
check(not leftovers, "no temporary files left behind: %s" % leftovers)

print("checks: %d passed, %d failed" % (len(passes), len(failures)))
sys.exit(1 if failures else 0)
