// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file DeferredCurving.h
/// The curved mid-edge nodes of `element_order` 2, for a run and for a run that has ended.
///
/// A run at element order 2 curves them in `MeshingRun::prepareExport`, with its indicator
/// functions. A run at order 1 drops those functions when it ends, so a host that switches the
/// order to 2 afterwards (the panel) could only write straight-sided mid-edge nodes: not what a run
/// at order 2 writes. `DeferredCurving` keeps what the curving needs with such a result (the
/// indicator functions with their working grid, the final linear mesh in the canonical frame with
/// compact labels, the facet distance and the input's frame) and curves on request, through the
/// same two functions prepareExport uses: the nodes are exactly those of a run at order 2 with the
/// same other parameters (the runs are deterministic; the element order changes nothing before
/// prepareExport).

#include <femesher/QuadraticCurving.h>
#include <femesher/Types.h>
#include <femesher/io/QuadraticTets.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/LabelPreprocess.h>

#include <cstddef>
#include <memory>
#include <mutex>

namespace femesher {

class RunContext;

/// Curves the mid-edge nodes of `canonical` (the run's final linear mesh: canonical frame, compact
/// labels, as VolumeMeshResult holds it) onto the interfaces of `field` (indicatorInterfaces with
/// `facetDistanceVoxels`, default QuadraticCurvingParameters) and puts them in physical LPS with
/// `frame` (the input's header). The figures go to `figures` (its `nodes` emptied).
std::shared_ptr<const MidEdgePositions> curvePhysicalMidEdgeNodes(
    const TetMesh& canonical, const IndicatorField& field, double facetDistanceVoxels,
    const LabelVolume& frame, QuadraticCurvingResult& figures, RunContext& ctx);

/// After the contact split added node copies to `mesh` (its vertices from `firstCopy` on, each
/// exactly where its original is; ContactSplit.h): the curved nodes `nodes` (by tetEdgeKey of the
/// vertices before the split) by tetEdgeKey of `mesh`'s edges, copies included.
std::shared_ptr<const MidEdgePositions> midEdgeNodesWithCopies(const MidEdgePositions& nodes,
                                                               const TetMesh& mesh,
                                                               size_t firstCopy);

class DeferredCurving {
 public:
  /// Takes the run's working grid and its indicator functions (computed on that grid), the final
  /// linear mesh (canonical frame, compact labels), the run's facet distance (voxels) and the
  /// input's header (its labels are not kept).
  DeferredCurving(PreprocessedVolume grid, std::unique_ptr<IndicatorField> field,
                  TetMesh canonical, double facetDistanceVoxels, const LabelVolume& frame);
  DeferredCurving(const DeferredCurving&) = delete;
  DeferredCurving& operator=(const DeferredCurving&) = delete;

  /// The curved mid-edge nodes of `mesh`, the run's result mesh (the canonical mesh in physical
  /// LPS, then the contact copies): what a run at element order 2 puts in
  /// PipelineResult::midEdgeNodes. Curves on the first call (it checks `ctx`'s cancel: throws
  /// Error(Canceled)) and then frees what it kept (the field, grid and mesh); later calls return
  /// the same nodes. Thread-safe.
  std::shared_ptr<const MidEdgePositions> midEdgeNodes(const TetMesh& mesh, RunContext& ctx) const;
  /// The curving's figures (zero before the first midEdgeNodes).
  QuadraticCurvingResult figures() const;
  /// Bytes held: before the curving the indicator functions' samples, the working grid's labels
  /// and the mesh; after it the curved nodes.
  size_t memoryBytes() const;

 private:
  // Freed (under the lock) once the nodes are made.
  mutable PreprocessedVolume grid_;
  mutable std::unique_ptr<IndicatorField> field_;
  mutable TetMesh canonical_;
  double facetDistance_ = 0;
  LabelVolume frame_;
  mutable std::mutex mutex_;
  mutable std::shared_ptr<const MidEdgePositions> nodes_;
  mutable QuadraticCurvingResult figures_;
};

}  // namespace femesher
