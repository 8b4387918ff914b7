#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Hostile runs of the CLI (issue 14): every failure gives its documented exit code, a message
naming the file, the problem and a remedy, and leaves the output folder exactly as it was (no
partial, temporary or replaced file). Every input is generated here (no binary files):
 - outputs of one run are one transaction: a later output failing (a file size limit, as a full
   disk does) leaves no earlier output and does not replace an existing file; two outputs with
   the same path (-o twice, --report equal to -o, also spelt differently) are refused up front;
 - a .vtu/.vtk write failing (file size limit) is exit 11 with one plain line, not VTK's dump;
 - headers claiming more voxels than the file holds or than the machine's memory;
 - truncated and corrupt compressed data (.nii.gz cut short, NRRD gzip with a flipped byte);
   bzip2 NRRD data, which the reader cannot decode, is said to be that, not damaged;
 - absurd geometry (NaN, infinite, zero or negative spacing, singular directions, an origin that is
   not finite or too far away) in NRRD, NIfTI and MetaImage headers: exit 5 naming the field;
 - two segments with the same LabelValue in one layer of a .seg.nrrd: exit 9 naming both;
 - size-like parameters out of the range the volume allows (max_tet_volume=1e-9 ran for more than
   300 s, target_edge_length=1e-9 crashed TetGen's child): exit 2 at once, from mesh and optimize,
   naming the parameter, the value and the smallest useful value.
A file size limit (RLIMIT_FSIZE, SIGXFSZ ignored) makes writes fail with EFBIG past the limit, as
they fail with ENOSPC on a full disk. Uses only the Python standard library."""
import bz2
import gzip
import os
import resource
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
from hostile_inputs import write_big_gzip_nrrd

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


def run(*args, preexec=None, timeout=None):
    return subprocess.run([CLI, *args], capture_output=True, text=True, stdin=subprocess.DEVNULL,
                          preexec_fn=preexec, timeout=timeout)


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

# ----------------------------------------------------------------------------------------------
# 3. Claimed size against the data present and the memory available, before allocating.
inputs = os.path.join(TMP, "inputs")
os.mkdir(inputs)
quiet = os.path.join(TMP, "quiet")  # the output folder of the mesh runs that must fail
os.mkdir(quiet)
before = listing(quiet)


def mesh_and_info(name, path, code, must_name, words):
    for cmd in ("mesh", "info"):
        extra = ["-o", os.path.join(quiet, "never.vtu")] + fast if cmd == "mesh" else []
        r = run(cmd, path, *extra)
        check_failure("%s (%s)" % (name, cmd), r, code, must_name, words, quiet, before)


def write_nrrd(path, sizes, encoding, body, pad_to=0):
    header = ("NRRD0004\ntype: uint8\ndimension: %d\nsizes: %s\nencoding: %s\n\n"
              % (len(sizes), " ".join(str(s) for s in sizes), encoding)).encode()
    data = header + body
    if pad_to:
        data += b"\0" * (pad_to - len(data))
    with open(path, "wb") as f:
        f.write(data)
    return len(data) - len(header)


# A 240-byte NRRD claiming 100000 x 100000 x 2 voxels: the two byte counts and a remedy, at once.
bomb = os.path.join(inputs, "bomb.nrrd")
present = write_nrrd(bomb, (100000, 100000, 2), "raw", b"", pad_to=240)
check(os.path.getsize(bomb) == 240, "the raw bomb is 240 bytes")
mesh_and_info("raw NRRD claiming 2e10 voxels", bomb, CORRUPT, "bomb.nrrd",
              [("20000000000",), (" %d bytes" % present,), ("re-export",)])
# The same claim with gzip data: deflate cannot expand 1:1032 and more, so also at once.
gzbomb = os.path.join(inputs, "gzbomb.nrrd")
present = write_nrrd(gzbomb, (100000, 100000, 2), "gzip", gzip.compress(b"\0" * 100000))
mesh_and_info("gzip NRRD claiming 2e10 voxels", gzbomb, CORRUPT, "gzbomb.nrrd",
              [("20000000000",), ("%d compressed bytes" % present,), ("re-export",)])
# A detached header whose data file is missing.
nhdr = os.path.join(inputs, "lost.nhdr")
with open(nhdr, "w") as f:
    f.write("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n"
            "data file: lost.raw\n")
mesh_and_info("nhdr without its data file", nhdr, CORRUPT, "lost.raw",
              [("missing",), ("keep the .nhdr and its data file together",)])

# A file whose data is all there but needs more memory than the process may use: an address space
# limit (RLIMIT_AS) below what reading needs. 400^3 uint32 values (256 MB, a 16 KB pattern of
# labels 0..3 repeated so that it compresses about 1:70 as real data does): reading needs
# 256 MB + 4 bytes per value = 512 MB; the limit is 400 MB, which a small map reads within.
AS_LIMIT = 400 * 1000 * 1000
small = os.path.join(inputs, "small.nrrd")
nrrd_ball(small, n=8)
r = run("info", small, preexec=limits(address_space=AS_LIMIT))
check(r.returncode == 0, "a small map reads within the address space limit (rc=%d, %s)"
      % (r.returncode, r.stderr[-300:]))
n = 400
big = os.path.join(inputs, "big.nrrd")
total = write_big_gzip_nrrd(big, n)
for cmd in ("mesh", "info"):
    extra = ["-o", os.path.join(quiet, "never.vtu")] + fast if cmd == "mesh" else []
    r = run(cmd, big, *extra, preexec=limits(address_space=AS_LIMIT))
    check_failure("400^3 uint32 over the memory limit (%s)" % cmd, r, UNREADABLE, "big.nrrd",
                  [("64000000 voxels",), ("%d bytes as stored" % total,),
                   ("needs at least %d bytes" % (total * 2),), ("%d bytes" % AS_LIMIT,),
                   ("crop", "resample")], quiet, before)

# ----------------------------------------------------------------------------------------------
# 4. Truncated and corrupt compressed data: exit 5, never a mesh.


def nifti(n=40):
    """NIfTI-1 (.nii) bytes: uint8, n^3 voxels of 1 mm, a ball of label 1."""
    h = bytearray(352)
    struct.pack_into("<i", h, 0, 348)
    struct.pack_into("<8h", h, 40, 3, n, n, n, 1, 1, 1, 1)
    struct.pack_into("<hh", h, 70, 2, 8)  # datatype uint8, bitpix 8
    struct.pack_into("<8f", h, 76, 1, 1, 1, 1, 0, 0, 0, 0)
    struct.pack_into("<f", h, 108, 352.0)  # vox_offset
    struct.pack_into("<hh", h, 252, 0, 1)  # qform 0, sform 1 (scanner)
    struct.pack_into("<4f", h, 280, 1, 0, 0, 0)
    struct.pack_into("<4f", h, 296, 0, 1, 0, 0)
    struct.pack_into("<4f", h, 312, 0, 0, 1, 0)
    h[344:348] = b"n+1\0"
    c = (n - 1) / 2.0
    data = bytes(1 if (x - c) ** 2 + (y - c) ** 2 + (z - c) ** 2 < (n / 3.0) ** 2 else 0
                 for z in range(n) for y in range(n) for x in range(n))
    return bytes(h) + data


good_nii = gzip.compress(nifti(), mtime=0)
path = os.path.join(inputs, "good.nii.gz")
with open(path, "wb") as f:
    f.write(good_nii)
r = run("info", path)
check(r.returncode == 0, "the generated .nii.gz is read (rc=%d, %s)" % (r.returncode, r.stderr[-300:]))

cut = os.path.join(inputs, "cut.nii.gz")
with open(cut, "wb") as f:
    f.write(good_nii[:len(good_nii) // 5])
mesh_and_info(".nii.gz cut to a fifth", cut, CORRUPT, "cut.nii.gz",
              [("cut off", "truncated"), ("re-export",)])
crc = os.path.join(inputs, "crc.nii.gz")
with open(crc, "wb") as f:
    f.write(good_nii[:-8] + bytes([good_nii[-8] ^ 0x01]) + good_nii[-7:])
mesh_and_info(".nii.gz with a flipped CRC byte", crc, CORRUPT, "crc.nii.gz",
              [("damaged",), ("re-export",)])

gz = os.path.join(inputs, "gz.nrrd")
header_len = nrrd_ball(gz, n=14, encoding="gzip")
r = run("info", gz)
check(r.returncode == 0, "the generated gzip NRRD is read (rc=%d, %s)" % (r.returncode, r.stderr[-300:]))
with open(gz, "rb") as f:
    good = f.read()
body = len(good) - header_len
# Flipped bytes: in the gzip trailer (CRC-32, length) and across the deflate data (after the
# 10-byte gzip header). Each must be exit 5; none may be meshed.
positions = [len(good) - 8, len(good) - 5, len(good) - 2] + \
            [header_len + 10 + k * (body - 18) // 6 for k in range(6)]
for i, pos in enumerate(positions):
    flipped = os.path.join(inputs, "flip%d.nrrd" % i)
    with open(flipped, "wb") as f:
        f.write(good[:pos] + bytes([good[pos] ^ 0x10]) + good[pos + 1:])
    mesh_and_info("gzip NRRD, byte %d of %d flipped" % (pos, len(good)), flipped, CORRUPT,
                  "flip%d.nrrd" % i, [("damaged",), ("re-export",)])
cutnrrd = os.path.join(inputs, "cut.nrrd")
with open(cutnrrd, "wb") as f:
    f.write(good[:header_len + body // 2])
mesh_and_info("gzip NRRD cut in half", cutnrrd, CORRUPT, "cut.nrrd",
              [("cut off", "truncated"), ("re-export",)])

# bzip2 NRRD data: not damaged, but ITK's NRRD reader cannot decode it; say so (exit 4).
bz = os.path.join(inputs, "bz.nrrd")
with open(bz, "wb") as f:
    f.write(b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: bzip2\n\n" +
            bz2.compress(bytes([1]) * 64))
mesh_and_info("bzip2 NRRD", bz, UNREADABLE, "bz.nrrd",
              [("bzip2",), ("not damaged",), ("gzip or raw",)])

# ----------------------------------------------------------------------------------------------
# 5. Absurd geometry (exit 5, an invalid header): the message names the file, the field and its
# value, and says to fix the header and check it with `femesher info`. NaN/infinite/zero/negative
# spacing, direction vectors that are not finite, zero or dependent, an origin that is not finite
# or so far away that voxel positions lose their precision.
GEO_REMEDY = [("fix the header",), ("femesher info",)]


def nrrd_geometry(path, fields, n=8):
    """A uint8 NRRD ball of label 1 whose geometry lines are `fields` (a string)."""
    c = (n - 1) / 2.0
    data = bytes(1 if (x - c) ** 2 + (y - c) ** 2 + (z - c) ** 2 < (n / 2.6) ** 2 else 0
                 for z in range(n) for y in range(n) for x in range(n))
    with open(path, "wb") as f:
        f.write(("NRRD0004\ntype: uint8\ndimension: 3\nsizes: %d %d %d\n%s\nkinds: domain domain "
                 "domain\nencoding: raw\n\n" % (n, n, n, fields)).encode() + data)


LPS = "space: left-posterior-superior\n"
nrrd_cases = [
    ("spacings nan", "spacings: nan 1 1", ["spacings", "'nan'", "finite"]),
    ("spacings inf", "spacings: 1 inf 1", ["spacings", "'inf'", "finite"]),
    ("spacings 0", "spacings: 1 1 0", ["spacings", "'0'", "greater than 0"]),
    ("spacings negative", "spacings: -0.5 1 1", ["spacings", "'-0.5'", "greater than 0"]),
    ("space directions nan", LPS + "space directions: (nan,0,0) (0,1,0) (0,0,1)",
     ["space directions", "(nan, 0, 0)", "finite"]),
    ("space directions inf", LPS + "space directions: (1,0,0) (0,inf,0) (0,0,1)",
     ["space directions", "(0, inf, 0)", "finite"]),
    ("space directions zero vector", LPS + "space directions: (1,0,0) (0,0,0) (0,0,1)",
     ["space directions", "(0, 0, 0)", "size 0"]),
    ("space directions singular", LPS + "space directions: (1,0,0) (0,1,0) (1,1,0)",
     ["space directions", "(1,1,0)", "not independent"]),
    ("space origin nan", LPS + "space directions: (1,0,0) (0,1,0) (0,0,1)\nspace origin: (0,nan,0)",
     ["space origin", "(0, nan, 0)", "finite"]),
    ("space origin 1e300", LPS + "space directions: (1,0,0) (0,1,0) (0,0,1)\n"
     "space origin: (1e300,0,0)", ["origin", "1e+300", "precision"]),
    ("space origin 2e12", LPS + "space directions: (1,0,0) (0,1,0) (0,0,1)\n"
     "space origin: (0,0,-2e12)", ["origin", "-2e+12", "within 1e+12"]),
    # Within 1e12 mm, but 1e9 mm is not representable to 1e-6 of a 0.001 mm voxel.
    ("space origin 1e9 with 0.001 mm voxels", LPS + "space directions: (0.001,0,0) (0,0.001,0) "
     "(0,0,0.001)\nspace origin: (1e9,0,0)", ["origin", "1e+09", "precision"]),
]
for i, (name, fields, words) in enumerate(nrrd_cases):
    path = os.path.join(inputs, "geo%d.nrrd" % i)
    nrrd_geometry(path, fields)
    mesh_and_info("NRRD " + name, path, CORRUPT, "geo%d.nrrd" % i,
                  [(w.lower(),) for w in words] + GEO_REMEDY)
# Sane geometry far from 0 (1e5 mm, oblique, anisotropic) is read.
sane = os.path.join(inputs, "sane.nrrd")
nrrd_geometry(sane, LPS + "space directions: (0.6,0.1,0) (-0.1,0.6,0) (0,0,2.5)\n"
              "space origin: (1e5,-3e4,250)")
r = run("info", sane)
check(r.returncode == 0, "sane geometry far from 0 is read (rc=%d, %s)"
      % (r.returncode, r.stderr[-300:]))


def nifti_geometry(pixdim=(1, 1, 1), qform=None, srow=None):
    """nifti() with pixdim[1..3], a qform (quatern_b, c, d, qoffset_x, y, z) or sform rows."""
    b = bytearray(nifti(n=8))
    struct.pack_into("<3f", b, 80, *pixdim)
    if qform is not None:
        struct.pack_into("<hh", b, 252, 1, 0)
        struct.pack_into("<6f", b, 256, *qform)
    if srow is not None:
        struct.pack_into("<12f", b, 280, *srow)
    return bytes(b)


nan, inf = float("nan"), float("inf")
IDENTITY = (1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0)
nifti_cases = [
    ("pixdim nan", dict(pixdim=(nan, 1, 1)), ["pixdim[1]", "nan", "finite"]),
    ("pixdim inf", dict(pixdim=(1, inf, 1)), ["pixdim[2]", "inf", "finite"]),
    ("pixdim 0", dict(pixdim=(1, 1, 0)), ["pixdim[3]", "is 0", "greater than 0"]),
    ("pixdim negative", dict(pixdim=(1, -2, 1)), ["pixdim[2]", "-2", "greater than 0"]),
    ("qoffset nan", dict(qform=(0, 0, 0, 0, nan, 0)), ["qoffset_y", "nan", "finite"]),
    ("srow inf", dict(srow=(1, 0, 0, 0, 0, 1, 0, inf, 0, 0, 1, 0)), ["srow_y", "inf", "finite"]),
    ("sform singular", dict(srow=(1, 0, 0, 0, 0, 1, 0, 0, 1, 1, 0, 0)),
     ["sform", "(1, 1, 0, 0)", "not independent"]),
    ("sform origin 1e30", dict(srow=(1, 0, 0, 1e30, 0, 1, 0, 0, 0, 0, 1, 0)),
     ["srow_x[3]", "origin", "within 1e+12 mm"]),
    ("qoffset 1e13", dict(qform=(0, 0, 0, 0, 0, -1e13)),  # -1e13 as a float32
     ["qoffset_z", "-9999999827968 mm", "within 1e+12 mm"]),
    # Within 1e12 mm but not exact to 1e-6 of a 0.001 mm voxel (ITK passes it on).
    ("sform origin 1e9, 0.001 mm voxels", dict(pixdim=(0.001, 0.001, 0.001), srow=(
        0.001, 0, 0, 1e9, 0, 0.001, 0, 0, 0, 0, 0.001, 0)), ["srow_x[3]", "1e+09 mm", "precision"]),
]
for i, (name, kw, words) in enumerate(nifti_cases):
    for ext, pack in ((".nii", lambda b: b), (".nii.gz", lambda b: gzip.compress(b, mtime=0))):
        path = os.path.join(inputs, "geo%d%s" % (i, ext))
        with open(path, "wb") as f:
            f.write(pack(nifti_geometry(**kw)))
        mesh_and_info("NIfTI%s %s" % (ext, name), path, CORRUPT, "geo%d%s" % (i, ext),
                      [(w.lower(),) for w in words] + GEO_REMEDY)

# MetaImage: ITK passes its geometry through; the same checks name the field and the value.
mha_cases = [
    ("ElementSpacing nan", "ElementSpacing = nan 1 1", ["`elementspacing`", "'nan 1 1'", "finite"]),
    ("Offset inf", "Offset = 0 -inf 0", ["`offset`", "'0 -inf 0'", "finite"]),
    ("ElementSpacing 0", "ElementSpacing = 1 0 1", ["spacing along axis j", "is 0 mm"]),
    ("TransformMatrix singular", "TransformMatrix = 1 0 0 0 1 0 1 1 0",
     ["direction matrix's determinant is 0", "not independent"]),
    ("Offset 1e300", "Offset = 0 0 1e300", ["origin", "1e+300", "precision"]),
]
for i, (name, line, words) in enumerate(mha_cases):
    path = os.path.join(inputs, "geo%d.mha" % i)
    n = 8
    with open(path, "wb") as f:
        f.write(("ObjectType = Image\nNDims = 3\nDimSize = %d %d %d\n%s\nElementType = MET_UCHAR\n"
                 "ElementDataFile = LOCAL\n" % (n, n, n, line)).encode() +
                bytes(1 if 1 < x < 6 else 0 for z in range(n) for y in range(n) for x in range(n)))
    mesh_and_info("MetaImage " + name, path, CORRUPT, "geo%d.mha" % i,
                  [(w.lower(),) for w in words] + GEO_REMEDY)

# ----------------------------------------------------------------------------------------------
# 6. Two segments with the same LabelValue in one layer of a .seg.nrrd: exit 9 (every voxel of
# that value would belong to both), naming both segments, the value and a remedy. The same
# LabelValue in two layers is how 3D Slicer stores overlapping segments and stays accepted.
def seg_nrrd(path, layers, segments, n=8):
    """A .seg.nrrd: `layers` functions (i, j, k) -> value (one layer: 3-D, else a "list" axis
    first); `segments` are (name, LabelValue, layer)."""
    vals = bytes(layer(i, j, k) for k in range(n) for j in range(n) for i in range(n)
                 for layer in layers)
    if len(layers) == 1:
        header = ("NRRD0004\ntype: unsigned char\ndimension: 3\nsizes: %d %d %d\n"
                  "kinds: domain domain domain\nspace: left-posterior-superior\n"
                  "space directions: (1,0,0) (0,1,0) (0,0,1)\n" % (n, n, n))
    else:
        header = ("NRRD0004\ntype: unsigned char\ndimension: 4\nsizes: %d %d %d %d\n"
                  "kinds: list domain domain domain\nspace: left-posterior-superior\n"
                  "space directions: none (1,0,0) (0,1,0) (0,0,1)\n" % (len(layers), n, n, n))
    header += "space origin: (0,0,0)\nencoding: raw\nendian: little\n"
    for idx, (name, value, layer) in enumerate(segments):
        header += ("Segment%d_ID:=Segment_%d\nSegment%d_Name:=%s\nSegment%d_Color:=0.1 0.2 0.3\n"
                   "Segment%d_LabelValue:=%d\nSegment%d_Layer:=%d\n"
                   % (idx, idx, idx, name, idx, idx, value, idx, layer))
    with open(path, "wb") as f:
        f.write((header + "\n").encode() + vals)


left = lambda i, j, k: 1 if i < 4 and 1 < j < 7 and 1 < k < 7 else 0
right = lambda i, j, k: 2 if i >= 4 and 1 < j < 7 and 1 < k < 7 else 0
both = lambda i, j, k: left(i, j, k) or right(i, j, k)
seg_ok1 = os.path.join(inputs, "ok1.seg.nrrd")
seg_nrrd(seg_ok1, [both], [("femur", 1, 0), ("tibia", 2, 0)])
seg_ok2 = os.path.join(inputs, "ok2.seg.nrrd")  # value 1 in two layers: Slicer's overlap layout
seg_nrrd(seg_ok2, [left, lambda i, j, k: 1 if i >= 4 and 1 < j < 7 and 1 < k < 7 else 0],
         [("femur", 1, 0), ("tibia", 1, 1)])
for path in (seg_ok1, seg_ok2):
    r = run("info", path)
    check(r.returncode == 0, "%s is read (rc=%d, %s)" % (os.path.basename(path), r.returncode,
                                                          r.stderr[-300:]))
dup_cases = [
    ("one layer", [both], [("femur", 1, 0), ("tibia", 2, 0), ("patella", 1, 0)],
     ["'femur' (id segment_0)", "'patella' (id segment_2)", "labelvalue 1 in layer 0"]),
    ("two layers", [both, lambda i, j, k: 1 if k == 0 else 0],
     [("femur", 1, 0), ("tibia", 2, 0), ("cartilage", 1, 1), ("fibula", 2, 0)],
     ["'tibia' (id segment_1)", "'fibula' (id segment_3)", "labelvalue 2 in layer 0"]),
]
for i, (name, layers, segs, words) in enumerate(dup_cases):
    path = os.path.join(inputs, "dup%d.seg.nrrd" % i)
    seg_nrrd(path, layers, segs)
    mesh_and_info(".seg.nrrd duplicate LabelValue, " + name, path, 9, "dup%d.seg.nrrd" % i,
                  [(w,) for w in words] + [("re-export",), ("3d slicer",)])

# ----------------------------------------------------------------------------------------------
# 7. Size-like parameters against the volume (the 14^3 ball of 1 mm voxels): refused before any
# stage with exit 2, the parameter, its value, the smallest useful value and a remedy. A generous
# timeout only guards against the hang these values caused.
ranges = os.path.join(TMP, "ranges")
os.mkdir(ranges)
before = listing(ranges)
range_cases = [
    ("max_tet_volume=1e-9", ["tets", "50 m tets"], ["use max_tet_volume >="]),
    ("target_edge_length=1e-9", ["tets", "smallest useful value"], ["use a value >="]),
    ("h_max=1e-6", ["smallest useful value"], ["use h_max >="]),
    ("h_min=1e-6", ["smallest voxel spacing"], ["use h_min >="]),
    ("facet_distance=1e-6", ["0.02 voxels"], ["use facet_distance >="]),
]
for setting, why, remedy in range_cases:
    key, value = setting.split("=")
    try:
        r = run("mesh", ball, "-o", os.path.join(ranges, "never.vtu"), "--set", setting, *fast,
                timeout=120)
    except subprocess.TimeoutExpired:
        check(False, "--set %s: refused at once (still running after 120 s)" % setting)
        continue
    check_failure("--set " + setting, r, INVALID_ARGUMENT, "ball.nrrd",
                  [(key,), ("%g" % float(value),)] + [(w,) for w in why] + [tuple(remedy)],
                  ranges, before)
# femesher optimize checks the same ranges (its sizing field follows target_edge_length).
try:
    r = run("optimize", os.path.join(ref, "m.vtu"), "--labels", ball, "-o",
            os.path.join(ranges, "never.vtu"), "--set", "target_edge_length=1e-9", "-q", timeout=120)
    check_failure("optimize --set target_edge_length=1e-9", r, INVALID_ARGUMENT, "ball.nrrd",
                  [("target_edge_length",), ("1e-09",), ("smallest useful value",)], ranges, before)
except subprocess.TimeoutExpired:
    check(False, "optimize --set target_edge_length=1e-9: refused at once")
# Values within the range still mesh.
r = run("mesh", ball, "-o", os.path.join(ranges, "ok.vtu"), "--set", "max_tet_volume=5", *fast)
check(r.returncode == 0 and os.path.exists(os.path.join(ranges, "ok.vtu")),
      "max_tet_volume=5 meshes (rc=%d, %s)" % (r.returncode, r.stderr[-300:]))

if failures:
    print("\n%d failure(s)" % len(failures))
    sys.exit(1)
shutil.rmtree(TMP, ignore_errors=True)
print("all passed")
