#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Seeded random multi-material label volumes (issue 12) and a sweep that meshes them.

Families: blobs (overlapping ellipsoids), nested shells with 1-2-voxel layers, noisy k-means-like
maps (nearest of k random centres, distances perturbed by smooth noise; labels fill the box),
boxes, labels cut by the volume border; any of them may get an oblique (rotated) and/or
anisotropic header. Sizes 12^3 to 48^3 (each axis drawn on its own).

API: generate(seed, out_dir=None, max_size=48) -> (name, path of the NRRD file).
CLI: random_volumes.py --count N --seed S --femesher build/bin/femesher [--max-size M] [--json F]
meshes each volume (default parameters, --threads 2), reads each written mesh back with
`femesher quality MESH --labels IN --json` and an independent decoder of the .vtu, and prints a
table (exit code, zero-volume tets, worst angle, share < 5 and < 10 degrees, missing labels,
min Dice), a summary line and a table per family (volumes, failures, zero-volume meshes, how many
reach 5 and 10 degrees, median and lowest worst angle, median lowest Dice, missing labels)."""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "Exports"))
from vtu_decode import read_vtu  # noqa: E402

FAMILIES = ("blobs", "shells", "kmeans", "boxes", "border")
FLAT_RATIO = 1e-12  # volume <= FLAT_RATIO * longest-edge^3 counts as zero (as MeshCheck.h)


def _grid(dims):
    z, y, x = np.meshgrid(*(np.arange(n, dtype=float) for n in dims[::-1]), indexing="ij")
    return x, y, z


def _blobs(rng, dims):
    x, y, z = _grid(dims)
    lab = np.zeros(dims[::-1], np.uint8)
    for label in range(1, int(rng.integers(2, 5)) + 1):
        c = [rng.uniform(0.25, 0.75) * n for n in dims]
        r = [rng.uniform(0.12, 0.35) * min(dims) for _ in range(3)]
        inside = ((x - c[0]) / r[0]) ** 2 + ((y - c[1]) / r[1]) ** 2 + ((z - c[2]) / r[2]) ** 2 < 1
        lab[inside] = label
    return lab


def _shells(rng, dims):
    x, y, z = _grid(dims)
    c = [(n - 1) / 2 + rng.uniform(-1, 1) for n in dims]
    d = np.sqrt((x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2)
    lab = np.zeros(dims[::-1], np.uint8)
    radius = rng.uniform(0.15, 0.25) * min(dims)
    lab[d < radius] = 1
    for label in range(2, int(rng.integers(3, 5)) + 1):
        outer = radius + rng.choice([1.0, 1.5, 2.0])  # 1-2-voxel layers
        lab[(d >= radius) & (d < outer)] = label
        radius = outer
    return lab


def _kmeans(rng, dims):
    x, y, z = _grid(dims)
    k = int(rng.integers(2, 6))
    best = np.full(dims[::-1], np.inf)
    lab = np.zeros(dims[::-1], np.uint8)
    noise = rng.normal(0, 1, (4, 4, 4))
    # smooth noise: trilinear upsampling of a coarse random grid
    idx = [np.clip(a / (n - 1) * 3, 0, 2.999) for a, n in zip((z, y, x), dims[::-1])]
    i0 = [np.floor(a).astype(int) for a in idx]
    f = [a - b for a, b in zip(idx, i0)]
    smooth = np.zeros(dims[::-1])
    for dz in (0, 1):
        for dy in (0, 1):
            for dx in (0, 1):
                w = (f[0] if dz else 1 - f[0]) * (f[1] if dy else 1 - f[1]) * (f[2] if dx else 1 - f[2])
                smooth += w * noise[i0[0] + dz, i0[1] + dy, i0[2] + dx]
    amp = rng.uniform(0.5, 2.0)
    for label in range(1, k + 1):
        c = [rng.uniform(0, n) for n in dims]
        d = np.sqrt((x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2) + amp * smooth * label
        closer = d < best
        best[closer] = d[closer]
        lab[closer] = label
    if rng.random() < 0.5:  # some maps with a background around them
        lab[best > rng.uniform(0.3, 0.5) * min(dims)] = 0
    return lab


def _boxes(rng, dims):
    lab = np.zeros(dims[::-1], np.uint8)
    for label in range(1, int(rng.integers(2, 5)) + 1):
        lo = [int(rng.integers(0, n - 4)) for n in dims]
        hi = [int(min(n, a + rng.integers(3, max(4, n // 2)))) for a, n in zip(lo, dims)]
        lab[lo[2]:hi[2], lo[1]:hi[1], lo[0]:hi[0]] = label
    return lab


def _border(rng, dims):
    lab = _blobs(rng, dims)
    x, y, z = _grid(dims)
    axis = int(rng.integers(0, 3))
    coord = (x, y, z)[axis]
    lab[coord < rng.uniform(2, 0.3 * dims[axis])] = int(lab.max()) + 1  # a slab on a box face
    c = [rng.choice([0.0, n - 1.0]) for n in dims]  # a ball at a box corner
    lab[(x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2 < (0.3 * min(dims)) ** 2] = 1
    return lab


def _rotation(rng):
    q = rng.normal(size=4)
    a, b, c, d = q / np.linalg.norm(q)
    return np.array([[a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
                     [2 * (b * c + a * d), a * a - b * b + c * c - d * d, 2 * (c * d - a * b)],
                     [2 * (b * d - a * c), 2 * (c * d + a * b), a * a - b * b - c * c + d * d]])


def write_nrrd(path, lab, spacing, direction, origin):
    """`lab` indexed [k, j, i]; direction columns are the axes' unit vectors."""
    dirs = " ".join("(%s)" % ",".join("%.17g" % (direction[r, col] * spacing[col]) for r in range(3))
                    for col in range(3))
    header = ("NRRD0004\ntype: unsigned char\ndimension: 3\nsizes: %d %d %d\n"
              "space: left-posterior-superior\nspace directions: %s\nspace origin: (%s)\n"
              "encoding: raw\nendian: little\n\n") % (
        lab.shape[2], lab.shape[1], lab.shape[0], dirs, ",".join("%.17g" % o for o in origin))
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(np.ascontiguousarray(lab, np.uint8).tobytes())


def generate(seed, out_dir=None, max_size=48):
    """Writes one random label volume; returns (name, path)."""
    rng = np.random.default_rng(seed)
    family = FAMILIES[int(rng.integers(0, len(FAMILIES)))]
    dims = [int(rng.integers(12, max(13, max_size + 1))) for _ in range(3)]
    lab = globals()["_" + family](rng, dims)
    if lab.max() == 0:
        lab[tuple(n // 2 for n in lab.shape)] = 1
    spacing, direction, tags = [1.0, 1.0, 1.0], np.eye(3), []
    if rng.random() < 0.4:
        spacing = [float(rng.choice([0.5, 0.8, 1.0, 1.5, 2.5])) for _ in range(3)]
        if len(set(spacing)) == 1:
            spacing[2] *= 2.0
        tags.append("aniso")
    if rng.random() < 0.4:
        direction = _rotation(rng)
        tags.append("oblique")
    origin = [float(rng.uniform(-50, 50)) for _ in range(3)]
    name = "rv%05d_%s_%dx%dx%d%s" % (seed, family, *dims, "".join("_" + t for t in tags))
    out_dir = out_dir or tempfile.mkdtemp(prefix="random_volumes_")
    path = os.path.join(out_dir, name + ".nrrd")
    write_nrrd(path, lab, spacing, direction, origin)
    return name, path


def read_tets(vtu):
    """(points n x 3, tets m x 4) of a written .vtu, decoded without FEMesher."""
    root, values, _ = read_vtu(vtu)
    pts_name = next(a.get("Name") for p in root.iter("Points") for a in p)
    p = np.asarray(values[pts_name], float).reshape(-1, 3)
    return p, np.asarray(values["connectivity"], np.int64).reshape(-1, 4)


def written_mesh_volumes(p, t):
    """Signed volumes over longest-edge^3 of every tet."""
    a, b, c, d = (p[t[:, i]] for i in range(4))
    vol = np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6.0
    edges = [b - a, c - a, d - a, c - b, d - b, d - c]
    longest = np.max([np.linalg.norm(e, axis=1) for e in edges], axis=0)
    return vol / np.maximum(longest ** 3, 1e-300)


def mesh_one(femesher, path, work, extra=()):
    """Meshes one volume and judges the written mesh. Returns a dict of figures."""
    base = os.path.join(work, os.path.basename(path)[:-5])
    out, rep = base + ".vtu", base + ".json"
    r = subprocess.run([femesher, "mesh", path, "-o", out, "--report", rep, "--threads", "2",
                        *extra], capture_output=True, text=True, timeout=900, stdin=subprocess.DEVNULL)
    row = {"exit": r.returncode, "stderr": r.stderr, "written": os.path.exists(out)}
    if r.returncode != 0:
        row["error"] = next((ln for ln in r.stderr.splitlines() if ln.startswith("error")),
                            r.stderr[-200:])
        return row
    report = json.load(open(rep))
    row["status"] = report["status"]
    row["warning_deg"] = report["mesh_check"]["min_dihedral_warning"]
    q = subprocess.run([femesher, "quality", out, "--labels", path, "--json"], capture_output=True,
                       text=True, timeout=900, stdin=subprocess.DEVNULL)
    qj = json.loads(q.stdout)
    points, tets = read_tets(out)
    rel = written_mesh_volumes(points, tets)
    angles = min_dihedral_values(points, tets)
    row["tets"] = len(rel)
    # sign convention of the written mesh: its majority orientation is "positive"
    sign = 1.0 if np.sum(rel > 0) >= np.sum(rel < 0) else -1.0
    row["zero_volume"] = max(int(np.sum(sign * rel <= FLAT_RATIO)),
                             int(qj["quality"]["inverted_tets"]))
    row["worst"] = float(angles.min()) if len(angles) else 0.0
    row["below5"] = float(np.mean(angles < 5)) if len(angles) else 0.0
    row["below10"] = float(np.mean(angles < 10)) if len(angles) else 0.0
    # labels below min_voxels are dropped on purpose (the report says so): judged on the others
    dropped = set(report["input"]["dropped_labels"]) | set(report["input"].get("excluded_labels", []))
    fid = qj.get("fidelity", {})
    dice = [m["dice"] for m in fid.get("materials", []) if m["label"] not in dropped]
    row["min_dice"] = min(dice) if dice else float("nan")
    row["missing"] = [m for m in fid.get("missing_labels", []) if m not in dropped]
    row["dropped"] = sorted(dropped)
    row["elements_line"] = next((ln for ln in r.stderr.splitlines() if ln.startswith("Elements:")), "")
    return row


def min_dihedral_values(p, t):
    """Smallest dihedral angle (degrees) of every tet, from its vertices."""
    faces = [(1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1)]  # face opposite vertex 0..3
    normals = []
    for f in faces:
        a, b, c = (p[t[:, i]] for i in f)
        n = np.cross(b - a, c - a)
        normals.append(n / np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None])
    angles = []
    for i in range(4):
        for j in range(i + 1, 4):
            cosv = -np.einsum("ij,ij->i", normals[i], normals[j])
            angles.append(np.degrees(np.arccos(np.clip(cosv, -1, 1))))
    return np.min(angles, axis=0) if angles else np.zeros(0)


def sweep(femesher, count, seed, max_size=48, work=None, out=sys.stdout):
    work = work or tempfile.mkdtemp(prefix="random_volumes_")
    os.makedirs(work, exist_ok=True)
    rows = []
    print("%-44s %4s %6s %9s %7s %7s %8s %7s %s" % ("volume", "exit", "zero", "worst", "<5deg",
                                                    "<10deg", "missing", "minDice", "status"), file=out)
    for i in range(count):
        name, path = generate(seed * 100003 + i, work, max_size)
        row = mesh_one(femesher, path, work)
        row["name"], row["path"] = name, path
        rows.append(row)
        if row["exit"] != 0:
            print("%-44s %4d  %s" % (name, row["exit"], row["error"][:110]), file=out)
        else:
            print("%-44s %4d %6d %9.4f %6.2f%% %6.2f%% %8s %7.3f %s" % (
                name, row["exit"], row["zero_volume"], row["worst"], 100 * row["below5"],
                100 * row["below10"], ",".join(map(str, row["missing"])) or "-", row["min_dice"],
                row["status"]), file=out)
        out.flush()
    ok = [r for r in rows if r["exit"] == 0]
    reach = sum(r["worst"] >= 5 for r in ok)
    zero = sum(r["zero_volume"] > 0 for r in ok)
    failed = [r for r in rows if r["exit"] != 0]
    reasons = {}
    for r in failed:
        key = r["error"].split("]")[0] + "]" if "]" in r["error"] else r["error"][:40]
        reasons[key] = reasons.get(key, 0) + 1
    print("summary: %d/%d reach worst >= 5 deg; %d meshed (%d status ok, %d poor_elements), "
          "%d with a zero-volume tet written; %d failed%s" % (
              reach, count, len(ok), sum(r["status"] == "ok" for r in ok),
              sum(r["status"] == "poor_elements" for r in ok), zero, len(failed),
              (" (" + ", ".join("%s x%d" % kv for kv in sorted(reasons.items())) + ")") if failed else ""),
          file=out)
    print_family_table(rows, out)
    return rows


def print_family_table(rows, out=sys.stdout):
    """One markdown row per family (and one for all): volumes, failed, zero-volume meshes, share
    reaching 5 and 10 degrees, median and lowest worst angle, median lowest Dice, missing labels."""
    def family(r):
        return r["name"].split("_")[1]
    print("| family | volumes | failed | zero-volume tets | worst >= 5° | worst >= 10° | median worst ° | "
          "lowest worst ° | median min Dice | with a missing label |", file=out)
    print("|---|---|---|---|---|---|---|---|---|---|", file=out)
    for fam in list(FAMILIES) + ["all"]:
        rs = [r for r in rows if fam == "all" or family(r) == fam]
        if not rs:
            continue
        ok = [r for r in rs if r["exit"] == 0]
        worst = sorted(r["worst"] for r in ok)
        dice = sorted(r["min_dice"] for r in ok if r["min_dice"] == r["min_dice"])
        print("| %s | %d | %d | %d | %d | %d | %s | %s | %s | %d |" % (
            fam, len(rs), len(rs) - len(ok), sum(r["zero_volume"] > 0 for r in ok),
            sum(w >= 5 for w in worst), sum(w >= 10 for w in worst),
            "%.1f" % float(np.median(worst)) if worst else "-", "%.2f" % worst[0] if worst else "-",
            "%.3f" % float(np.median(dice)) if dice else "-", sum(bool(r["missing"]) for r in ok)), file=out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--count", type=int, default=10)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--femesher", default="build/bin/femesher")
    ap.add_argument("--max-size", type=int, default=48, help="largest axis size (12..48)")
    ap.add_argument("--work", default=None, help="directory for the volumes and meshes")
    ap.add_argument("--json", default=None, help="write every row (without stderr) to this file")
    a = ap.parse_args()
    rows = sweep(a.femesher, a.count, a.seed, a.max_size, a.work)
    if a.json:
        with open(a.json, "w") as f:
            json.dump([{k: v for k, v in r.items() if k != "stderr"} for r in rows], f, indent=1)


if __name__ == "__main__":
    main()
