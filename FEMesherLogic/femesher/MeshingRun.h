// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file MeshingRun.h
/// One meshing run, stage by stage: what each stage hands to the next and the glue between them
/// (the uniform edge length, the sizing function, unit conversions, the physical frame). This is
/// the only code that connects stages: `runPipeline` runs every stage through it, and the CLI's
/// `sizing` command and the tests run the first few, so they see exactly what a mesh run sees.
///
/// Usage: `MeshingRun run(input, params, ctx); run.runThrough(StageId::SizingField);` then read
/// `run.state()`. Stages that a run's parameters switch off (MedialAxis and SizingField with
/// uniform sizing, Fidelity with compute_fidelity off) are skipped. Each stage is timed and
/// reported to the RunContext (progress, cancel). Errors are thrown as femesher::Error.

#include <femesher/DeferredCurving.h>
#include <femesher/MemoryEstimate.h>
#include <femesher/MeshCheck.h>
#include <femesher/Parameters.h>
#include <femesher/QuadraticCurving.h>
#include <femesher/RunContext.h>
#include <femesher/StageTable.h>
#include <femesher/Types.h>
#include <femesher/io/ContactSplit.h>
#include <femesher/stages/BoundaryMesh.h>
#include <femesher/stages/Fidelity.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/Junctions.h>
#include <femesher/stages/LabelPreprocess.h>
#include <femesher/stages/LocalDelaunay.h>
#include <femesher/stages/Optimize.h>
#include <femesher/stages/ParticleSystem.h>
#include <femesher/stages/Quality.h>
#include <femesher/stages/SizingField.h>
#include <femesher/stages/SurfaceSampling.h>
#include <femesher/stages/VolumeMesh.h>

#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace femesher {

struct StageTiming {
  std::string name;
  double seconds = 0;
};

/// What the stages of one run produced so far. Frames: see WorkingGrid.h.
struct MeshingState {
  PreprocessedVolume grid;                      ///< LabelPreprocess
  std::unique_ptr<IndicatorField> field;        ///< IndicatorFunctions
  double edgeLength = 0;                        ///< mm, the uniform edge length of the run
  size_t medialVoxels = 0;                      ///< MedialAxis
  /// MedialAxis, on `grid` with compact labels; released once the sizing field is made.
  std::shared_ptr<const LabelMedialAxes> medialAxes;
  std::shared_ptr<const SizingField> sizingField;  ///< SizingField (on `grid`, grid-mm frame)
  SizingFunction sizing;                        ///< target edge length at a canonical point
  /// SurfaceSampling, Junctions, ParticleSystem: what only BoundaryMesh reads. Emptied once
  /// BoundaryMesh has run (their report counts are kept: `surfaceInputCounts`).
  SurfaceSamples samples;
  Junctions junctions;
  ParticleSystemResult particleSystem;          ///< (empty when the particle system is off)
  std::vector<Vec3> particles;                  ///< the particle positions (local voxel index)
  /// The report counts of samples, junctions and particles, taken when BoundaryMesh empties
  /// them (empty before).
  ReportCounts surfaceInputCounts;
  InterfaceSurface surface;                     ///< BoundaryMesh
  VolumeMeshResult volumeMesh;                  ///< VolumeMesh then Optimize (canonical, compact)
  OptimizeResult optimize;                      ///< Optimize
  MeshCheckResult meshCheck;                    ///< the check after Optimize (MeshCheck.h)
  TetMesh mesh;                                 ///< physical LPS, user labels (after Optimize)
  std::set<int32_t> meshedMaterials;            ///< compact labels present in `mesh`
  QualityReport quality;                        ///< Quality
  FidelityReport fidelity;                      ///< Fidelity
  bool hasFidelity = false;
  /// prepareExport: the split contact pairs (parameter contact_pairs) and the mesh nodes on the
  /// faces of the input's box (io/ContactSplit.h).
  std::vector<ContactSurfacePair> contacts;
  std::vector<NamedNodeSet> boxNodeSets;
  /// prepareExport with element_order 2: the mid-edge nodes curved onto the smooth interfaces
  /// (physical LPS, by tetEdgeKey of `mesh`'s vertices, contact copies included) and the
  /// figures of the curving (its `nodes` emptied; QuadraticCurving.h).
  std::shared_ptr<const MidEdgePositions> midEdgeNodes;
  QuadraticCurvingResult quadratic;
  std::vector<StageTiming> timings;             ///< wall seconds per stage run, in run order
  MemoryEstimate memory;  ///< runPipeline's estimate before the run (empty for other callers)
};

/// The stages `params` runs, in order, with their progress weights (for RunContext).
std::vector<std::pair<std::string, double>> pipelineStagePlan(const MeshingParameters& params);
bool stageEnabled(StageId id, const MeshingParameters& params);

class MeshingRun {
 public:
  /// Validates `params` and checks its size-like parameters against `input` (checkSizeParameters,
  /// ParameterRanges.h; both throw Error(InvalidArgument)), applies the thread count to `ctx` and
  /// declares the stage plan. `input` and `ctx` must outlive the run.
  MeshingRun(const LabelVolume& input, const MeshingParameters& params, RunContext& ctx);

  /// Runs every enabled stage after the last one run, up to and including `last`.
  void runThrough(StageId last);
  const MeshingState& state() const { return state_; }
  MeshingState& state() { return state_; }
  const LabelVolume& input() const { return input_; }
  const MeshingParameters& parameters() const { return params_; }

  /// Replaces the run's size (the target edge length, mm, at a canonical point) for the stages
  /// still to run: sampling, junctions and particles follow it as they follow the adaptive field.
  /// For experiments and tests with a prescribed size; call it after IndicatorFunctions.
  void setSizing(SizingFunction sizing);

  /// Takes an existing mesh (physical LPS, user labels, as the readers return it) as the volume
  /// mesh, so that the run continues with Optimize, Quality and Fidelity on it (`femesher
  /// optimize`). Requires the run through SizingField (the interior coarsening follows the sizing
  /// field), and no stage after it. Throws
  /// InvalidArgument when a tet's material is not a material of the label map (or was dropped or
  /// excluded) or a tet is inverted or flat.
  void adoptVolumeMesh(const TetMesh& mesh);

  /// An image header for the working grid placed in the input's physical space (what
  /// `femesher sizing` and `femesher medial-axis` write on). Requires LabelPreprocess to have run.
  LabelVolume workingGridGeometry() const { return state_.grid.geometryIn(input_); }

  /// After the last stage, on the final linear mesh: with element_order 2 curves the mid-edge
  /// nodes on interfaces and the outer boundary onto the run's smooth interfaces
  /// (curveMidEdgeNodes with the indicator functions, in the canonical frame, into
  /// `state().midEdgeNodes`); splits the interfaces of the parameter
  /// `contact_pairs` (`splitContactInterfaces`: duplicates nodes of `state().mesh`) and finds the
  /// nodes on the faces of the input's box (`boxFaceNodeSets`, copies included), into
  /// `state().contacts` and `state().boxNodeSets`. Quality and Fidelity are measured before (the
  /// split moves nothing). Throws InvalidArgument for a pair the mesh has no interface of.
  void prepareExport();

  /// After prepareExport, for a result of element_order 1: moves the working grid and the
  /// indicator functions out of the run, with a copy of the final linear mesh in the canonical
  /// frame, into a DeferredCurving that curves the mid-edge nodes later exactly as
  /// prepareExport would at element_order 2 (DeferredCurving.h). The run keeps no grid or field
  /// afterwards and runs no more stages. Null when the run has no field or no volume mesh.
  std::shared_ptr<const DeferredCurving> keepForCurving();

  /// Every stage result's counts, in report order.
  ReportCounts reportCounts() const;

  /// With `on`, what only curving reads goes as soon as nothing else does (unless element_order
  /// 2 curves with it in prepareExport): the indicator functions once Optimize has run, the
  /// canonical volume mesh once the physical mesh is made (Quality and Fidelity then run beside
  /// a smaller process: colin27 upsampled 2x held about 1.2 GB in the functions);
  /// keepForCurving then returns null. For a caller that keeps no curving data (the CLI). Off by
  /// default.
  void dropCurvingInputs(bool on) { dropCurving_ = on; }

 private:
  void run(StageId id);
  const LabelVolume& workingLabels();
  void preprocess();
  void indicatorFunctions();
  void medialAxis();
  void sizingField();
  void surfaceSampling();
  void junctions();
  void particleSystem();
  void boundaryMesh();
  void volumeMesh();
  void optimize();
  void quality();
  void fidelity();
  /// The report counts of the samples, junctions and particles (kept once they are emptied).
  ReportCounts surfaceInputCounts() const;
  /// Canonical frame, compact labels -> physical LPS, user labels; warns about lost materials.
  void toPhysical();
  /// prepareExport's curving of the mid-edge nodes (element_order 2), before the contact split
  /// (curvePhysicalMidEdgeNodes; midEdgeNodesWithCopies after the split).
  void curveQuadraticNodes();
  /// The final linear mesh in the canonical frame with compact labels (what curving takes).
  TetMesh canonicalMesh() const;

  const LabelVolume& input_;
  const MeshingParameters params_;
  RunContext& ctx_;
  MeshingState state_;
  int next_ = 0;          ///< index in stageTable() of the next stage to run
  bool customSizing_ = false;  ///< setSizing was called
  bool dropCurving_ = false;   ///< dropCurvingInputs
  /// The working grid's labels as a label map, for MedialAxis and SizingField (made once).
  std::unique_ptr<const LabelVolume> workingLabels_;
};

}  // namespace femesher
