// SPDX-License-Identifier: GPL-3.0-or-later
// TetGen jobs of the VolumeMesh stage: each problem runs in a worker process (cancel stops it at
// once, several run side by side) and where the helper is.
#pragma once

#include <femesher/RunContext.h>
#include <femesher/stages/internal/TetgenProcess.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace femesher {
namespace volume_detail {

/// The result of one TetGen job.
struct JobResult {
  bool ok = false;
  std::string error;
  TetgenOutput out;
};

/// Runs TetGen on every input, at most `parallel` at a time, each in a worker process so that a
/// cancel request stops them at once (TetGen itself has no cancel hook) and so that several run
/// side by side: the parent polls the cancel token while it reads the results from pipes, and
/// kills the workers when asked to stop. Inputs start in the given order (put the largest first).
///
/// A worker is the small helper executable `femesher-tetgen-worker` (tetgenWorkerPath), started
/// with posix_spawn: a fresh process that holds only its problem and TetGen's own memory. (A
/// fork()ed child would map every page of the run, the label map and its fields included: on a
/// clinical-size volume each child then shows the parent's gigabytes in its resident size, and
/// the process tree's peak counts them once per child.) Without the helper the job runs in a
/// fork()ed child, and when fork() fails in this process. Progress goes from `p0` to `p1` by the
/// inputs' triangle counts. Helpers start side by side only while the sum of their
/// tetgenHelperBytes fits in the memory available when the jobs began (memoryAvailableForRun;
/// no bound when unknown): on a machine too small for two at once they run one at a time, with a
/// warning, and the result is the same.
std::vector<JobResult> runTetgenJobs(const std::vector<TetgenInput>& inputs,
                                     const std::string& switches, int parallel, RunContext& ctx,
                                     double p0, double p1);

/// A TetGen helper's peak resident size per triangle of its problem, an upper bound of what was
/// measured (colin27's six materials: 1.65-2.9 KB; TetGen's subfaces, segments, tets and flip
/// queues, its whole tetrahedralisation of the problem's hull before the outside is carved).
constexpr double kTetgenHelperBytesPerTriangle = 3000;
/// The peak resident size runTetgenJobs expects of the helper that meshes `input`.
uintmax_t tetgenHelperBytes(const TetgenInput& input);

/// The helper executable the jobs start: $FEMESHER_TETGEN_WORKER when set (empty: none, the jobs
/// fork), otherwise `femesher-tetgen-worker` in ../bin from the FEMesher library's directory (the
/// build and install trees) or in that directory itself; empty when none is executable.
std::string tetgenWorkerPath();

}  // namespace volume_detail
}  // namespace femesher
