// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Pipeline.h>
#include <femesher/RunReport.h>

#include <chrono>

namespace femesher {

Status runGuarded(const std::function<void()>& body) {
  try {
    body();
  } catch (const Error& e) {
    return e.status();
  } catch (const std::bad_alloc&) {
    return Status(ErrorCode::MeshingFailed,
                  "Out of memory while meshing. Use a larger element size (target_edge_length) "
                  "or crop the label map.");
  } catch (const std::exception& e) {
    return Status(ErrorCode::Internal, std::string("Unexpected error: ") + e.what());
  }
  return Status::ok();
}

namespace {

/// The result of a run that went through Fidelity (or Quality when fidelity is off).
PipelineResult collect(MeshingRun& run, RunContext& ctx,
                       std::chrono::steady_clock::time_point start, bool keepCurvingData) {
  PipelineResult result;
  run.prepareExport();
  MeshingState& s = run.state();
  result.counts = run.reportCounts();
  result.warnings = ctx.warnings();
  result.totalSeconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.reportJson = runReportJson(run, result.warnings, result.totalSeconds);
  result.contacts = std::move(s.contacts);
  result.boxNodeSets = std::move(s.boxNodeSets);
  result.midEdgeNodes = s.midEdgeNodes;
  result.timings = s.timings;
  result.droppedLabels = s.grid.droppedLabels;
  result.excludedLabels = s.grid.excludedLabels;
  result.sizingField = s.sizingField;
  if (s.sizingField) result.sizingGeometry = run.workingGridGeometry();
  result.hasFidelity = s.hasFidelity;
  result.meshCheck = s.meshCheck;
  result.mesh = std::move(s.mesh);
  result.quality = std::move(s.quality);
  result.fidelity = std::move(s.fidelity);
  // Last: it moves the grid and the indicator functions out of the run.
  if (keepCurvingData && run.parameters().elementOrder != 2)
    result.deferredCurving = run.keepForCurving();
  return result;
}

}  // namespace

Result<PipelineResult> runPipeline(const LabelVolume& input, const MeshingParameters& params,
                                   RunContext& ctx, const PipelineOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  PipelineResult result;
  const Status status = runGuarded([&] {
    MeshingRun run(input, params, ctx);
    run.dropCurvingInputs(!options.keepCurvingData);
    // Before the first stage: warn when the run may not fit in memory (MemoryEstimate.h).
    run.state().memory = estimateRunMemory(input, params);
    if (const std::string w = memoryWarning(run.state().memory); !w.empty()) ctx.warn(w);
    run.runThrough(StageId::Fidelity);
    result = collect(run, ctx, start, options.keepCurvingData);
  });
  if (!status) return status;
  return result;
}

Result<PipelineResult> optimizeMesh(const LabelVolume& labels, const TetMesh& mesh,
                                    const MeshingParameters& params, RunContext& ctx) {
  const auto start = std::chrono::steady_clock::now();
  PipelineResult result;
  const Status status = runGuarded([&] {
    MeshingRun run(labels, params, ctx);
    run.dropCurvingInputs(true);  // nothing curves later (see collect below)
    run.runThrough(StageId::SizingField);  // the sizing field is what Optimize coarsens to
    run.adoptVolumeMesh(mesh);
    run.runThrough(StageId::Fidelity);
    result = collect(run, ctx, start, false);  // the CLI's optimize: nothing switches its order
  });
  if (!status) return status;
  return result;
}

}  // namespace femesher
