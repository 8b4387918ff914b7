# SPDX-License-Identifier: GPL-3.0-or-later
"""Generated hostile inputs shared by the CLI tests (no binary blobs in the repository)."""
import zlib


def write_big_gzip_nrrd(path, n):
    """A gzip NRRD of n^3 uint32 voxels holding labels 0..3 in a repeating pattern: small on disk,
    n^3 * 4 bytes (and seconds of inflating) once read. Returns that size in bytes."""
    pattern = bytes((i * 7919 >> 5) % 4 for i in range(16384)) * 4  # 64 KB = 16384 uint32 values
    comp = zlib.compressobj(1, zlib.DEFLATED, 16 + 15)
    with open(path, "wb") as f:
        f.write(("NRRD0004\ntype: uint32\ndimension: 3\nsizes: %d %d %d\nendian: little\n"
                 "encoding: gzip\n\n" % (n, n, n)).encode())
        total = n * n * n * 4
        for _ in range(total // len(pattern)):
            f.write(comp.compress(pattern))
        f.write(comp.compress(pattern[:total % len(pattern)]) + comp.flush())
    return total
