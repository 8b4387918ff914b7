// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// `femesher batch`: a cohort of label maps meshed by child processes of `femesher mesh` (one
// output folder per case, resume, a summary). See the README's *Cohorts*.
#include <femesher/MemoryEstimate.h>
#include <femesher/Parameters.h>
#include <femesher/Types.h>

#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace femesher::cli {

/// Exit code of `femesher batch` when at least one case failed (every other case still ran and
/// the summary was written). A batch that was canceled exits 12, one with invalid arguments 2.
constexpr int kBatchCasesFailedExit = 14;

struct BatchOptions {
  std::vector<std::string> inputs;   ///< folders, glob patterns, label maps, CSV manifests
  std::string outDir;
  std::vector<std::string> formats;  ///< mesh formats (extensions without the dot); default vtu
  int jobs = 0;                      ///< concurrent cases; 0 = from cores and memory
  int threads = 0;                   ///< threads per case; 0 = cores / jobs
  std::string preset;
  std::string parameterFile;         ///< for every case without its own (manifest column)
  std::string labelNames;            ///< for every case without its own (manifest column)
  std::vector<std::string> sets;     ///< --set key=value, for every case
  bool force = false;                ///< mesh every case again (no resume)
  bool quiet = false;
  std::string summariseOnly;         ///< only (re)write the summary of this output folder
  bool list = false;                 ///< print the cases (JSON) and exit: for the Snakefile
};

/// Adds the `batch` subcommand to `app`.
CLI::App* addBatchCommand(CLI::App& app, BatchOptions& options);

/// Runs `femesher batch`: 0 when every case succeeded (or was up to date),
/// kBatchCasesFailedExit when one failed, 12 when canceled, another exit code when the batch
/// itself could not start (no cases, invalid arguments, output folder not writable).
int runBatch(const BatchOptions& options);

/// The JSON `femesher mesh IN --memory-estimate` prints: the estimate for `threads` threads, the
/// per-process share (peak / (1 + TetGen children)) that scales it to other thread counts, and
/// the memory to request from a scheduler (peak x kMemoryEstimateFactor, in MB).
std::string memoryEstimateJson(const std::string& input, const MemoryEstimate& estimate,
                               int threads);

}  // namespace femesher::cli
