#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Signals (issue 14, item 7): a run is canceled from the first byte read to the last rename.
 - SIGINT / SIGTERM while the input is read: exit 12 with the meshing-stage cancel's message,
   nothing written (the process used to die by the signal without a word);
 - SIGINT once the last stage has ended (report, exports): exit 12, no output and no temporary
   file (it used to be ignored and every output written);
 - temporary files of a dead process (SIGKILL) are removed by the next run writing to that
   folder; those of a live process and other names are kept;
 - TetGen workers die with their parent: SIGKILL the run during VolumeMesh, and none of its
   children is left two seconds later;
 - phantom, sizing, medial-axis and quality --raster: exit 12 and nothing left, whether the
   signal comes while they compute or while they write.
Timeouts only guard against hangs; they are not what a case measures. Every input is generated
here."""
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from hostile_inputs import write_big_gzip_nrrd

CLI = os.environ["FEMESHER_CLI"]
TMP = tempfile.mkdtemp(prefix="cli_signals_", dir=os.environ.get("FEMESHER_TMP"))
CANCELED = 12
MESSAGE = "error [canceled]: The run was canceled."
TEMP = re.compile(r"^\..+\.femesher-(tmp|bak)-([0-9]+)-[0-9]+")

failures = []


def check(cond, msg):
    print(("ok:   " if cond else "FAIL: ") + msg)
    if not cond:
        failures.append(msg)


def listing(folder):
    return sorted(os.listdir(folder))


def start(*args):
    """The CLI with stderr as a pipe (its stage lines, one per finished stage)."""
    return subprocess.Popen([CLI, *args], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, bufsize=1)


def finish(p, timeout=300):
    try:
        _, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        p.kill()
        _, err = p.communicate()
        err += "\n(killed by the test after %d s)" % timeout
    return p.returncode, err


def wait_for_line(p, text, timeout=600):
    """Reads p's stderr until a line containing `text`; returns what was read (None at EOF)."""
    seen = []
    deadline = time.time() + timeout
    while time.time() < deadline:
        line = p.stderr.readline()
        if not line:
            return None
        seen.append(line)
        if text in line:
            return "".join(seen)
    return None


def opened(pid, path):
    """True when process `pid` has `path` open."""
    fd_dir = "/proc/%d/fd" % pid
    try:
        for fd in os.listdir(fd_dir):
            try:
                if os.readlink(os.path.join(fd_dir, fd)) == path:
                    return True
            except OSError:
                pass
    except OSError:
        pass
    return False


def children(pid):
    """Live (not zombie) processes whose parent is `pid`."""
    out = []
    for name in os.listdir("/proc"):
        if not name.isdigit():
            continue
        try:
            with open("/proc/%s/stat" % name) as f:
                stat = f.read()
        except OSError:
            continue
        fields = stat[stat.rfind(")") + 2:].split()
        if int(fields[1]) == pid and fields[0] != "Z":
            out.append(int(name))
    return out


def alive(pid):
    try:
        with open("/proc/%d/stat" % pid) as f:
            stat = f.read()
    except OSError:
        return False
    return stat[stat.rfind(")") + 2:].split()[0] != "Z"


def ball(path, n=14):
    c = (n - 1) / 2.0
    data = bytes(2 if (x - c) ** 2 + (y - c) ** 2 + (z - c) ** 2 < (n / 6.0) ** 2 else
                 1 if (x - c) ** 2 + (y - c) ** 2 + (z - c) ** 2 < (n / 2.6) ** 2 else 0
                 for z in range(n) for y in range(n) for x in range(n))
    with open(path, "wb") as f:
        f.write(("NRRD0004\ntype: uint8\ndimension: 3\nsizes: %d %d %d\nencoding: raw\n\n"
                 % (n, n, n)).encode() + data)


small = os.path.join(TMP, "ball.nrrd")
ball(small)
fast = ["--preset", "coarse", "--set", "compute_fidelity=false"]

# ----------------------------------------------------------------------------------------------
# 1. A signal while the input is read. 400^3 uint32 gzip data (256 MB decoded, checksummed and
# converted: seconds of reading); the signal goes once the process has the file open.
n = 400
big = os.path.join(TMP, "big.nrrd")
write_big_gzip_nrrd(big, n)

for sig in (signal.SIGINT, signal.SIGTERM):
    out = os.path.join(TMP, "read_%s" % sig.name)
    os.mkdir(out)
    p = start("mesh", big, "-o", os.path.join(out, "m.vtu"), "--report", os.path.join(out, "r.json"),
              "--save-parameters", os.path.join(out, "p.json"))
    deadline = time.time() + 120
    while time.time() < deadline and p.poll() is None and not opened(p.pid, big):
        time.sleep(0.001)
    reading = opened(p.pid, big)
    check(reading, "%s while reading: the run opened the input (rc so far %s)" % (sig.name, p.poll()))
    p.send_signal(sig)
    rc, err = finish(p)
    check(rc == CANCELED, "%s while reading: exit 12 (got %s; %s)" % (sig.name, rc, err[-300:]))
    check(MESSAGE in err, "%s while reading: the canceled message (%s)" % (sig.name, err[-300:]))
    check(listing(out) == [], "%s while reading: nothing written (%s)" % (sig.name, listing(out)))

# ----------------------------------------------------------------------------------------------
# 2. Late. SIGINT when Fidelity begins (a stage's line is printed when the next one begins:
# "Measuring quality" ended), and SIGINT once the outputs are being written: the first hidden
# temporary file in the output folder shows that the run is past its last stage; five exports of
# 67 k tets take about 1.5 s, the signal comes within milliseconds.
phantom = os.path.join(TMP, "phantom.nrrd")
r = subprocess.run([CLI, "phantom", phantom, "--voxel-size", "0.5"], capture_output=True, text=True)
check(r.returncode == 0, "phantom written (%s)" % r.stderr[-300:])


def outputs_in(folder):
    args = []
    for ext in (".vtu", ".inp", ".msh", ".feb", ".vtk"):
        args += ["-o", os.path.join(folder, "m" + ext)]
    return args + ["--report", os.path.join(folder, "r.json")]


def wait_for_temporary(p, folder, timeout=600):
    """Waits until `folder` holds a hidden file (an output being written); True when it does."""
    deadline = time.time() + timeout
    while time.time() < deadline and p.poll() is None:
        if any(f.startswith(".") for f in os.listdir(folder)):
            return True
        time.sleep(0.001)
    return False


out = os.path.join(TMP, "late_fidelity")
os.mkdir(out)
p = start("mesh", phantom, *outputs_in(out), "--threads", "2")
check(wait_for_line(p, "Measuring quality") is not None, "late: Fidelity begins")
p.send_signal(signal.SIGINT)
rc, err = finish(p)
check(rc == CANCELED, "SIGINT during Fidelity: exit 12 (got %s; %s)" % (rc, err[-300:]))
check(MESSAGE in err, "SIGINT during Fidelity: the canceled message")
check(listing(out) == [], "SIGINT during Fidelity: no output, no temporary file (%s)" % listing(out))

for sig in (signal.SIGINT, signal.SIGTERM):
    out = os.path.join(TMP, "late_write_%s" % sig.name)
    os.mkdir(out)
    p = start("mesh", phantom, *outputs_in(out), "--threads", "2")
    writing = wait_for_temporary(p, out)
    check(writing, "%s while writing: the run writes its outputs (%s)" % (sig.name, listing(out)))
    p.send_signal(sig)
    rc, err = finish(p)
    check(rc == CANCELED, "%s while writing: exit 12 (got %s; %s)" % (sig.name, rc, err[-300:]))
    check(MESSAGE in err, "%s while writing: the canceled message" % sig.name)
    check(listing(out) == [], "%s while writing: no output, no temporary file (%s)"
          % (sig.name, listing(out)))

# ----------------------------------------------------------------------------------------------
# 3. Temporary files of dead processes are removed by the next run into that folder; a live
# process's and every other name are kept.
out = os.path.join(TMP, "stale")
os.mkdir(out)
dead = subprocess.Popen(["true"])
dead.wait()
dead_pid, live_pid = dead.pid, os.getpid()
names = {
    ".m.femesher-tmp-%d-0.vtu" % dead_pid: False,       # stale: removed
    ".r.femesher-bak-%d-3.nii.gz" % dead_pid: False,    # stale backup: removed
    ".m.femesher-tmp-%d-0.vtu" % live_pid: True,        # a live process's: kept
    "m.femesher-tmp-%d-0.vtu" % dead_pid: True,         # not hidden: not the pattern
    ".m.femesher-tmp-%d-0.vtu.keep~" % dead_pid: True,  # more after the extension: not the pattern
    ".m.tmp%d_0.vtu" % dead_pid: True,                  # some other program's name
}
for name in names:
    with open(os.path.join(out, name), "w") as f:
        f.write("x\n")
os.mkdir(os.path.join(out, ".d.femesher-tmp-%d-0.vtu" % dead_pid))  # a folder: never removed
r = subprocess.run([CLI, "mesh", small, "-o", os.path.join(out, "m.vtu"), *fast],
                   capture_output=True, text=True, timeout=300)
check(r.returncode == 0, "run into a folder with stale files (rc=%d, %s)" % (r.returncode, r.stderr[-300:]))
for name, kept in names.items():
    check(os.path.exists(os.path.join(out, name)) == kept,
          "%s is %s" % (name, "kept" if kept else "removed"))
check(os.path.isdir(os.path.join(out, ".d.femesher-tmp-%d-0.vtu" % dead_pid)), "a folder is kept")
check("removed" in r.stderr and ".m.femesher-tmp-%d-0.vtu" % dead_pid in r.stderr,
      "the run says what it removed (%s)" % r.stderr[-300:])

# A run killed by SIGKILL while it writes: whatever it left is gone after the next run.
out = os.path.join(TMP, "killed")
os.mkdir(out)
p = start("mesh", phantom, *outputs_in(out), "--set", "compute_fidelity=false", "--threads", "2")
wait_for_temporary(p, out)
p.kill()
finish(p)
left = [f for f in listing(out) if TEMP.match(f)]
check(left != [], "SIGKILL while writing leaves temporary files (%s)" % listing(out))
r = subprocess.run([CLI, "mesh", small, "-o", os.path.join(out, "next.vtu"), *fast],
                   capture_output=True, text=True, timeout=300)
check(r.returncode == 0, "the next run succeeds (rc=%d)" % r.returncode)
remaining = [f for f in listing(out) if TEMP.match(f) and int(TEMP.match(f).group(2)) == p.pid]
check(remaining == [], "no temporary file of the killed run remains (%s)" % remaining)

# ----------------------------------------------------------------------------------------------
# 4. TetGen workers die with their parent. The ball with max_tet_volume=0.0003 mm^3 as one
# TetGen job (volume_per_material off): about 2 M tets, TetGen alone runs for many seconds (an
# orphaned worker of the old binary lived 19 s). SIGKILL the run once its worker is forked (the
# line of BoundaryMesh, "Meshing the surfaces", is printed when VolumeMesh begins); no worker may
# be left 2 s later.
out = os.path.join(TMP, "workers")
os.mkdir(out)
p = start("mesh", small, "-o", os.path.join(out, "w.vtu"), "--threads", "2",
          "--set", "max_tet_volume=0.0003", "--set", "volume_per_material=false")
seen = wait_for_line(p, "Meshing the surfaces")
check(seen is not None, "the run reaches VolumeMesh")
workers = []
deadline = time.time() + 120
while time.time() < deadline and p.poll() is None and not workers:
    workers = children(p.pid)
    time.sleep(0.01)
check(workers != [], "a TetGen worker was forked (%s)" % workers)
p.kill()
p.wait()  # not communicate(): a surviving worker holds stderr open
deadline = time.time() + 2  # "within a couple of seconds"
while time.time() < deadline and any(alive(w) for w in workers):
    time.sleep(0.05)
survivors = [w for w in workers if alive(w)]
for w in survivors:  # do not leave them running
    try:
        os.kill(w, signal.SIGKILL)
    except OSError:
        pass
check(survivors == [], "no worker outlives the killed run by 2 s (left: %s)" % survivors)
p.stderr.close()

# ----------------------------------------------------------------------------------------------
# 5. The commands that compute and then write one file (phantom, sizing, medial-axis, quality
# --raster): a signal while they compute ends them at once with exit 12, one while they write
# stops the write before its rename; nothing is left either way (they used to die by the signal,
# leaving a temporary file behind when it came during the write).
def expect_canceled(p, out, what):
    rc, err = finish(p)
    check(rc == CANCELED, "%s: exit 12 (got %s; %s)" % (what, rc, err[-300:]))
    check(MESSAGE in err, "%s: the canceled message (%s)" % (what, err[-200:]))
    check(listing(out) == [], "%s: nothing written, no temporary file (%s)" % (what, listing(out)))


hip = os.path.join(TMP, "hip.nrrd")  # 256 x 256 x 200 voxels, for sizing and medial-axis
r = subprocess.run([CLI, "phantom", "--hip", "--scale", "0.5", hip], capture_output=True, text=True)
check(r.returncode == 0, "hip phantom written (%s)" % r.stderr[-300:])

out = os.path.join(TMP, "phantom_computing")
os.mkdir(out)
p = start("phantom", "--hip", os.path.join(out, "h.nrrd"))  # about 10 s of computing
time.sleep(1.0)
p.send_signal(signal.SIGINT)
expect_canceled(p, out, "SIGINT while the hip phantom is computed")

out = os.path.join(TMP, "phantom_writing")
os.mkdir(out)
p = start("phantom", "--hip", os.path.join(out, "h.nrrd"))
check(wait_for_temporary(p, out), "the hip phantom is being written (%s)" % listing(out))
p.send_signal(signal.SIGTERM)
expect_canceled(p, out, "SIGTERM while the hip phantom is written")

for command in ("sizing", "medial-axis"):
    out = os.path.join(TMP, command)
    os.mkdir(out)
    p = start(command, hip, "-o", os.path.join(out, "x.nrrd"))
    deadline = time.time() + 120
    while time.time() < deadline and p.poll() is None and not opened(p.pid, hip):
        time.sleep(0.001)
    time.sleep(1.0)  # past the reading, into the stages (several seconds on this size)
    p.send_signal(signal.SIGINT)
    expect_canceled(p, out, "SIGINT during %s" % command)

mesh = os.path.join(TMP, "ball.vtu")
r = subprocess.run([CLI, "mesh", small, "-o", mesh, *fast], capture_output=True, text=True,
                   timeout=300)
check(r.returncode == 0, "the ball is meshed for quality (%s)" % r.stderr[-300:])
out = os.path.join(TMP, "quality")
os.mkdir(out)
p = start("quality", mesh, "--labels", big, "--raster", os.path.join(out, "r.nrrd"))
deadline = time.time() + 120
while time.time() < deadline and p.poll() is None and not opened(p.pid, big):
    time.sleep(0.001)
p.send_signal(signal.SIGTERM)
expect_canceled(p, out, "SIGTERM while quality --raster reads its label map")

if failures:
    print("\n%d failure(s)" % len(failures))
    sys.exit(1)
shutil.rmtree(TMP, ignore_errors=True)
print("all passed")
