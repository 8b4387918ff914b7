// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file MemoryEstimate.h
/// Before a run: the peak resident memory of the run's process tree (the process and TetGen's
/// forked children), estimated from the label map and the parameters, against the memory the
/// machine offers; and a rough wall time for schedulers. `runPipeline` warns (on the run context:
/// stderr in the CLI, the report's `warnings`) when the estimate exceeds what is available, and the
/// report holds both figures
/// (`memory_estimate`).
///
/// The model: the tree's peak is in VolumeMesh, where k = min(threads, materials) TetGen helper
/// processes (`femesher-tetgen-worker`, each holding one material's problem and TetGen's memory)
/// run beside the main process:
///   main = base + perGridMaterialVoxel x working-grid voxels x materials
///               + perInterfaceFace x voxel faces between two labels x (3 / edge length in voxels)^2
///   peak = main x (1 + kTetgenWorkerShare x k)
/// calibrated against `Testing/Benchmarks/clinical_size.py` (the sum of the tree's resident sizes)
/// on the femur phantom, the knee, colin27 and the hip phantom at scales 0.5 and 1, at default
/// parameters and 2 threads (see the README's *Memory*). It is an estimate: kMemoryEstimateFactor
/// is the factor the tests hold it to.

#include <femesher/Parameters.h>
#include <femesher/Types.h>

#include <cstdint>
#include <string>

namespace femesher {

/// The measured peaks of the calibration volumes lie within [estimate / factor, estimate x factor].
constexpr double kMemoryEstimateFactor = 1.5;
/// A TetGen helper's peak resident size as a share of the main process's (see the model above).
constexpr double kTetgenWorkerShare = 0.4;
/// The process tree's peak for a main process of `mainBytes` and `workers` TetGen helpers.
inline uintmax_t treePeakBytes(uintmax_t mainBytes, size_t workers) {
  return uintmax_t(double(mainBytes) * (1 + kTetgenWorkerShare * double(workers)));
}
/// What a scheduler job asks for: this many times MemoryEstimate::seconds, at least
/// kRuntimeRequestMinimumMinutes (measured runs took up to 2.1x the estimate, colin27 upsampled 2x
/// about 1.9x of its CPU seconds / 1.6 and 3.4x of its wall time on a loaded machine; other
/// machines are slower or faster).
constexpr double kRuntimeRequestFactor = 4.0;
constexpr double kRuntimeRequestMinimumMinutes = 10.0;

struct MemoryEstimate {
  size_t gridVoxels = 0;       ///< the labelled box plus the working grid's margin
  size_t materials = 0;        ///< meshed materials (background and excluded ones not counted)
  size_t interfaceFaces = 0;   ///< voxel faces between two different labels (background too)
  uintmax_t mainBytes = 0;     ///< estimated peak resident size of the main process
  uintmax_t peakBytes = 0;     ///< estimated peak resident size of the process tree
  /// Estimated wall seconds of the run at its thread count on a machine like the project's
  /// (2 cores); rough (measured runs took 0.85x to 2.1x of it): schedulers ask for
  /// kRuntimeRequestFactor times it.
  double seconds = 0;
  uintmax_t availableBytes = 0;  ///< what the machine offers the run; 0 when unknown
  std::string availableSource;   ///< where availableBytes comes from
  bool exceeds() const { return availableBytes > 0 && peakBytes > availableBytes; }
};

/// Memory the run may use: the least of MemAvailable (/proc/meminfo), the address-space limit
/// (RLIMIT_AS) and the cgroup's room (memory.max - memory.current of the process's cgroup v2, or
/// v1's memory.limit_in_bytes - memory.usage_in_bytes, when set). The environment variable FEMESHER_MEMORY_AVAILABLE (bytes; for tests, to play a
/// small machine) replaces them all. 0 when unknown. `source` names where the figure came from.
uintmax_t memoryAvailableForRun(std::string* source = nullptr);

/// The estimate for meshing `input` with `params`, and the memory available (one pass over the
/// voxels).
MemoryEstimate estimateRunMemory(const LabelVolume& input, const MeshingParameters& params);

/// The warning for an estimate that exceeds the memory available ("" when it does not).
std::string memoryWarning(const MemoryEstimate& estimate);

}  // namespace femesher
