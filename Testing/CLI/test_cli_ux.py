#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""The CLI's output for people: the summary at the end of `femesher mesh` (its figures are the run
report's), "Did you mean" for misspelt commands, flags, --set keys and material fields (with the
usual exit codes), and plain progress lines (no Slicer XML, no carriage returns) when stderr is a
file outside Slicer. Uses only the Python standard library."""
import json
import os
import re
import subprocess
import sys
import tempfile

CLI = os.environ["FEMESHER_CLI"]
TMP = tempfile.mkdtemp(prefix="cli_ux_", dir=os.environ.get("FEMESHER_TMP"))
INVALID_ARGUMENT, FILE_NOT_FOUND = 2, 3

failures = []


def check(cond, msg):
    print(("ok:   " if cond else "FAIL: ") + msg)
    if not cond:
        failures.append(msg)


def run(*args):
    return subprocess.run([CLI, *args], capture_output=True, text=True, stdin=subprocess.DEVNULL)


phantom = os.path.join(TMP, "phantom.nrrd")
check(run("phantom", phantom).returncode == 0, "phantom written")

# --- one run with stdout and stderr redirected to one log file, as `> log 2>&1` does -------------
vtu, report, log = (os.path.join(TMP, n) for n in ("phantom.vtu", "phantom.json", "phantom.log"))
with open(log, "w") as f:
    rc = subprocess.call([CLI, "mesh", phantom, "-o", vtu, "--report", report,
                          "--set", "compute_fidelity=true"],
                         stdout=f, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
check(rc == 0 and os.path.exists(report), "mesh with --report, output redirected (rc=%d)" % rc)
with open(log, newline="") as f:
    text = f.read()
rep = json.load(open(report))
print(text)

check("<filter-" not in text, "redirected output holds no Slicer <filter-...> tags")
check("\r" not in text, "redirected output holds no carriage return")
stage_lines = re.findall(r"^  (\S.*?)\s+(\d+\.\d\d) s$", text, re.M)
stage_keys = [s["name"] for s in rep["stages"]]
check(len(stage_lines) == len(stage_keys),
      "one progress line per stage: %d lines, %d stages in the report (%s)"
      % (len(stage_lines), len(stage_keys), [t for t, _ in stage_lines]))
check(all(" " in title and title[0].isupper() for title, _ in stage_lines)
      and not any(title in stage_keys for title, _ in stage_lines),
      "stage lines name the stages in plain words, never by their keys (%s)"
      % [t for t, _ in stage_lines])
check(len(set(t for t, _ in stage_lines)) == len(stage_lines), "each stage line names another stage")

# --- the summary: figures as in the report of the same run ---------------------------------------
summary = text[text.index("Summary\n"):] if "Summary\n" in text else ""
check(summary != "", "the run ends with a summary")
lines = summary.splitlines()
check(len(lines) <= 12, "the summary fits on one screen (%d lines)" % len(lines))
tets, verts = rep["counts"]["tets"], rep["counts"]["vertices"]
m = re.search(r"^  Mesh +(\d+) tets, (\d+) vertices, (\d+) materials", summary, re.M)
check(m is not None and int(m.group(1)) == tets and int(m.group(2)) == verts,
      "summary tet and vertex counts are the report's (%s vs %d, %d)"
      % (m.groups() if m else None, tets, verts))
q = rep["quality"]
for deg in (5, 10, 15):
    count = q["min_dihedral_below_%ddeg" % deg]
    m = re.search(r"^  Below %d deg +(\d+) tets \(([0-9.]+) %%\)$" % deg, summary, re.M)
    check(m is not None and int(m.group(1)) == count
          and abs(float(m.group(2)) - 100.0 * count / tets) < 0.0005 + 1e-9,
          "below %d deg: %s in the summary, %d of %d tets in the report" % (deg, m and m.groups(), count, tets))
fid = rep["fidelity"]
dice = {mat["label"]: mat["dice"] for mat in fid["materials"]}
low = min(dice, key=dice.get)
m = re.search(r"^  Volume Dice +([0-9.]+) lowest \((.*)label (-?\d+)\) \.\. ([0-9.]+) highest$",
              summary, re.M)
check(m is not None and abs(float(m.group(1)) - dice[low]) < 5e-5 and int(m.group(3)) == low
      and abs(float(m.group(4)) - max(dice.values())) < 5e-5,
      "Dice range: lowest with its label and highest as in the report (%s; lowest %d %.4f, highest %.4f)"
      % (m and m.groups(), low, dice[low], max(dice.values())))
# A material without a name of its own (mickey.nrrd names none) is "label N" once, not
# "(label N, label N)".
mickey = os.path.join(os.environ["FEMESHER_DATA_DIR"], "mickey.nrrd")
r = run("mesh", mickey, "-o", os.path.join(TMP, "mickey.vtu"))
m = re.search(r"^  Volume Dice +[0-9.]+ lowest \((.*)\) \.\.", r.stderr, re.M)
check(r.returncode == 0 and m is not None and re.fullmatch(r"label \d+", m.group(1)) is not None,
      "an unnamed material is named once in the summary (%s)" % (m and m.group(0),))
m = re.search(r"^  Boundary p99 +([0-9.]+) voxels mesh to labels, ([0-9.]+) voxels labels to mesh",
              summary, re.M)
check(m is not None and abs(float(m.group(1)) - fid["mesh_to_labels"]["p99"]) < 5e-4
      and abs(float(m.group(2)) - fid["labels_to_mesh"]["p99"]) < 5e-4,
      "boundary p99 both ways as in the report (%s)" % (m and m.groups(),))
m = re.search(r"^Elements: worst dihedral angle ([0-9.e+-]+) deg.*: status (\w+)$", summary, re.M)
worst = rep["mesh_check"]["worst_min_dihedral"]
check(m is not None and m.group(2) == rep["status"]
      and m.group(1) == "%.3g" % worst,
      "worst angle and status as in the report (%s; %s %s)" % (m and m.groups(), worst, rep["status"]))
check(re.search(r"^  Wrote +%s, %s$" % (re.escape(vtu), re.escape(report)), summary, re.M) is not None,
      "the summary names the files written")

# Without fidelity the summary has no Dice line; with -q there is no summary at all.
r = run("mesh", phantom, "-o", os.path.join(TMP, "nofid.vtu"), "--set", "compute_fidelity=false")
check(r.returncode == 0 and "Summary\n" in r.stderr and "Volume Dice" not in r.stderr
      and "Boundary p99" not in r.stderr, "without fidelity: a summary without Dice and distances")
r = run("mesh", phantom, "-o", os.path.join(TMP, "quiet.vtu"), "-q")
check(r.returncode == 0 and "Summary" not in r.stderr and "Below 5 deg" not in r.stderr
      and not re.search(r"^  \S.*\d s$", r.stderr, re.M), "-q: no summary, no stage lines")

# --- "Did you mean" -------------------------------------------------------------------------------
out = os.path.join(TMP, "never.vtu")
cases = [
    (["mesh", phantom, "-o", out, "--set", "edge_lenght_factor=3"], "'edge_lenght_factor'",
     "'edge_length_factor'"),
    (["mesh", phantom, "-o", out, "--set", "material.1.densty=1.1"], "'densty'", "'density'"),
    (["mesh", phantom, "-o", out, "--set", "materal.1.E=500"], "'materal.1.E'", "'material.1.E'"),
    (["mesh", phantom, "-o", out, "--voxel-refinment"], "'--voxel-refinment'", "'--voxel-refinement'"),
    (["mesh", phantom, "-o", out, "--target-edge-lenght", "2"], "'--target-edge-lenght'",
     "'--target-edge-length'"),
    (["mesh", phantom, "-o", out, "--reprot", "r.json"], "'--reprot'", "'--report'"),
    (["mseh", phantom, "-o", out], "'mseh'", "'mesh'"),
    (["qualty", out], "'qualty'", "'quality'"),
    (["optimize", out, "--labels", phantom, "-o", out, "--set", "optimize_min_dihedal=12"],
     "'optimize_min_dihedal'", "'optimize_min_dihedral'"),
]
for args, named, suggested in cases:
    r = run(*args)
    check(r.returncode == INVALID_ARGUMENT and named in r.stderr
          and ("Did you mean %s?" % suggested) in r.stderr and not os.path.exists(out),
          "%s -> exit %d naming %s and suggesting %s (rc=%d: %s)"
          % (" ".join(args[:1] + args[2:]), INVALID_ARGUMENT, named, suggested, r.returncode,
             r.stderr.strip()[:300]))
# Far from every name: no suggestion, the exit codes as before.
r = run("mesh", phantom, "-o", out, "--set", "zzzzzzzz=1")
check(r.returncode == INVALID_ARGUMENT and "Unknown parameter 'zzzzzzzz'" in r.stderr
      and "Did you mean" not in r.stderr, "an unknown key far from all: exit 2, no suggestion")
r = run("mesh", phantom, "-o", out, "--frobnicate")
check(r.returncode == INVALID_ARGUMENT and "--frobnicate" in r.stderr and "Did you mean" not in r.stderr,
      "an unknown flag far from all: exit 2, CLI11's message, no suggestion (%s)" % r.stderr.strip()[:200])
r = run("frobnicate", out)
check(r.returncode == FILE_NOT_FOUND and "Did you mean" not in r.stderr,
      "a word far from every command is still Slicer's input file: exit 3 (rc=%d)" % r.returncode)

print("%d failed" % len(failures))
sys.exit(1 if failures else 0)
