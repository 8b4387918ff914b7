// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file Pipeline.h
/// The whole meshing run: label map in, labelled conformal tet mesh out, plus the run report.
/// This is what the CLI, the panel and the Slicer adapter call. The stages and how they connect
/// are in MeshingRun.h (the stage table in StageTable.h); this file runs them all and assembles
/// the result.

#include <femesher/MeshingRun.h>
#include <femesher/Parameters.h>
#include <femesher/RunContext.h>
#include <femesher/Status.h>
#include <femesher/Types.h>
#include <femesher/stages/Fidelity.h>
#include <femesher/stages/Quality.h>

#include <memory>
#include <string>
#include <vector>

namespace femesher {

struct PipelineResult {
  TetMesh mesh;                     ///< LPS mm, tets labelled with user label ids
  QualityReport quality;
  MeshCheckResult meshCheck;        ///< the check after Optimize: worst angle, poor elements
  FidelityReport fidelity;          ///< empty when compute_fidelity is off
  bool hasFidelity = false;
  /// The interfaces split for contact (parameter contact_pairs; `mesh` has their node copies) and
  /// the nodes on the faces of the input's box: what ExportOptions::contacts and ::nodeSets take.
  std::vector<ContactSurfacePair> contacts;
  std::vector<NamedNodeSet> boxNodeSets;
  /// With element_order 2: the mid-edge nodes curved onto the smooth interfaces (physical LPS, by
  /// tetEdgeKey of `mesh`'s vertices): what ExportOptions::midEdgeNodes takes. Null otherwise.
  std::shared_ptr<const MidEdgePositions> midEdgeNodes;
  /// With element_order 1 and PipelineOptions::keepCurvingData: what curving those nodes needs,
  /// kept from the run, so that a host switched to order 2 afterwards exports the nodes a run at
  /// order 2 would have curved (`deferredCurving->midEdgeNodes(mesh, ctx)`; DeferredCurving.h).
  /// Null without that option, at order 2 (the nodes are in `midEdgeNodes`) and for a run
  /// without indicator functions.
  std::shared_ptr<const DeferredCurving> deferredCurving;
  std::vector<StageTiming> timings; ///< wall seconds per stage, in run order
  std::vector<std::string> warnings;
  /// Counts by name: "surface_samples", "surface_triangles", "vertices", "tets", ...
  ReportCounts counts;
  std::vector<int32_t> droppedLabels;   ///< labels below min_voxels
  std::vector<int32_t> excludedLabels;  ///< labels the user excluded
  /// The adaptive sizing field the run used (null with uniform sizing) and its image geometry
  /// (the working grid placed in the input's physical space): what `femesher sizing` writes.
  std::shared_ptr<const SizingField> sizingField;
  LabelVolume sizingGeometry;
  double totalSeconds = 0;
  std::string reportJson;           ///< the full run report (see RunReport.h)
};

/// What a host asks of a run besides its parameters (nothing a user sets).
struct PipelineOptions {
  /// With element_order 1, keep what curving the mid-edge nodes needs in
  /// PipelineResult::deferredCurving (the indicator functions with their working grid and the
  /// final mesh in the canonical frame: ~160 MB on the knee) for a host that can switch the
  /// element order to 2 after the run: the panel sets it. Off, the run frees them when it ends:
  /// the CLI, where nothing could use them.
  bool keepCurvingData = false;
};

/// Run the full pipeline. Canceled -> Status Canceled. Never writes files.
Result<PipelineResult> runPipeline(const LabelVolume& input, const MeshingParameters& params,
                                   RunContext& ctx, const PipelineOptions& options = {});

/// Improves an existing labelled tet mesh (physical LPS, user labels; e.g. read by readMesh) with
/// the Optimize stage, against the smooth interfaces of the label map it was made from, then
/// measures it (Quality, Fidelity): `femesher optimize`. The result's mesh is the improved one.
Result<PipelineResult> optimizeMesh(const LabelVolume& labels, const TetMesh& mesh,
                                    const MeshingParameters& params, RunContext& ctx);

/// Runs `body`, turning femesher::Error, std::bad_alloc and other exceptions into a Status with a
/// message a user can act on (the boundary every entry point into the stages uses).
Status runGuarded(const std::function<void()>& body);

}  // namespace femesher
