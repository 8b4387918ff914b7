#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""`femesher batch` (issue 16, items 1, 2 and 4a) on a CSV manifest of five label maps of the
data folder (mickey, spheres_argmax, example_seg and two CGAL 2x2x2 images with a per-case
parameter file setting min_voxels=1), the built-in phantom and one broken case (a truncated
.nii.gz):
 - the broken case is in the summary (CSV, JSON, HTML) as failed, with its exit code (5) and
   error; the batch exits 14; every good case's outputs are complete and readable (meshio), and
   the summary's tet counts are those of the files;
 - a second run resumes: every good case is up to date and not rerun (outputs untouched), the
   broken one is tried again; touching one input or changing a parameter file reruns exactly
   those cases; a moved output folder still resumes;
 - SIGINT in the middle of a batch: exit 12, a summary of what finished, no case folder with a
   partial set of outputs or a temporary file; the next run completes the rest and skips what
   had finished;
 - a case whose `femesher mesh` crashes (SIGSEGV) is failed with exit 139, the others finish;
 - when the memory available (FEMESHER_MEMORY_AVAILABLE) holds one case's estimate but not two,
   cases never run at the same time, even with --jobs 2; with the machine's memory they do;
 - `--summarise-only` rewrites the same summary from the folder; `--list` prints the cases.
Timeouts only guard against hangs; no time is asserted. With CI=true a missing tool or data file
is a failure."""
import csv
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

CLI = os.environ["FEMESHER_CLI"]
DATA = os.environ.get("FEMESHER_DATA_DIR", "")
IN_CI = os.environ.get("CI") == "true"
TMP = tempfile.mkdtemp(prefix="cli_batch_", dir=os.environ.get("FEMESHER_TMP"))
TEMP = re.compile(r"\.femesher-(tmp|bak)-")
failures = []


def check(cond, msg):
    print(("ok:   " if cond else "FAIL: ") + msg, flush=True)
    if not cond:
        failures.append(msg)


def finish():
    if failures:
        print("%d check(s) failed" % len(failures))
        sys.exit(1)
    shutil.rmtree(TMP, ignore_errors=True)
    print("all checks passed")
    sys.exit(0)


try:
    import meshio
except ImportError:
    check(False, "python3-meshio is installed")
    finish()

names = ["mickey.nrrd", "spheres_argmax.nrrd", "example_seg.nii.gz", "420.nrrd", "12323.nrrd"]
missing = [n for n in names if not os.path.exists(os.path.join(DATA, n))]
if missing:
    check(not IN_CI, "data files present: missing %s" % missing)
    if not IN_CI:
        print("skipped outside CI: missing data")
    finish()

IN = os.path.join(TMP, "in")
os.makedirs(IN)
for n in names:
    shutil.copy(os.path.join(DATA, n), IN)
subprocess.run([CLI, "phantom", os.path.join(IN, "phantom.nrrd")], check=True, capture_output=True)
with open(os.path.join(DATA, "example_seg.nii.gz"), "rb") as f:
    head = f.read(20000)
with open(os.path.join(IN, "broken.nii.gz"), "wb") as f:
    f.write(head)  # cut off: the gzip stream ends early
params = os.path.join(TMP, "tiny.json")
# min_voxels 1 for CGAL's 2 x 2 x 2 cells, and a warning angle above any of their tets (the
# optimised 420 reaches 21 degrees and 12323 41; no mesh but a regular tet reaches 70.5): those runs
# are poor_elements.
subprocess.run([CLI, "mesh", "x.nrrd", "--set", "min_voxels=1", "--set", "min_dihedral_warning=70",
                "--save-parameters", params], check=True, capture_output=True)
manifest = os.path.join(TMP, "cohort.csv")
with open(manifest, "w") as f:
    f.write("# a comment line\ncase,label_map,parameters\n")
    f.write("mickey,in/mickey.nrrd,\nspheres,in/spheres_argmax.nrrd,\n")
    f.write("example_seg,in/example_seg.nii.gz,\ncgal_420,in/420.nrrd,tiny.json\n")
    f.write("cgal_12323,in/12323.nrrd,tiny.json\nphantom,in/phantom.nrrd,\n")
    f.write("broken,in/broken.nii.gz,\n")
GOOD = ["mickey", "spheres", "example_seg", "cgal_420", "cgal_12323", "phantom"]
FORMATS = ["vtu", "msh"]


def batch(out, *extra, inputs=(manifest,)):
    p = subprocess.run([CLI, "batch", *inputs, "-o", out, "--format", ",".join(FORMATS),
                        "--jobs", "2", "--threads", "1", *extra],
                       capture_output=True, text=True, timeout=1200, stdin=subprocess.DEVNULL)
    return p.returncode, p.stderr


def outputs(out, case):
    d = os.path.join(out, case)
    return [os.path.join(d, case + "." + f) for f in FORMATS] + [
        os.path.join(d, "report.json"), os.path.join(d, "parameters.json")]


def temporaries(out):
    return [os.path.join(r, f) for r, _, fs in os.walk(out) for f in fs if TEMP.search(f)]


def summary(out):
    with open(os.path.join(out, "summary.json")) as f:
        return {c["case"]: c for c in json.load(f)["cases"]}


# --list: the manifest's cases, paths relative to the manifest's folder.
p = subprocess.run([CLI, "batch", "--list", manifest], capture_output=True, text=True)
listed = json.loads(p.stdout) if p.returncode == 0 else []
check([c["case"] for c in listed] == GOOD + ["broken"], "--list names the manifest's 7 cases")
check(any(c["case"] == "cgal_420" and c["parameters"] == params for c in listed),
      "--list resolves the parameters column against the manifest's folder")

# 1. First run: the broken case fails, the others are meshed.
OUT = os.path.join(TMP, "out")
rc, err = batch(OUT)
print(err)
check(rc == 14, "a batch with a failed case exits 14 (got %d)" % rc)
s = summary(OUT)
check(sorted(s) == sorted(GOOD + ["broken"]), "summary.json lists the 7 cases")
b = s.get("broken", {})
check(b.get("status") == "failed" and b.get("exit_code") == 5,
      "the broken case is failed with exit code 5 (corrupt file): %s" % b.get("exit_code"))
check("corrupt-file" in b.get("error", "") and "broken.nii.gz" in b.get("error", ""),
      "its error names the problem and the file: %r" % b.get("error", "")[:120])
for case in GOOD:
    c = s.get(case, {})
    check(c.get("status") in ("ok", "poor_elements") and c.get("exit_code") == 0
          and c.get("run") == "meshed", "%s: meshed, status %s" % (case, c.get("status")))
    files = outputs(OUT, case)
    check(all(os.path.getsize(f) > 0 for f in files if os.path.exists(f))
          and all(os.path.exists(f) for f in files), "%s: every output written" % case)
    try:
        meshes = [meshio.read(f) for f in files[:len(FORMATS)]]
        tets = [sum(len(b.data) for b in m.cells if b.type == "tetra") for m in meshes]
        check(tets[0] > 0 and len(set(tets)) == 1 and tets[0] == c.get("tets"),
              "%s: meshio reads %s with %s tets, as the summary says (%s)"
              % (case, "/".join(FORMATS), tets, c.get("tets")))
    except Exception as e:
        check(False, "%s: meshio reads the meshes (%s)" % (case, e))
    check(c.get("worst_dihedral_deg") is not None and c.get("min_dice") is not None
          and c.get("dice"), "%s: worst angle, Dice per label in the summary" % case)
# The lowest Dice of a case is over its labels of >= 1,000 voxels when it has any (example_seg has
# labels of a few voxels whose Dice is low by size alone), the lowest over all labels otherwise.
with open(os.path.join(OUT, "example_seg", "report.json")) as f:
    mats = json.load(f)["fidelity"]["materials"]
big = [m for m in mats if m["voxels"] >= 1000 and m["tets"] > 0]
check(big and [m for m in mats if 0 < m["voxels"] < 1000 and m["tets"] > 0
               and m["dice"] < min(b["dice"] for b in big)],
      "example_seg has small labels below its big ones' Dice (the case this checks)")
low = min(big, key=lambda m: m["dice"])
check(s["example_seg"]["min_dice_label"] == str(low["label"])
      and abs(s["example_seg"]["min_dice"] - low["dice"]) < 1e-9,
      "example_seg's lowest Dice is its lowest label of >= 1,000 voxels (%s, %s; summary %s, %s)"
      % (low["label"], low["dice"], s["example_seg"]["min_dice_label"], s["example_seg"]["min_dice"]))
check(s["cgal_420"]["status"] == "poor_elements" and s["cgal_12323"]["status"] == "poor_elements",
      "a poor_elements run shows as such")
check(any("13 (below min_voxels)" in m for m in s["example_seg"]["missing_labels"]),
      "example_seg's dropped label 13 is a missing label")
check(not temporaries(OUT), "no temporary file in the output folder")
with open(os.path.join(OUT, "summary.csv")) as f:
    rows = {r["case"]: r for r in csv.DictReader(f)}
check(set(rows) == set(s) and rows["broken"]["exit_code"] == "5"
      and rows["mickey"]["tets"] == str(s["mickey"]["tets"]), "summary.csv holds the same table")
with open(os.path.join(OUT, "summary.html")) as f:
    page = f.read()
check(page.count("<tr class=") == 7 and page.count("<svg") == 3 and "<script>" in page
      and "http" not in page.replace("http://www.w3.org/2000/svg", ""),
      "summary.html: 7 rows, 3 inline plots, a script, no network reference")
stamp = {c: os.path.getmtime(outputs(OUT, c)[0]) for c in GOOD}

# 2. Resume: nothing good reruns; the broken case is tried again.
time.sleep(1.1)
rc, err = batch(OUT)
s = summary(OUT)
check(rc == 14, "the second run still exits 14 (the broken case)")
check(all(s[c]["run"] == "up_to_date" for c in GOOD), "every good case is up to date: %s"
      % {c: s[c]["run"] for c in GOOD})
check(all(os.path.getmtime(outputs(OUT, c)[0]) == stamp[c] for c in GOOD),
      "no good case's mesh was rewritten")
check(s["broken"]["run"] == "meshed" and s["broken"]["status"] == "failed",
      "the broken case was tried again and failed again")
check("6 up to date" in err, "the batch says 6 cases are up to date")
# A changed input (its modification time) reruns that case only; a changed parameter file too.
os.utime(os.path.join(IN, "spheres_argmax.nrrd"))
with open(params) as f:
    pj = json.load(f)
pj["smoothing_sigma"] = 0.35
with open(params, "w") as f:
    json.dump(pj, f)
rc, err = batch(OUT)
s = summary(OUT)
rerun = sorted(c for c in GOOD if s[c]["run"] == "meshed")
check(rerun == ["cgal_12323", "cgal_420", "spheres"],
      "a touched input and a changed parameter file rerun exactly their cases: %s" % rerun)

# A moved output folder still resumes (output paths are not part of the fingerprint).
MOVED = os.path.join(TMP, "moved")
os.rename(OUT, MOVED)
rc, err = batch(MOVED)
s = summary(MOVED)
check(all(s[c]["run"] == "up_to_date" for c in GOOD), "a moved output folder resumes: %s"
      % {c: s[c]["run"] for c in GOOD})
os.rename(MOVED, OUT)

# 3. --summarise-only: the same table from the folder.
rc2 = subprocess.run([CLI, "batch", "--summarise-only", OUT], capture_output=True).returncode
s2 = summary(OUT)
check(rc2 == 14 and {c: (v["status"], v["exit_code"], v["tets"]) for c, v in s2.items()} ==
      {c: (v["status"], v["exit_code"], v["tets"]) for c, v in s.items()},
      "--summarise-only rewrites the same statuses, exit codes and tets (exit 14)")

# 4. SIGINT in the middle: exit 12, no partial case; the next run completes it.
OUT2 = os.path.join(TMP, "out2")
small = [os.path.join(IN, n) for n in ("example_seg.nii.gz", "mickey.nrrd", "phantom.nrrd",
                                       "spheres_argmax.nrrd")]
proc = subprocess.Popen([CLI, "batch", *small, "-o", OUT2, "--jobs", "1", "--threads", "1"],
                        stderr=subprocess.PIPE, text=True, stdin=subprocess.DEVNULL)
seen = ""
deadline = time.time() + 600
while time.time() < deadline:
    line = proc.stderr.readline()
    if not line:
        break
    seen += line
    if "[1/4]" in line:
        time.sleep(0.3)  # the second case is running now
        proc.send_signal(signal.SIGINT)
        break
try:
    rest = proc.communicate(timeout=600)[1]
except subprocess.TimeoutExpired:
    proc.kill()
    rest = proc.communicate()[1]
print(seen + rest)
check(proc.returncode == 12, "SIGINT: the batch exits 12 (got %s)" % proc.returncode)
s = summary(OUT2) if os.path.exists(os.path.join(OUT2, "summary.json")) else {}
check(len(s) == 4, "a summary of the 4 cases is written after SIGINT")
done = sorted(c for c, v in s.items() if v["status"] in ("ok", "poor_elements"))
notdone = sorted(c for c, v in s.items() if c not in done)
check(len(done) >= 1 and len(notdone) >= 1 and
      all(s[c]["status"] in ("canceled", "not_run") for c in notdone),
      "finished: %s; canceled or not run: %s" % (done, notdone))
for c in s:
    d = os.path.join(OUT2, c)
    present = [f for f in [c + ".vtu", "report.json", "parameters.json", "batch-case.json"]
               if os.path.exists(os.path.join(d, f))]
    check(len(present) in (0, 4) and (len(present) == 4) == (c in done),
          "%s: all outputs or none (%s)" % (c, present))
check(not temporaries(OUT2), "no temporary file after SIGINT")
proc = subprocess.run([CLI, "batch", *small, "-o", OUT2, "--jobs", "2", "--threads", "1"],
                      capture_output=True, text=True, timeout=1200)
s = summary(OUT2)
check(proc.returncode == 0, "the next run completes (exit %d)" % proc.returncode)
check(all(s[c]["run"] == "up_to_date" for c in done) and
      all(s[c]["run"] == "meshed" and s[c]["status"] in ("ok", "poor_elements") for c in notdone),
      "it skips the finished cases and meshes the others: %s" % {c: v["run"] for c, v in s.items()})

# 5. A crash in one case (SIGSEGV to its `femesher mesh`) does not take down the others.
OUT3 = os.path.join(TMP, "out3")
proc = subprocess.Popen([CLI, "batch", *small[:2], small[3], "-o", OUT3, "--jobs", "1",
                         "--threads", "1"], stderr=subprocess.PIPE, text=True,
                        stdin=subprocess.DEVNULL)


def mesh_children(pid):
    out = []
    for name in os.listdir("/proc"):
        try:
            with open("/proc/%s/stat" % name) as f:
                stat = f.read()
            with open("/proc/%s/cmdline" % name) as f:
                cmd = f.read().split("\0")
        except (OSError, ValueError):
            continue
        fields = stat[stat.rfind(")") + 2:].split()
        if int(fields[1]) == pid and fields[0] != "Z" and "mesh" in cmd and \
                "--memory-estimate" not in cmd:
            out.append((int(name), cmd[2]))
    return out


crashed = None
while proc.poll() is None:
    line = proc.stderr.readline()
    if "[1/3]" in line:
        deadline = time.time() + 30
        while crashed is None and time.time() < deadline:
            kids = mesh_children(proc.pid)
            if kids:
                os.kill(kids[0][0], signal.SIGSEGV)
                crashed = os.path.basename(kids[0][1]).split(".")[0]
            time.sleep(0.02)
        break
rest = proc.communicate(timeout=600)[1]
s = summary(OUT3) if os.path.exists(os.path.join(OUT3, "summary.json")) else {}
check(crashed is not None, "a running case's femesher mesh got SIGSEGV (%s)" % crashed)
check(proc.returncode == 14, "the batch goes on and exits 14 (got %s)" % proc.returncode)
check(s.get(crashed, {}).get("status") == "failed" and s.get(crashed, {}).get("exit_code") == 139
      and "killed by signal 11" in s.get(crashed, {}).get("error", ""),
      "the crashed case is failed with exit 139 (128 + SIGSEGV): %s" % s.get(crashed))
check(sorted(c for c, v in s.items() if v["status"] == "ok") ==
      sorted(c for c in s if c != crashed), "the other two cases are ok: %s" %
      {c: v["status"] for c, v in s.items()})
p = subprocess.run([CLI, "batch", *small[:2], small[3], "-o", OUT3], capture_output=True,
                   text=True, timeout=1200)
check(p.returncode == 0 and not temporaries(OUT3), "the next run meshes it; no temporary file left")

# 6. Memory: with FEMESHER_MEMORY_AVAILABLE below the two smallest estimates together (and not
# below the largest: each fits alone; 1 MB below, as the batch books whole-byte per-process
# shares), cases never overlap in time
# even with --jobs 2; with the machine's memory, two run at once.
three = [small[1], small[2], small[3]]
peaks = [json.loads(subprocess.run([CLI, "mesh", f, "--threads", "1", "--memory-estimate"],
                                   capture_output=True, text=True, check=True).stdout)["peak_bytes"]
         for f in three]
for label, env, expect_overlap in (
        ("room for one case at a time", {"FEMESHER_MEMORY_AVAILABLE":
                                         str(max(sorted(peaks)[0] + sorted(peaks)[1] - 1000000,
                                                 max(peaks)))}, False),
        ("the machine's memory", {}, True)):
    out = os.path.join(TMP, "mem_" + str(expect_overlap))
    p = subprocess.run([CLI, "batch", *three, "-o", out, "--jobs", "2", "--threads", "1"],
                       capture_output=True, text=True, timeout=1200, env=dict(os.environ, **env))
    spans = []
    for c in os.listdir(out):
        rec = os.path.join(out, c, "batch-case.json")
        if os.path.exists(rec):
            with open(rec) as f:
                r = json.load(f)
            spans.append((r["started_unix"], r["finished_unix"]))
    spans.sort()
    overlap = any(b[0] < a[1] for a, b in zip(spans, spans[1:]))
    check(p.returncode == 0 and len(spans) == 3 and overlap == expect_overlap,
          "--jobs 2 with %s: cases overlap in time: %s" % (label, overlap))

# 7. Wrong usage: exit 2 / 3 with a message.
rc, err = batch(os.path.join(TMP, "o3"), "--format", "obj")
check(rc == 2 and "obj" in err, "an unknown --format is exit 2")
p = subprocess.run([CLI, "batch", os.path.join(TMP, "nothing*.nrrd"), "-o", TMP + "/o4"],
                   capture_output=True, text=True)
check(p.returncode == 3 and "No file matches" in p.stderr, "a glob matching nothing is exit 3")
dup = os.path.join(TMP, "dup.csv")
with open(dup, "w") as f:
    f.write("case,label_map\na,in/mickey.nrrd\na,in/phantom.nrrd\n")
p = subprocess.run([CLI, "batch", dup, "-o", TMP + "/o5"], capture_output=True, text=True)
check(p.returncode == 2 and "Two cases are called 'a'" in p.stderr, "duplicate case ids: exit 2")
finish()
