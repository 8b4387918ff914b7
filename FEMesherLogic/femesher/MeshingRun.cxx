// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/MeshingRun.h>
#include <femesher/DeferredCurving.h>
#include <femesher/ParameterRanges.h>
#include <femesher/io/ContactSplit.h>
#include <femesher/stages/InterfaceSmoothing.h>

#include <algorithm>
#ifdef __GLIBC__
#include <malloc.h>
#endif
#include <chrono>
#include <cmath>
#include <map>
#include <set>

namespace femesher {

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

/// Times a stage and tells the context where the run is.
class StageScope {
 public:
  StageScope(RunContext& ctx, std::vector<StageTiming>& timings, const std::string& name)
      : ctx_(ctx), timings_(timings), name_(name), start_(Clock::now()) {
    ctx_.beginStage(name);
  }
  ~StageScope() { timings_.push_back({name_, secondsSince(start_)}); }
  void done() { ctx_.endStage(); }

 private:
  RunContext& ctx_;
  std::vector<StageTiming>& timings_;
  std::string name_;
  Clock::time_point start_;
};

}  // namespace

bool stageEnabled(StageId id, const MeshingParameters& params) {
  switch (id) {
    case StageId::MedialAxis:
    case StageId::SizingField: return params.sizing.mode == SizingMode::Adaptive;
    case StageId::Fidelity: return params.run.computeFidelity;
    default: return true;
  }
}

std::vector<std::pair<std::string, double>> pipelineStagePlan(const MeshingParameters& params) {
  std::vector<std::pair<std::string, double>> plan;
  for (const auto& s : stageTable())
    if (stageEnabled(s.id, params)) plan.emplace_back(s.key, s.weight);
  return plan;
}

MeshingRun::MeshingRun(const LabelVolume& input, const MeshingParameters& params, RunContext& ctx)
    : input_(input), params_(params), ctx_(ctx) {
  if (Status s = validate(params_); !s) throw Error(s.code(), s.message());
  // Size-like parameters against this volume (ParameterRanges.h): before any heavy stage.
  if (Status s = checkSizeParameters(params_, input_); !s) throw Error(s.code(), s.message());
  if (!params_.materialProperties.empty() || !params_.preprocess.names.empty()) {
    // Properties or names for a label the map does not have are a mistake: say so before meshing.
    std::set<int32_t> labels;
    int32_t last = 0;
    for (size_t i = 0; i < input_.labels.size(); ++i)
      if (i == 0 || input_.labels[i] != last) labels.insert(last = input_.labels[i]);
    if (!input_.hasNoBackground()) labels.erase(0);
    if (Status s = checkMaterialLabels(params_, {labels.begin(), labels.end()}, input_.sourcePath); !s)
      throw Error(s.code(), s.message());
  }
  // Contact pairs of absent labels, or of labels that do not touch, are a mistake too.
  if (Status s = checkContactPairs(params_.contactPairs, input_); !s) throw Error(s.code(), s.message());
  if (params_.run.threads > 0) ctx_.setThreads(params_.run.threads);
  ctx_.setStagePlan(pipelineStagePlan(params_));
}

void MeshingRun::runThrough(StageId last) {
  const auto& table = stageTable();
  for (; next_ < int(table.size()) && int(table[size_t(next_)].id) <= int(last); ++next_)
    if (stageEnabled(table[size_t(next_)].id, params_)) run(table[size_t(next_)].id);
}

void MeshingRun::run(StageId id) {
  if (id == StageId::Quality && state_.mesh.tets.empty()) toPhysical();
  StageScope scope(ctx_, state_.timings, stageInfo(id).key);
  switch (id) {
    case StageId::LabelPreprocess: preprocess(); break;
    case StageId::IndicatorFunctions: indicatorFunctions(); break;
    case StageId::MedialAxis: medialAxis(); break;
    case StageId::SizingField: sizingField(); break;
    case StageId::SurfaceSampling: surfaceSampling(); break;
    case StageId::Junctions: junctions(); break;
    case StageId::ParticleSystem: particleSystem(); break;
    case StageId::BoundaryMesh: boundaryMesh(); break;
    case StageId::VolumeMesh: volumeMesh(); break;
    case StageId::Optimize: optimize(); break;
    case StageId::Quality: quality(); break;
    case StageId::Fidelity: fidelity(); break;
  }
  scope.done();
#ifdef __GLIBC__
  // What the stage freed goes back to the system, not only the top of the heap: the many small
  // blocks of CGAL's triangulations otherwise stay resident through the stages after them (the
  // TetGen helpers run beside them).
  malloc_trim(0);
#endif
}

void MeshingRun::preprocess() {
  state_.grid = preprocessLabels(input_, params_.preprocess, ctx_);
  state_.edgeLength = uniformEdgeLength(input_, params_.sizing);
  const double h = state_.edgeLength;
  state_.sizing = [h](const Vec3&) { return h; };
}

void MeshingRun::indicatorFunctions() {
  state_.field = std::make_unique<IndicatorField>(
      computeIndicatorFunctions(state_.grid, params_.indicators, ctx_));
}

const LabelVolume& MeshingRun::workingLabels() {
  if (!workingLabels_) {
    auto work = std::make_unique<LabelVolume>();
    work->dims = state_.grid.dims;
    work->spacing = state_.grid.spacing;
    work->labels.assign(state_.grid.labels.begin(), state_.grid.labels.end());
    workingLabels_ = std::move(work);
  }
  return *workingLabels_;
}

void MeshingRun::medialAxis() {
  SizingParameters sp = params_.sizing;
  sp.threads = ctx_.threads();
  state_.medialAxes = std::make_shared<const LabelMedialAxes>(
      computeAllMedialAxes(workingLabels(), medialAxisParameters(sp), ctx_));
  state_.medialVoxels = state_.medialAxes->voxelCount();
}

void MeshingRun::sizingField() {
  SizingParameters sp = params_.sizing;
  sp.threads = ctx_.threads();
  sp.targetEdgeLength = state_.edgeLength;  // the automatic bounds follow the run's edge length
  SizingField computed =
      computeSizingField(workingLabels(), *state_.medialAxes, sp, ctx_, state_.field.get());
  const size_t denseBytes = computed.h.size() * sizeof(float);
  computed.pack(ctx_.threads());  // the rest of the run reads it; constant far from interfaces
  ctx_.debug("SizingField: " + std::to_string(computed.packed.bytes() >> 20) + " MB in bricks, " +
             std::to_string(denseBytes >> 20) + " MB dense");
  auto field = std::make_shared<const SizingField>(std::move(computed));
  workingLabels_.reset();
  state_.medialAxes.reset();
  state_.sizingField = field;
  const WorkingGrid grid = state_.grid;
  state_.sizing = [field, grid](const Vec3& c) { return double(field->at(grid.canonicalToGridMm(c))); };
}

void MeshingRun::adoptVolumeMesh(const TetMesh& mesh) {
  if (next_ != int(StageId::SizingField) + 1 || !state_.field)
    throw Error(ErrorCode::Internal, "adoptVolumeMesh: run exactly through SizingField first");
  const PreprocessedVolume& vol = state_.grid;
  std::map<int32_t, int32_t> compact;
  for (size_t c = 1; c < vol.userLabel.size(); ++c) compact[vol.userLabel[c]] = int32_t(c);
  VolumeMeshResult& vm = state_.volumeMesh;
  vm = VolumeMeshResult{};
  vm.method = "input mesh";
  vm.points.reserve(mesh.points.size());
  for (const Vec3& p : mesh.points) vm.points.push_back(input_.physicalToCanonical(p));
  // The mesh must lie in the label map's space (within a voxel of its box).
  for (const Vec3& c : vm.points)
    for (int a = 0; a < 3; ++a) {
      const double lo = -1.5 * input_.spacing[a], hi = (input_.dims[a] + 0.5) * input_.spacing[a];
      if (!(c[a] >= lo && c[a] <= hi))
        throw Error(ErrorCode::InvalidArgument,
                    "The mesh does not lie in the space of " +
                        (input_.sourcePath.empty() ? std::string("the label map")
                                                   : input_.sourcePath) +
                        " (a vertex is more than a voxel outside its box): give the label map the "
                        "mesh was made from.");
    }
  const bool flip = input_.directionDeterminant() < 0;
  vm.tets = mesh.tets;
  vm.labels.reserve(mesh.tets.size());
  for (size_t t = 0; t < mesh.tets.size(); ++t) {
    auto it = compact.find(mesh.tetLabels[t]);
    if (it == compact.end())
      throw Error(ErrorCode::InvalidArgument,
                  "Tet " + std::to_string(t) + " has material " + std::to_string(mesh.tetLabels[t]) +
                      ", which is not a meshed material of " +
                      (input_.sourcePath.empty() ? std::string("the label map") : input_.sourcePath) +
                      " (absent, below min_voxels or excluded): give the label map the mesh was "
                      "made from.");
    vm.labels.push_back(it->second);
    if (flip) std::swap(vm.tets[t][2], vm.tets[t][3]);
    const auto& T = vm.tets[t];
    if (tetMinDihedral(vm.points[size_t(T[0])], vm.points[size_t(T[1])], vm.points[size_t(T[2])],
                       vm.points[size_t(T[3])]) < 0)
      throw Error(ErrorCode::InvalidArgument,
                  "Tet " + std::to_string(t) + " of the mesh is inverted or flat: the mesh must "
                  "have positively oriented tets of non-zero volume to be improved.");
  }
  next_ = int(StageId::Optimize);  // continue with Optimize (the table is in StageId order)
}

void MeshingRun::setSizing(SizingFunction sizing) {
  state_.sizing = std::move(sizing);
  customSizing_ = true;
}

void MeshingRun::surfaceSampling() {
  SurfaceSamplingParameters sp;
  sp.targetEdgeLength = state_.edgeLength;
  if (state_.sizingField || customSizing_) sp.sizing = state_.sizing;
  sp.seed = params_.run.seed;
  state_.samples = sampleInterfaces(*state_.field, input_, sp, ctx_);
}

void MeshingRun::junctions() {
  state_.junctions = findJunctions(*state_.field, state_.sizing, JunctionParameters{}, ctx_);
}

void MeshingRun::particleSystem() {
  auto& particles = state_.particles;
  if (params_.particles.maxIterations > 0) {
    ParticleSystemParameters pp = params_.particles;
    pp.seed = params_.run.seed;
    state_.particleSystem = runParticleSystem(*state_.field, state_.samples, state_.junctions,
                                              state_.sizing, input_, pp, ctx_);
    particles.reserve(state_.particleSystem.particles.size());
    for (const auto& p : state_.particleSystem.particles) particles.push_back(p.local);
  } else {
    for (const auto& j : state_.junctions.particles) particles.push_back(j.local);
    for (uint32_t i : state_.samples.selected) particles.push_back(state_.samples.all[i].local);
  }
}

void MeshingRun::boundaryMesh() {
  BoundaryMeshParameters bp = params_.boundary;
  bp.sizeAt = state_.sizing;
  state_.surface = buildInterfaceSurface(*state_.field, state_.particles,
                                         state_.particleSystem.particles, state_.samples,
                                         state_.junctions, bp, ctx_);
  // Nothing after this stage reads the samples (every isosurface vertex), the junction
  // particles or the particles: only their counts stay, for the report.
  state_.surfaceInputCounts = surfaceInputCounts();
  state_.samples = SurfaceSamples{};
  state_.junctions.particles = {};
  state_.particleSystem.particles = {};
  state_.particles = {};
}

ReportCounts MeshingRun::surfaceInputCounts() const {
  if (!state_.surfaceInputCounts.empty()) return state_.surfaceInputCounts;
  const MeshingState& s = state_;
  ReportCounts c = femesher::reportCounts(s.samples);
  const ReportCounts j = femesher::reportCounts(s.junctions);
  c.insert(c.end(), j.begin(), j.end());
  c.emplace_back("particles", double(s.particles.size()));
  const ReportCounts p = femesher::reportCounts(s.particleSystem);
  c.insert(c.end(), p.begin(), p.end());
  return c;
}

void MeshingRun::volumeMesh() {
  VolumeMeshParameters vp = params_.volume;
  const BoundarySurface& surface = state_.surface.surface;
  if (state_.sizingField && params_.sizing.volumeSizing) {
    vp.pointSizes.reserve(surface.points.size());
    for (const auto& p : surface.points) vp.pointSizes.push_back(state_.sizing(p));
  }
  // The labelled Delaunay goes to the stage, which releases it before TetGen runs: nothing after
  // this stage reads it.
  state_.volumeMesh =
      buildVolumeMesh(surface, std::move(state_.surface.surface.delaunay), vp, ctx_);
}

void MeshingRun::optimize() {
  OptimizeParameters op = params_.optimize;
  op.voxelSize = state_.grid.minSpacing();
  op.voxelVolume = state_.grid.spacing[0] * state_.grid.spacing[1] * state_.grid.spacing[2];
  if (state_.sizing) op.sizeAt = state_.sizing;
  VolumeMeshResult& vm = state_.volumeMesh;
  // The interfaces the mesh approximates, within the boundary stage's facet distance.
  const OptimizeInterfaces interfaces =
      state_.field ? indicatorInterfaces(*state_.field, params_.boundary.facetDistance)
                   : OptimizeInterfaces{};
  const OptimizeResult& opt = state_.optimize =
      optimizeTetMesh(vm.points, vm.tets, vm.labels, op, interfaces, ctx_);
  ctx_.debug("Optimize: " + std::to_string(opt.tetsBelowTargetBefore) + " -> " +
             std::to_string(opt.tetsBelowTargetAfter) + " tets below target, min dihedral " +
             std::to_string(opt.minDihedralBefore) + " -> " + std::to_string(opt.minDihedralAfter));
  MeshCheckParameters cp;
  cp.minDihedralWarning = op.minDihedralWarning;
  const LabelVolume& in = input_;
  const MeshCheckFrame frame{[&in](const Vec3& c) { return in.canonicalToPhysical(c); },
                             in.sourcePath};
  state_.meshCheck = checkTetMesh(vm.points, vm.tets, vm.labels, cp, frame);
  if (state_.meshCheck.poor()) ctx_.warn(poorElementsWarning(state_.meshCheck));
  if (dropCurving_ && params_.elementOrder != 2) state_.field.reset();
}

void MeshingRun::toPhysical() {
  VolumeMeshResult& vm = state_.volumeMesh;
  const PreprocessedVolume& vol = state_.grid;
  TetMesh& mesh = state_.mesh;
  mesh.points.resize(vm.points.size());
  for (size_t i = 0; i < vm.points.size(); ++i)
    mesh.points[i] = input_.canonicalToPhysical(vm.points[i]);
  // Nothing reads the canonical mesh after this but curving (canonicalMesh, keepForCurving).
  const bool drop = dropCurving_ && params_.elementOrder != 2;
  if (drop) {
    mesh.tets.swap(vm.tets);
    std::vector<Vec3>().swap(vm.points);
  } else {
    mesh.tets = vm.tets;
  }
  // A left-handed direction flips orientation: swap two vertices per tet.
  if (input_.directionDeterminant() < 0)
    for (auto& t : mesh.tets) std::swap(t[2], t[3]);
  mesh.tetLabels.resize(vm.labels.size());
  std::set<int32_t>& present = state_.meshedMaterials;
  for (size_t t = 0; t < vm.labels.size(); ++t) {
    mesh.tetLabels[t] = vol.userLabel[size_t(vm.labels[t])];
    present.insert(vm.labels[t]);
  }
  if (drop) std::vector<int32_t>().swap(vm.labels);
  for (int32_t m : present) mesh.materials.push_back(vol.materials[size_t(m)]);
  for (int m = 1; m <= vol.materialCount(); ++m)
    if (!present.count(m))
      ctx_.warn("Label " + std::to_string(vol.userLabel[m]) + " (" + vol.materials[m].name +
                ") is missing from the mesh.");
}

void MeshingRun::quality() { state_.quality = computeQuality(state_.mesh, ctx_); }

void MeshingRun::fidelity() {
  state_.fidelity = computeFidelity(input_, state_.mesh, ctx_);
  state_.hasFidelity = true;
}

void MeshingRun::prepareExport() {
  if (params_.elementOrder == 2) curveQuadraticNodes();
  const size_t vertices = state_.mesh.points.size();
  state_.contacts = splitContactInterfaces(state_.mesh, params_.contactPairs);
  if (state_.midEdgeNodes && state_.mesh.points.size() > vertices)
    state_.midEdgeNodes = midEdgeNodesWithCopies(*state_.midEdgeNodes, state_.mesh, vertices);
  state_.boxNodeSets = boxFaceNodeSets(state_.mesh, input_);
}

void MeshingRun::curveQuadraticNodes() {
  if (!state_.field) return;
  // In the canonical frame with compact labels: the frame and materials of the indicators.
  state_.midEdgeNodes = curvePhysicalMidEdgeNodes(canonicalMesh(), *state_.field,
                                                  params_.boundary.facetDistance, input_,
                                                  state_.quadratic, ctx_);
}

TetMesh MeshingRun::canonicalMesh() const {
  const VolumeMeshResult& vm = state_.volumeMesh;
  TetMesh canonical;
  canonical.points = vm.points;
  canonical.tets = vm.tets;
  canonical.tetLabels = vm.labels;
  return canonical;
}

std::shared_ptr<const DeferredCurving> MeshingRun::keepForCurving() {
  if (!state_.field || state_.volumeMesh.tets.empty()) return nullptr;
  VolumeMeshResult& vm = state_.volumeMesh;  // moved, not copied: the run ends here
  TetMesh canonical;
  canonical.points = std::move(vm.points);
  canonical.tets = std::move(vm.tets);
  canonical.tetLabels = std::move(vm.labels);
  auto kept = std::make_shared<const DeferredCurving>(std::move(state_.grid),
                                                      std::move(state_.field), std::move(canonical),
                                                      params_.boundary.facetDistance, input_);
  state_.grid = PreprocessedVolume{};
  vm = VolumeMeshResult{};
  next_ = int(stageTable().size());  // nothing more can run without the grid and the field
  return kept;
}

ReportCounts MeshingRun::reportCounts() const {
  const MeshingState& s = state_;
  double sizeMin = s.edgeLength, sizeMax = s.edgeLength;
  if (s.sizingField && !s.sizingField->empty()) {
    sizeMin = s.sizingField->lowest;
    sizeMax = s.sizingField->highest;
  }
  ReportCounts c = {{"target_edge_length_mm", s.edgeLength},
                    {"sizing_min_mm", sizeMin},
                    {"sizing_max_mm", sizeMax},
                    {"medial_axis_voxels", double(s.medialVoxels)},
                    {"working_grid_voxels", double(s.grid.labels.size())},
                    {"materials", double(s.grid.materialCount())}};
  auto append = [&c](const ReportCounts& more) { c.insert(c.end(), more.begin(), more.end()); };
  append(surfaceInputCounts());
  append(femesher::reportCounts(s.surface));
  append(femesher::reportCounts(s.volumeMesh));
  append(femesher::reportCounts(s.optimize));
  c.insert(c.end(), {{"vertices", double(s.mesh.points.size())},
                     {"tets", double(s.mesh.tets.size())}});
  if (params_.elementOrder == 2 && s.field) append(femesher::reportCounts(s.quadratic));
  return c;
}

}  // namespace femesher
