#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Mesh large label maps and measure time and memory of the whole process tree, per stage.

  clinical_size.py [--build build] [--data DIR] [--threads 2] [--keep DIR] [--set k=v ...]
                   [--interval 0.05] [--json out.json] [NAME ...]

NAME: "hip" (the clinical-size hip phantom, `femesher phantom --hip`), "hip:S" (at --scale S),
"colin27x2" (colin27_v3.nrrd upsampled 2x by nearest neighbour, made here with numpy: 362 x 434 x
362 voxels of 0.5 mm), "knee" (9135902_00m_WB01.nii.gz), a file name in DIR, or a path. Default:
knee, colin27x2, hip.

Each volume is meshed once by `femesher mesh IN -o OUT.vtu --report R.json --threads N` (stderr a
pipe: one line per finished stage). While it runs, every --interval seconds the script reads /proc
for the femesher process and all its descendants (TetGen's forked children; /proc/PID/task/*/children)
and sums their resident sizes (VmRSS; pages a fork shares with its parent count in both, as `top`
shows them) and their CPU time (utime + stime, plus cutime + cstime of the ones already reaped).
A stage line on stderr closes the stage it names: its peak is the largest sample since the
previous line, so the first stage's row includes reading the input and the last one's writing the
outputs. Stage wall seconds come from the report; CPU seconds from the samples. Also printed: the
main process's VmHWM (its own peak resident size as the kernel counts it), the largest single
process (ru_maxrss from wait4), per-voxel and per-tet figures, and the load average before and
after (other work on the machine distorts timings: run it alone).

Timings are printed, never asserted."""
import argparse
import gzip
import json
import os
import re
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

from process_tree import PAGE, counts_own_memory, descendants

ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("names", nargs="*")
ap.add_argument("--build", default="build")
ap.add_argument("--data", default=os.environ.get("FEMESHER_DATA_DIR",
                os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../../shared/data")))
ap.add_argument("--threads", type=int, default=2)
ap.add_argument("--keep")
ap.add_argument("--set", action="append", default=[])
ap.add_argument("--interval", type=float, default=0.05)
ap.add_argument("--json")
args = ap.parse_args()
femesher = os.path.abspath(os.path.join(args.build, "bin", "femesher"))
out = args.keep or tempfile.mkdtemp(prefix="clinical_")
os.makedirs(out, exist_ok=True)
TICK = os.sysconf("SC_CLK_TCK")
MB = 1e6  # decimal megabytes, as in the README


def read_nrrd(path):
    """(array z,y,x, header lines) of a gzip or raw NRRD with an attached header."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"\n\n")
    header = data[:end].decode().split("\n")
    fields = dict(l.split(": ", 1) for l in header if ": " in l and not l.startswith("#"))
    sizes = [int(x) for x in fields["sizes"].split()]
    dtype = {"uint8": np.uint8, "unsigned char": np.uint8, "uint16": np.uint16, "ushort": np.uint16,
             "int16": np.int16, "short": np.int16, "int32": np.int32, "int": np.int32}[fields["type"]]
    body = data[end + 2:]
    if fields.get("encoding") in ("gzip", "gz"):
        body = gzip.decompress(body)
    return np.frombuffer(body, dtype=dtype).reshape(sizes[::-1]), fields


def upsample2(src, dst):
    """Nearest-neighbour 2x upsampling of a NRRD label map (each voxel becomes 2 x 2 x 2 of half
    the size, the same physical extent)."""
    a, f = read_nrrd(src)
    b = a.repeat(2, 0).repeat(2, 1).repeat(2, 2)
    dirs = [[float(x) for x in d.strip("()").split(",")] for d in re.findall(r"\([^)]*\)", f["space directions"])]
    origin = [float(x) for x in f["space origin"].strip("()").split(",")]
    # The old voxel centre c covers c +- d/2; its first half-size voxel is centred at c - d/4.
    origin = [origin[r] - sum(dirs[c][r] for c in range(3)) / 4 for r in range(3)]
    half = " ".join("(%s)" % ",".join(repr(x / 2) for x in d) for d in dirs)
    header = ("NRRD0004\n# %s upsampled 2x by nearest neighbour (clinical_size.py)\ntype: %s\n"
              "dimension: 3\nspace: %s\nsizes: %s\nspace directions: %s\nkinds: domain domain domain\n"
              "endian: little\nencoding: gzip\nspace origin: (%s)\n\n") % (
        os.path.basename(src), f["type"], f["space"], " ".join(str(n) for n in b.shape[::-1]), half,
        ",".join(repr(x) for x in origin))
    with open(dst, "wb") as o:
        o.write(header.encode())
        o.write(gzip.compress(np.ascontiguousarray(b).tobytes(), compresslevel=1))


def input_for(name):
    """(path, voxel count) of a benchmark volume, made when it is a generated one."""
    if name == "hip" or name.startswith("hip:"):
        scale = name.split(":")[1] if ":" in name else "1"
        path = os.path.join(out, "hip_%s.nrrd" % scale)
        if not os.path.exists(path):
            subprocess.run([femesher, "phantom", "--hip", "--scale", scale, path], check=True,
                           capture_output=True)
    elif name == "colin27x2":
        path = os.path.join(out, "colin27x2.nrrd")
        if not os.path.exists(path):
            upsample2(os.path.join(args.data, "colin27_v3.nrrd"), path)
    elif name == "knee":
        path = os.path.join(args.data, "9135902_00m_WB01.nii.gz")
    elif os.path.exists(name):
        path = name
    else:
        path = os.path.join(args.data, name)
    info = json.loads(subprocess.run([femesher, "info", path, "--json"], check=True,
                                     capture_output=True, text=True).stdout)
    dims = info["dims"]
    return path, int(np.prod(dims)), dims


def sample(pid):
    """(tree RSS bytes, tree CPU seconds, main RSS bytes, main VmHWM bytes or None, processes)."""
    rss = cpu = 0
    main_rss, hwm = 0, None
    procs = descendants(pid)
    for p in procs:
        try:
            with open("/proc/%d/stat" % p) as f:
                st = f.read().rsplit(")", 1)[1].split()
            # fields after the name: state(0) ... utime(11) stime(12) cutime(13) cstime(14) rss(21)
            cpu += sum(int(x) for x in st[11:15]) / TICK
            r = int(st[21]) * PAGE
            rss += r if counts_own_memory(pid, p) else 0
            if p == pid:
                main_rss = r
                with open("/proc/%d/status" % p) as f:
                    m = re.search(r"VmHWM:\s+(\d+) kB", f.read())
                    hwm = int(m.group(1)) * 1024 if m else None
        except (FileNotFoundError, ProcessLookupError, IndexError):
            pass
    return rss, cpu, main_rss, hwm, len(procs)


def run(name):
    path, voxels, dims = input_for(name)
    stem = re.sub(r"\.(nrrd|nhdr|nii|nii\.gz|mha|mhd|seg\.nrrd)$", "", os.path.basename(path))
    vtu, rep = os.path.join(out, stem + ".vtu"), os.path.join(out, stem + ".report.json")
    sets = [x for kv in args.set for x in ("--set", kv)]
    load0 = os.getloadavg()
    t0 = time.time()
    proc = subprocess.Popen([femesher, "mesh", path, "-o", vtu, "--report", rep, "--threads",
                             str(args.threads), *sets], stderr=subprocess.PIPE, text=True)
    lock = threading.Lock()
    cur = {"rss": 0, "main": 0, "cpu": 0.0, "procs": 1}
    state = {"hwm": 0, "tree_peak": 0, "main_peak": 0, "procs": 1, "cpu": 0.0}
    done = threading.Event()

    def sampler():
        while not done.is_set():
            rss, cpu, main, hwm, n = sample(proc.pid)
            with lock:
                if rss:
                    cur["rss"], cur["main"] = max(cur["rss"], rss), max(cur["main"], main)
                    state["tree_peak"] = max(state["tree_peak"], rss)
                    state["main_peak"] = max(state["main_peak"], main)
                    state["procs"] = max(state["procs"], n)
                    cur["procs"] = max(cur["procs"], n)
                    state["cpu"] = max(state["cpu"], cpu)
                if hwm:
                    state["hwm"] = max(state["hwm"], hwm)
            done.wait(args.interval)

    th = threading.Thread(target=sampler, daemon=True)
    th.start()
    stages, log, last_cpu, summary = [], [], 0.0, False
    for line in proc.stderr:
        log.append(line)
        summary = summary or line.rstrip("\n") == "Summary"  # figures follow, no stage lines
        m = re.match(r"^  (\S.*?)\s+([0-9.]+) s$", line.rstrip("\n"))
        if not m or summary:
            continue
        with lock:
            cpu_now = state["cpu"]
            stages.append({"title": m.group(1), "line_seconds": float(m.group(2)),
                           "cpu_seconds": cpu_now - last_cpu, "tree_peak": cur["rss"],
                           "main_peak": cur["main"], "processes": cur["procs"]})
            last_cpu = cpu_now
            cur["rss"] = cur["main"] = 0
            cur["procs"] = 1
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.time() - t0
    done.set()
    th.join()
    proc.returncode = os.waitstatus_to_exitcode(status)
    cpu_total = usage.ru_utime + usage.ru_stime  # the process and every descendant it reaped
    load1 = os.getloadavg()
    row = {"volume": name, "path": path, "dims": dims, "voxels": voxels, "exit": proc.returncode,
           "wall_seconds": wall, "cpu_seconds": cpu_total, "tree_peak_bytes": state["tree_peak"],
           "main_peak_bytes": state["main_peak"], "main_vmhwm_bytes": state["hwm"],
           "max_single_process_bytes": usage.ru_maxrss * 1024, "max_processes": state["procs"],
           "threads": args.threads, "load_before": load0, "load_after": load1, "stages": stages}
    if proc.returncode not in (0, 10):
        row["stderr"] = "".join(log)[-2000:]
        return row
    report = json.load(open(rep))
    row["tets"] = int(report["counts"]["tets"])
    row["report_counts"] = report["counts"]
    for st, rs in zip(stages, report.get("stages", [])):
        st["name"], st["seconds"] = rs["name"], rs["seconds"]
    return row


def fmt_mb(b):
    return "%.0f" % (b / MB)


rows = []
for name in args.names or ["knee", "colin27x2", "hip"]:
    r = run(name)
    rows.append(r)
    print("\n### %s: %s voxels (%s), exit %d, %d threads, load average %.2f before, %.2f after" % (
        name, format(r["voxels"], ","), " x ".join(str(d) for d in r["dims"]), r["exit"], args.threads,
        r["load_before"][0], r["load_after"][0]), flush=True)
    if "stderr" in r:
        print(r["stderr"])
        continue
    print("| stage | wall s | CPU s | peak tree RSS MB | peak main RSS MB | processes |")
    print("|---|---|---|---|---|---|")
    for st in r["stages"]:
        print("| %s | %.1f | %.1f | %s | %s | %d |" % (st.get("name", st["title"]), st.get("seconds", st["line_seconds"]),
                                                      st["cpu_seconds"], fmt_mb(st["tree_peak"]),
                                                      fmt_mb(st["main_peak"]), st["processes"]))
    v, t = r["voxels"], max(1, r["tets"])
    print("| **run** | %.1f | %.1f | %s | %s (VmHWM %s) | %d |" % (r["wall_seconds"], r["cpu_seconds"],
          fmt_mb(r["tree_peak_bytes"]), fmt_mb(r["main_peak_bytes"]), fmt_mb(r["main_vmhwm_bytes"]), r["max_processes"]))
    print("\n%s tets; %.3f us wall and %.3f us CPU per voxel, %.1f us wall per tet; peak tree %.1f bytes "
          "per voxel, %.0f bytes per tet; largest single process %s MB" % (
              format(r["tets"], ","), 1e6 * r["wall_seconds"] / v, 1e6 * r["cpu_seconds"] / v,
              1e6 * r["wall_seconds"] / t, r["tree_peak_bytes"] / v, r["tree_peak_bytes"] / t,
              fmt_mb(r["max_single_process_bytes"])), flush=True)

if len(rows) > 1:
    print("\n| volume | voxels | tets | wall s | CPU s | tree peak MB | main VmHWM MB | us/voxel | us/tet | B/voxel | B/tet |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        if "stderr" in r:
            print("| %s | failed (exit %d) |" % (r["volume"], r["exit"]))
            continue
        v, t = r["voxels"], max(1, r["tets"])
        print("| %s | %s | %s | %.1f | %.1f | %s | %s | %.3f | %.1f | %.1f | %.0f |" % (
            r["volume"], format(v, ","), format(r["tets"], ","), r["wall_seconds"], r["cpu_seconds"],
            fmt_mb(r["tree_peak_bytes"]), fmt_mb(r["main_vmhwm_bytes"]), 1e6 * r["wall_seconds"] / v,
            1e6 * r["wall_seconds"] / t, r["tree_peak_bytes"] / v, r["tree_peak_bytes"] / t))
if args.json:
    json.dump(rows, open(args.json, "w"), indent=1)
