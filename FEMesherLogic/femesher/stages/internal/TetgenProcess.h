// SPDX-License-Identifier: GPL-3.0-or-later
// One TetGen problem in this process, and its wire format between the VolumeMesh stage and the
// helper process `femesher-tetgen-worker` (TetgenJobs.h). This file and its .cxx depend on TetGen
// and the C library only: the helper is built from them alone, so that it starts small.
#pragma once

#include <femesher/VecMath.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <sys/types.h>
#include <vector>

namespace femesher {
namespace volume_detail {

/// One TetGen problem: a closed piecewise-linear complex made of interface triangles.
struct TetgenInput {
  std::vector<Vec3> points;
  std::vector<std::array<int32_t, 3>> triangles;
  std::vector<int> markers;      ///< facet marker per triangle (interface id)
  std::vector<Vec3> holes;       ///< points inside regions TetGen must leave empty
  std::vector<double> sizes;     ///< per point target edge length for -m (empty = none)
  std::vector<int32_t> globalId; ///< per point its index in the whole surface
  int label = -1;                ///< the material it holds (-1: every region, labelled later)
};

/// TetGen's output as plain arrays.
struct TetgenOutput {
  std::vector<double> points;  // 3 per point
  std::vector<int32_t> tets;   // 4 per tet
  std::vector<double> regions; // 1 per tet (region attribute) or empty
};

/// Runs TetGen in this process; returns false (and the error text) when it throws.
bool runTetgen(const TetgenInput& s, const std::string& switches, TetgenOutput& result,
               std::string& error);

/// Writes all n bytes to fd; false on an error.
bool writeAll(int fd, const void* data, size_t n);
/// Everything from `fd` until its end; false on a read error.
bool readAll(int fd, std::vector<char>& out);
/// The problem as the helper reads it: the five array sizes, then the arrays (points, triangles,
/// markers, holes, sizes; native layout: writer and reader come from the same build).
bool writeInput(int fd, const TetgenInput& in);
/// Reads writeInput's bytes; false when they are cut short or inconsistent.
bool readInput(const std::vector<char>& bytes, TetgenInput& in);
/// A TetGen process (the helper, or a forked child right after fork()) must not outlive the run
/// that started it (a run killed by SIGKILL cannot kill it). Linux: SIGKILL when the starting
/// thread ends (PR_SET_PDEATHSIG), then, as the run may have died before that was set, leave at
/// once (exit 4) if it already has (the process was reparented).
void dieWithParent(pid_t parent);
/// The result of one job as the helper (or a forked child) streams it: status, then the arrays
/// or the error text.
bool writeResult(int fd, bool ok, const TetgenOutput& r, const std::string& err);

/// The helper's main: `femesher-tetgen-worker SWITCHES PARENT_PID`, the problem on standard input
/// (as runTetgenJobs writes it), the result on standard output (TetGen's own messages go to
/// standard error). Exit code 0 when the result was written (also a TetGen failure, which the
/// result carries), 2 on bad arguments or input.
int tetgenWorkerMain(int argc, char** argv);

}  // namespace volume_detail
}  // namespace femesher
