#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Mesh every label map in the data folder (and the built-in phantom) and judge the *written* mesh.

  judge_real_volumes.py [--build build] [--judge-build DIR] [--data DIR] [--threads 2] [--keep DIR]
                        [--set k=v ...] [--json out.json] [NAME ...]   (NAME: file names in DIR, or
                        "phantom")

Each volume is meshed at default parameters (plus --set) to a .vtu; the figures are then computed
by `femesher quality OUT.vtu --labels IN --json`, i.e. from the file as a stranger reads it, not from
the run's own report. Printed per volume: tets, worst dihedral angle, share of tets below 5/10/15
degrees, zero-or-negative volumes, the smallest volume Dice over labels of at least 1,000 voxels,
mesh->labels boundary distance p99 (voxels), the Optimize stage's seconds and the run's seconds.
Timings are printed, never asserted. With --judge-build, the meshes of --build (an older checkout,
say) are judged by another build's `femesher quality`: today's reader on yesterday's meshes."""
import argparse
import glob
import json
import os
import subprocess
import tempfile
import time

ap = argparse.ArgumentParser()
ap.add_argument("names", nargs="*")
ap.add_argument("--build", default="build")
ap.add_argument("--judge-build", help="build whose `femesher quality` judges the meshes (default: --build)")
ap.add_argument("--data", default=os.environ.get("FEMESHER_DATA_DIR",
                os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../../shared/data")))
ap.add_argument("--threads", type=int, default=2)
ap.add_argument("--keep")
ap.add_argument("--set", action="append", default=[])
ap.add_argument("--json")
args = ap.parse_args()
femesher = os.path.abspath(os.path.join(args.build, "bin", "femesher"))
judge = os.path.abspath(os.path.join(args.judge_build or args.build, "bin", "femesher"))


def build_env(build):
    # The binary's RUNPATH names the build tree it was linked in: a copy of a build (a frozen binary
    # next to its own lib/) must load its own FEMesher library, not the one being rebuilt there.
    env = dict(os.environ)
    env["LD_LIBRARY_PATH"] = os.pathsep.join(
        [os.path.abspath(os.path.join(build, "lib"))] + [x for x in [os.environ.get("LD_LIBRARY_PATH")] if x])
    return env


mesh_env, judge_env = build_env(args.build), build_env(args.judge_build or args.build)
out = args.keep or tempfile.mkdtemp(prefix="judge_")
os.makedirs(out, exist_ok=True)
names = args.names or (["phantom"] + sorted(os.path.basename(p) for p in glob.glob(os.path.join(args.data, "*"))
                                            if p.endswith((".nrrd", ".nii.gz", ".nii"))))
rows = []
print("| volume | tets | worst ° | %<5° | %<10° | %<15° | vol≤0 | min Dice | labels | m→l p99 | optimize s | run s |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
for name in names:
    if name == "phantom":
        path = os.path.join(out, "phantom.nrrd")
        subprocess.run([femesher, "phantom", path], check=True, capture_output=True, env=mesh_env)
    else:
        path = os.path.join(args.data, name)
    stem = name.split(".")[0]
    vtu, rep = os.path.join(out, stem + ".vtu"), os.path.join(out, stem + ".report.json")
    sets = [x for kv in args.set for x in ("--set", kv)]
    t = time.time()
    p = subprocess.run([femesher, "mesh", path, "-o", vtu, "--report", rep, "--threads", str(args.threads), "-q", *sets],
                       capture_output=True, text=True, env=mesh_env)
    wall = time.time() - t
    if p.returncode not in (0, 10):
        print("| %s | failed (exit %d): %s |" % (name, p.returncode, p.stderr.strip()[-200:]))
        rows.append({"volume": name, "exit": p.returncode})
        continue
    r = json.load(open(rep))
    opt = sum(s["seconds"] for s in r["stages"] if s["name"] == "Optimize")
    j = json.loads(subprocess.run([judge, "quality", vtu, "--labels", path, "--json"], check=True,
                                  capture_output=True, text=True, env=judge_env).stdout)
    q, f = j["quality"], j["fidelity"]
    n = max(1, q["all"]["tets"])
    big = [m for m in f["materials"] if m["voxels"] >= 1000] or f["materials"]
    row = {"volume": name, "tets": q["all"]["tets"], "worst": q["all"]["min_dihedral"]["min"],
           "below5": 100 * q.get("min_dihedral_below_5deg", 0) / n,
           "below10": 100 * q["all"]["min_dihedral"]["bad_share"],
           "below15": 100 * q.get("min_dihedral_below_15deg", 0) / n,
           "nonpositive": q["inverted_tets"],
           "min_dice": min(m["dice"] for m in big), "dice": {str(m["label"]): m["dice"] for m in f["materials"]},
           "m2l_p99": f["mesh_to_labels"]["p99"],
           "l2m_p99": f["labels_to_mesh"]["p99"], "optimize_s": opt, "run_s": wall, "exit": p.returncode,
           "particle_iterations": r["counts"].get("particle_iterations"),
           "particle_converged": bool(r["counts"].get("particle_converged")),
           "stage_seconds": {s["name"]: s["seconds"] for s in r["stages"]}}
    rows.append(row)
    print("| %s | %d | %.3g | %.3f | %.3f | %.3f | %s | %.3f | %d | %.2f | %.2f | %.1f |" % (
        name, row["tets"], row["worst"], row["below5"], row["below10"], row["below15"], row["nonpositive"],
        row["min_dice"], len(f["materials"]), row["m2l_p99"], opt, wall), flush=True)
if args.json:
    json.dump(rows, open(args.json, "w"), indent=1)
