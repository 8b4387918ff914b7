// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file Pipeline.h
/// The whole meshing run: label map in, labelled conformal tet mesh out, plus the run report.
/// This is what the CLI, the panel and the Slicer adapter call.
///
/// Stages (DESIGN.md): LabelPreprocess, IndicatorFunctions, Isosurface, SurfaceSampling
/// (later: MedialAxis, SizingField, Junctions, ParticleSystem), BoundaryMesh, VolumeMesh,
/// Quality, Fidelity. Each stage reports progress and checks cancel through the RunContext.

#include <femesher/Parameters.h>
#include <femesher/RunContext.h>
#include <femesher/Status.h>
#include <femesher/Types.h>
#include <femesher/stages/Fidelity.h>
#include <femesher/stages/Quality.h>

#include <string>
#include <vector>

namespace femesher {

struct StageTiming {
  std::string name;
  double seconds = 0;
};

struct PipelineResult {
  TetMesh mesh;                     ///< LPS mm, tets labelled with user label ids
  QualityReport quality;
  FidelityReport fidelity;          ///< empty when compute_fidelity is off
  bool hasFidelity = false;
  std::vector<StageTiming> timings; ///< wall seconds per stage, in run order
  std::vector<std::string> warnings;
  /// Counts by name: "surface_samples", "surface_triangles", "vertices", "tets", ...
  std::vector<std::pair<std::string, double>> counts;
  std::vector<int32_t> droppedLabels;  ///< labels below min_voxels
  double totalSeconds = 0;
  std::string reportJson;           ///< the full run report (see `runReportJson`)
};

/// Run the full pipeline. Canceled -> Status Canceled. Never writes files.
Result<PipelineResult> runPipeline(const LabelVolume& input, const MeshingParameters& params,
                                   RunContext& ctx);

/// Names of the stages in run order with their progress weights.
std::vector<std::pair<std::string, double>> pipelineStagePlan(const MeshingParameters& params);

}  // namespace femesher
