# SPDX-License-Identifier: GPL-3.0-or-later
"""Shared set-up of the export tests: mesh the phantom (and a real volume) once per test file with
the femesher CLI and return the paths of every export and of the run report."""
import json
import os
import re
import subprocess
import sys
import tempfile

CLI = os.environ["FEMESHER_CLI"]
DATA = os.environ.get("FEMESHER_DATA_DIR", "")
IN_CI = os.environ.get("CI") == "true"
EXTS = [".vtu", ".vtk", ".inp", ".msh", ".mesh", ".feb", ".stl"]


class Checker:
    def __init__(self):
        self.passed, self.failed = [], []

    def __call__(self, cond, msg):
        (self.passed if cond else self.failed).append(msg)
        print(("ok:   " if cond else "FAIL: ") + msg, flush=True)
        return cond

    def finish(self):
        print("checks: %d passed, %d failed" % (len(self.passed), len(self.failed)))
        sys.exit(1 if self.failed else 0)


def run(args, **kw):
    return subprocess.run(args, capture_output=True, text=True, stdin=subprocess.DEVNULL, **kw)


def mesh_volume(name, source=None, extra=(), exts=EXTS):
    """Meshes `source` (a label map path; None = the built-in phantom) into every format (or
    those of `exts`)."""
    tmp = tempfile.mkdtemp(prefix="exports_%s_" % name, dir=os.environ.get("FEMESHER_TMP"))
    if source is None:
        source = os.path.join(tmp, "phantom.nrrd")
        r = run([CLI, "phantom", source])
        if r.returncode != 0:
            raise SystemExit("femesher phantom failed: " + r.stderr)
    elif not os.path.exists(source):
        if IN_CI:
            raise SystemExit("FAIL: missing data file " + source)
        print("missing data file %s: skipped outside CI" % source)
        sys.exit(0)
    base = os.path.join(tmp, name)
    args = [CLI, "mesh", source, "--report", base + ".json", "-q"]
    for e in exts:
        args += ["-o", base + e]
    args += list(extra)
    r = run(args, timeout=1800)
    if r.returncode != 0:
        raise SystemExit("femesher mesh failed (%d): %s" % (r.returncode, r.stderr))
    report = json.load(open(base + ".json"))
    return base, report, source


def node_lines(ids):
    """Node ids as INP data lines, 16 to a line."""
    return "".join(", ".join(str(n) for n in ids[i:i + 16]) + "\n" for i in range(0, len(ids), 16))


def run_ccx(ccx, work, job, check, timeout):
    """Runs CalculiX on `work`/`job`.inp, checks it exits 0 without *ERROR and wrote `job`.dat,
    and returns the .dat's displacement and total-force blocks (lists of rows of floats)."""
    r = subprocess.run([ccx, "-i", job], cwd=work, capture_output=True, text=True, timeout=timeout,
                       stdin=subprocess.DEVNULL, env=dict(os.environ, OMP_NUM_THREADS="2"))
    out = r.stdout + r.stderr
    check(r.returncode == 0, "%s: ccx exits 0" % job)
    err = out.find("*ERROR")
    check(err < 0, "%s: ccx reports no *ERROR" % job + ("" if err < 0 else ": " + out[err:err + 300]))
    dat = os.path.join(work, job + ".dat")
    check(os.path.exists(dat), "%s: ccx wrote %s.dat" % (job, job))
    text = open(dat).read() if os.path.exists(dat) else ""
    # Blocks of the .dat by their headers (other blocks, e.g. contact stress, are skipped).
    disp, totals = [], []
    for kind, body in dat_blocks(text):
        rows = [[float(x) for x in l.split()] for l in body.strip().splitlines() if l.strip()]
        if kind.startswith("displacements"):
            disp.append(rows)
        elif kind.startswith("total force"):
            totals.append(rows)
    return disp, totals


def dat_blocks(text):
    """(header, body) of each block of a CalculiX .dat ("displacements (vx,vy,vz) for set ...",
    "contact stress (...) ...": a header line starts with a letter, data lines with a number)."""
    parts = re.split(r"\n[ \t]*([a-z][^\n]*)\n", "\n" + text)
    return list(zip(parts[1::2], parts[2::2]))


class InpModel:
    """What the export tests read from an .inp: nodes (id -> xyz array), elements (id -> node ids,
    4 or 10), label_of (element id -> label of its ELSET M<label>_..., None otherwise), the element
    types, nsets (name -> node ids in file order) and surfaces (name -> (element id, face))."""

    def __init__(self, text):
        import numpy as np
        self.nodes, self.elements, self.label_of = {}, {}, {}
        self.types, self.nsets, self.surfaces = set(), {}, {}
        section, name, label = "", None, None
        for line in text.splitlines():
            if line.startswith("**"):
                continue
            if line.startswith("*"):
                section = line.upper()
                m = re.search(r"(?:NSET|NAME)=(\w+)", section)
                name = m.group(1) if m else None
                if section.startswith("*ELEMENT"):
                    self.types.add(re.search(r"TYPE=(\w+)", section).group(1))
                    m = re.search(r"ELSET=M(\d+)_", section)
                    label = int(m.group(1)) if m else None
                continue
            f = [x.strip() for x in line.split(",") if x.strip()]
            if section.startswith("*NODE"):
                self.nodes[int(f[0])] = np.array([float(x) for x in f[1:4]])
            elif section.startswith("*ELEMENT"):
                self.elements[int(f[0])] = [int(x) for x in f[1:]]
                self.label_of[int(f[0])] = label
            elif section.startswith("*NSET"):
                self.nsets.setdefault(name, []).extend(int(x) for x in f)
            elif section.startswith("*SURFACE,"):
                self.surfaces.setdefault(name, []).append((int(f[0]), int(f[1][1:])))
