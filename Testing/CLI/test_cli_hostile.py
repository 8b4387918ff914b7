#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Hostile runs of the CLI (issue 14): every failure gives its documented exit code, a message
naming the file, the problem and a remedy, and leaves the output folder exactly as it was (no
partial, temporary or replaced file). Every input is generated here (no binary files):
 - outputs of one run are one transaction: a later output failing (a file size limit, as a full
   disk does) leaves no earlier output and does not replace an existing file; two outputs with
   the same path (-o twice, --report equal to -o, also spelt differently) are refused up front;
 - a .vtu/.vtk write failing (file size limit) is exit 11 with one plain line, not VTK's dump;
A file size limit (RLIMIT_FSIZE, SIGXFSZ ignored) makes writes fail with EFBIG past the limit, as
they fail with ENOSPC on a full disk. Uses only the Python standard library."""
import gzip
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile

CLI = os.environ["FEMESHER_CLI"]
TMP = tempfile.mkdtemp(prefix="cli_hostile_", dir=os.environ.get("FEMESHER_TMP"))
INVALID_ARGUMENT, UNREADABLE, CORRUPT, WRITE_FAILED = 2, 4, 5, 11

failures = []


def check(cond, msg):
    print(("ok:   " if cond else "FAIL: ") + msg)
    if not cond:
        failures.append(msg)


def limits(file_size=None, address_space=None):
    """preexec_fn: a file size limit (writes past it fail with EFBIG) and/or an address space."""
    def apply():
        if file_size is not None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (file_size, file_size))
        if address_space is not None:
            resource.setrlimit(resource.RLIMIT_AS, (address_space, address_space))
    return apply


def run(*args, preexec=None):
    return subprocess.run([CLI, *args], capture_output=True, text=True, stdin=subprocess.DEVNULL,
                          preexec_fn=preexec)


def listing(folder):
    """Every file of `folder` (hidden ones too) with its size and content."""
    out = {}
    for name in sorted(os.listdir(folder)):
        path = os.path.join(folder, name)
        with open(path, "rb") as f:
            out[name] = f.read()
    return out


def one_line_error(stderr):
    lines = [l for l in stderr.splitlines() if l.strip()]
    errors = [l for l in lines if l.startswith("error [")]
    return errors[-1] if errors else ""


def check_failure(name, r, code, must_name, words, folder, before):
    """Exit `code`, an error naming `must_name` and one of `words` (the problem and a remedy), no
    VTK/ITK dump or terminal colours, and `folder` unchanged."""
    err = one_line_error(r.stderr)
    check(r.returncode == code, "%s: exit %d (got %d; stderr %s)" % (name, code, r.returncode,
                                                                     r.stderr[-600:]))
    check(must_name in err, "%s: the message names %s (%s)" % (name, must_name, err))
    for alternatives in words:
        check(any(w in err.lower() for w in alternatives),
              "%s: the message says %s (%s)" % (name, " or ".join(alternatives), err))
    check("\x1b[" not in r.stderr and "vtkXML" not in r.stderr and "ERROR: In " not in r.stderr,
          "%s: no VTK/ITK dump or colours on stderr" % name)
    after = listing(folder)
    check(after == before, "%s: output folder unchanged (before %s, after %s)"
          % (name, sorted(before), sorted(after)))


def nrrd_ball(path, n=14, encoding="raw"):
    """A uint8 NRRD, n^3 voxels of 1 mm: a ball of label 1 and a smaller one of label 2."""
    c = (n - 1) / 2.0
    data = bytearray(n * n * n)
    for z in range(n):
        for y in range(n):
            for x in range(n):
                r2 = (x - c) ** 2 + (y - c) ** 2 + (z - c) ** 2
                data[(z * n + y) * n + x] = 2 if r2 < (n / 6.0) ** 2 else 1 if r2 < (n / 2.6) ** 2 else 0
    body = bytes(data) if encoding == "raw" else gzip.compress(bytes(data), mtime=0)
    header = ("NRRD0004\ntype: uint8\ndimension: 3\nspace: left-posterior-superior\n"
              "sizes: %d %d %d\nspace directions: (1,0,0) (0,1,0) (0,0,1)\nkinds: domain domain "
              "domain\nencoding: %s\nspace origin: (0,0,0)\n\n" % (n, n, n, encoding))
    with open(path, "wb") as f:
        f.write(header.encode() + body)
    return len(header)


ball = os.path.join(TMP, "ball.nrrd")
nrrd_ball(ball)
fast = ["--preset", "coarse", "--set", "compute_fidelity=false", "-q"]

# ----------------------------------------------------------------------------------------------
# 1. One transaction for all outputs of a run.
# Sizes of a good run's outputs, to put a file size limit between them.
ref = os.path.join(TMP, "ref")
os.mkdir(ref)
r = run("mesh", ball, "-o", os.path.join(ref, "m.vtu"), "-o", os.path.join(ref, "m.inp"),
        "--report", os.path.join(ref, "m.json"), *fast)
check(r.returncode == 0, "reference run (rc=%d, %s)" % (r.returncode, r.stderr[-400:]))
size = {e: os.path.getsize(os.path.join(ref, "m" + e)) for e in (".vtu", ".inp", ".json")}
print("output sizes:", size)
check(size[".vtu"] < size[".inp"], "the .vtu is smaller than the .inp (the test needs it)")

out = os.path.join(TMP, "out")
os.mkdir(out)
existing = os.path.join(out, "mesh.vtu")
with open(existing, "w") as f:
    f.write("an existing mesh the failed run must not replace\n")
before = listing(out)

# The .vtu (first) fits under the limit, the .inp (second) does not: nothing may be written, and
# the existing mesh.vtu is not replaced.
limit = (size[".vtu"] + size[".inp"]) // 2
r = run("mesh", ball, "-o", existing, "-o", os.path.join(out, "mesh.inp"), *fast,
        preexec=limits(file_size=limit))
check_failure("second output fails", r, WRITE_FAILED, "mesh.inp",
              [("disk", "space", "full")], out, before)

# The report (last) fails after both meshes were written: no mesh either.
if size[".json"] > max(size[".vtu"], size[".inp"]):
    limit = (max(size[".vtu"], size[".inp"]) + size[".json"]) // 2
    r = run("mesh", ball, "-o", existing, "-o", os.path.join(out, "mesh.inp"),
            "--report", os.path.join(out, "report.json"), *fast, preexec=limits(file_size=limit))
    check_failure("report fails", r, WRITE_FAILED, "report.json", [("disk", "space", "full")],
                  out, before)

# Two outputs that are the same file: refused before any work, naming both spellings.
same = [
    ("-o twice", ["-o", existing, "-o", existing]),
    ("--report = -o", ["-o", existing, "--report", existing]),
    ("--report = -o, other spelling",
     ["-o", existing, "--report", os.path.join(out, "..", "out", ".", "mesh.vtu")]),
    ("--save-parameters = --report",
     ["-o", os.path.join(out, "a.vtu"), "--report", os.path.join(out, "p.json"),
      "--save-parameters", os.path.join(out, "p.json")]),
]
for name, args in same:
    r = run("mesh", ball, *args, *fast)
    err = one_line_error(r.stderr)
    check(r.returncode == INVALID_ARGUMENT, "%s: exit 2 (got %d: %s)" % (name, r.returncode, err))
    paths = [a for a in args if not a.startswith("-")]
    check(all(p in err for p in paths[-2:]) and "same file" in err and "own path" in err,
          "%s: the message names both paths, the problem and the remedy (%s)" % (name, err))
    check(listing(out) == before, "%s: output folder unchanged" % name)

# An output that is a folder: a plain message, not "Success".
folder_out = os.path.join(TMP, "folder.vtu")
os.mkdir(folder_out)
r = run("mesh", ball, "-o", folder_out, *fast)
err = one_line_error(r.stderr)
check(r.returncode == WRITE_FAILED and "folder" in err and "Success" not in err,
      "an output that is a folder: exit 11 and says so (rc=%d: %s)" % (r.returncode, err))

# ----------------------------------------------------------------------------------------------
# 2. VTK's writers checked: a .vtu/.vtk cut by a full disk (file size limit) is exit 11, no file,
# one line naming the file and the cause.
for ext in (".vtu", ".vtk"):
    folder = os.path.join(TMP, "vtk" + ext[1:])
    os.mkdir(folder)
    before = listing(folder)
    r = run("mesh", ball, "-o", os.path.join(folder, "cut" + ext), *fast,
            preexec=limits(file_size=600))
    check_failure(ext + " disk full", r, WRITE_FAILED, "cut" + ext,
                  [("disk is full", "size limit"), ("free", "another disk")], folder, before)

if failures:
    print("\n%d failure(s)" % len(failures))
    sys.exit(1)
shutil.rmtree(TMP, ignore_errors=True)
print("all passed")
