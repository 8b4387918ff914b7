# SPDX-License-Identifier: GPL-3.0-or-later
"""The resident memory of a process tree as a scheduler or an OOM killer adds it up: the process
and all its descendants (/proc/PID/task/*/children), each counted once. Shared by
clinical_size.py and Testing/CLI/test_memory_estimate.py."""
import ctypes
import os

PAGE = os.sysconf("SC_PAGE_SIZE")

# A child between posix_spawn's clone(CLONE_VM | CLONE_VFORK) and its exec shares the parent's
# memory (one address space, not copies): its VmRSS is the parent's and must not count again.
# kcmp(KCMP_VM) says whether two processes share it (x86_64 / aarch64 syscall numbers).
_SYS_KCMP = {"x86_64": 312, "aarch64": 272}.get(os.uname().machine)
_LIBC = ctypes.CDLL(None, use_errno=True)


def same_memory(a, b):
    return _SYS_KCMP is not None and _LIBC.syscall(_SYS_KCMP, a, b, 0, 0, 0) == 0  # KCMP_VM = 0


def descendants(pid):
    """pid and every process below it (those that ended meanwhile are skipped)."""
    todo, seen = [pid], []
    while todo:
        p = todo.pop()
        seen.append(p)
        try:
            for t in os.listdir("/proc/%d/task" % p):
                with open("/proc/%d/task/%s/children" % (p, t)) as f:
                    todo += [int(c) for c in f.read().split()]
        except (FileNotFoundError, ProcessLookupError, PermissionError):
            pass
    return seen


def counts_own_memory(root, p):
    """Whether p's resident size adds to the tree of root (not root's address space again)."""
    return p == root or not same_memory(root, p)


def tree_rss(pid):
    """Bytes resident in the tree of pid now."""
    total = 0
    for p in descendants(pid):
        try:
            with open("/proc/%d/stat" % p) as f:
                if counts_own_memory(pid, p):
                    total += int(f.read().rsplit(")", 1)[1].split()[21]) * PAGE
        except (FileNotFoundError, ProcessLookupError, IndexError):
            pass
    return total
