// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/MeshingRun.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>

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

/// Order-sensitive checksum of the interface surface handed to TetGen (determinism checks).
double surfaceChecksum(const BoundarySurface& s) {
  uint64_t h = 1469598103934665603ull;
  auto mix = [&](uint64_t x) {
    h ^= x;
    h *= 1099511628211ull;
  };
  for (const auto& p : s.points)
    for (double x : p) mix(uint64_t(std::llround(x * 1e6)));
  for (const auto& t : s.triangles)
    for (int32_t v : t) mix(uint64_t(uint32_t(v)));
  return double(h % 1000000007ull);
}

/// Share of junction particles that are vertices of an edge shared by the triangles of three or
/// more materials (i.e. the triple lines appear as mesh edges there).
double junctionsOnTripleEdges(const BoundarySurface& s, const PreprocessedVolume& vol,
                              const std::vector<Vec3>& particlesLocal, size_t junctionCount,
                              RunContext& ctx) {
  if (junctionCount == 0) return 1.0;
  std::map<Vec3, int32_t> vid;
  for (size_t i = 0; i < s.points.size(); ++i) vid.emplace(s.points[i], int32_t(i));
  std::map<std::pair<int32_t, int32_t>, std::set<int>> edgeMaterials;
  for (size_t t = 0; t < s.triangles.size(); ++t)
    for (int e = 0; e < 3; ++e) {
      int32_t a = s.triangles[t][e], b = s.triangles[t][(e + 1) % 3];
      if (a > b) std::swap(a, b);
      auto& m = edgeMaterials[{a, b}];
      m.insert(s.trianglePairs[t].first);
      m.insert(s.trianglePairs[t].second);
    }
  std::vector<size_t> best(s.points.size(), 0);
  for (const auto& [e, m] : edgeMaterials) {
    best[size_t(e.first)] = std::max(best[size_t(e.first)], m.size());
    best[size_t(e.second)] = std::max(best[size_t(e.second)], m.size());
  }
  size_t ok = 0, notVertex = 0;
  for (size_t j = 0; j < junctionCount && j < particlesLocal.size(); ++j) {
    auto it = vid.find(vol.localToCanonical(particlesLocal[j]));
    if (it == vid.end()) ++notVertex;
    else if (best[size_t(it->second)] >= 3) ++ok;
  }
  ctx.debug("Junction particles: " + std::to_string(junctionCount) + ", on triple edges " +
            std::to_string(ok) + ", not a surface vertex " + std::to_string(notVertex));
  return double(ok) / double(junctionCount);
}

/// The working grid's labels as a label map (the medial axis and the sizing field read one).
LabelVolume workingLabelMap(const PreprocessedVolume& vol) {
  LabelVolume work;
  work.dims = vol.dims;
  work.spacing = vol.spacing;
  work.labels.assign(vol.labels.begin(), vol.labels.end());
  return work;
}

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

void MeshingRun::medialAxis() {
  SizingParameters sp = params_.sizing;
  sp.threads = ctx_.threads();
  axes_ = computeAllMedialAxes(workingLabelMap(state_.grid), medialAxisParameters(sp), ctx_);
  state_.medialVoxels = axes_.voxelCount();
}

void MeshingRun::sizingField() {
  SizingParameters sp = params_.sizing;
  sp.threads = ctx_.threads();
  sp.targetEdgeLength = state_.edgeLength;  // the automatic bounds follow the run's edge length
  auto field = std::make_shared<const SizingField>(
      computeSizingField(workingLabelMap(state_.grid), axes_, sp, ctx_));
  axes_ = LabelMedialAxes{};
  state_.sizingField = field;
  const WorkingGrid grid = state_.grid;
  state_.sizing = [field, grid](const Vec3& c) { return double(field->at(grid.canonicalToGridMm(c))); };
}

void MeshingRun::surfaceSampling() {
  SurfaceSamplingParameters sp;
  sp.targetEdgeLength = state_.edgeLength;
  if (state_.sizingField) sp.sizing = state_.sizing;
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
  const PreprocessedVolume& vol = state_.grid;
  const IndicatorField& field = *state_.field;
  std::vector<Vec3>& particles = state_.particles;
  InterfaceSurface& out = state_.surface;
  BoundarySurface& surface = out.surface;
  const bool useLdt = params_.boundary.mesher == SurfaceMesher::LocalDelaunay;
  const auto boundaryStart = Clock::now();
  const double smin = vol.minSpacing();
  // Points on the input's box exactly on it (as buildBoundaryMesh does), so that the particles
  // below are the surface's vertices to the bit.
  for (Vec3& l : particles) l = field.snapToBox(l);
  surface = buildBoundaryMesh(field, particles, state_.samples, ctx_,
                              params_.boundary.facetDistance * smin, &state_.junctions,
                              params_.boundary.voxelRefinement);
  out.restrictedSeconds = secondsSince(boundaryStart);
  out.junctionShare =
      junctionsOnTripleEdges(surface, vol, particles, state_.junctions.particles.size(), ctx_);
  if (useLdt) {
    const auto ldtStart = Clock::now();
    std::vector<Particle> plist = state_.particleSystem.particles;
    if (plist.empty()) {
      plist = junctionParticles(state_.junctions);
      for (uint32_t i : state_.samples.selected) {
        Particle p;
        p.local = state_.samples.all[i].local;
        p.a = state_.samples.all[i].a;
        p.b = state_.samples.all[i].b;
        plist.push_back(p);
      }
    }
    const bool refined =
        surface.refinementPoints + surface.voxelCentrePoints + surface.junctionPoints > 0;
    BoundarySurface particlesOnly;
    if (refined) particlesOnly = buildBoundaryMesh(field, particles, state_.samples, ctx_);
    out.ldt = buildLocalDelaunaySurface(field, plist, state_.junctions,
                                        refined ? particlesOnly : surface, ctx_);
    out.ldtSeconds = secondsSince(ldtStart);
    const LocalDelaunayResult& ldt = out.ldt;
    if (ldt.openEdgesAfter > 0 || ldt.selfIntersectionsAfter > 0) {
      ctx_.warn("The local Delaunay surface still has " + std::to_string(ldt.openEdgesAfter) +
                " open edges and " + std::to_string(ldt.selfIntersectionsAfter) +
                " self-intersections after hole filling; the restricted Delaunay surface "
                "(watertight) is used instead.");
    } else {
      if (ldt.fromRestricted > 0)
        ctx_.info("The local Delaunay surface was closed with " +
                  std::to_string(ldt.fromRestricted) + " restricted-Delaunay triangles (" +
                  std::to_string(ldt.restrictedComponents) + " regions; " +
                  std::to_string(ldt.replacedTriangles) + " local triangles replaced).");
      std::vector<int32_t> id(plist.size(), -1);
      surface.points.clear();
      surface.triangles.clear();
      surface.trianglePairs = ldt.trianglePairs;
      for (const auto& t : ldt.triangles) {
        std::array<int32_t, 3> tri;
        for (int k = 0; k < 3; ++k) {
          int32_t& v = id[size_t(t[k])];
          if (v < 0) {
            v = int32_t(surface.points.size());
            surface.points.push_back(vol.localToCanonical(plist[size_t(t[k])].local));
          }
          tri[k] = v;
        }
        surface.triangles.push_back(tri);
      }
      out.ldtUsed = true;
    }
  }
  for (int m : surface.repairedLabels)
    ctx_.warn("Label " + std::to_string(vol.userLabel[m]) +
              " was too small for the element size; extra points were inserted to keep it.");
  for (int m : surface.forcedLabels)
    ctx_.warn("Label " + std::to_string(vol.userLabel[m]) +
              " is far below the element size; the tets holding its voxels carry it (its shape "
              "is not resolved: lower target_edge_length to resolve it).");
}

void MeshingRun::volumeMesh() {
  VolumeMeshParameters vp = params_.volume;
  const BoundarySurface& surface = state_.surface.surface;
  if (state_.sizingField && params_.sizing.volumeSizing) {
    vp.pointSizes.reserve(surface.points.size());
    for (const auto& p : surface.points) vp.pointSizes.push_back(state_.sizing(p));
  }
  state_.volumeMesh = buildVolumeMesh(surface, vp, ctx_);
}

void MeshingRun::optimize() {
  OptimizeParameters op = params_.optimize;
  op.voxelSize = state_.grid.minSpacing();
  VolumeMeshResult& vm = state_.volumeMesh;
  const OptimizeResult& opt = state_.optimize = optimizeTetMesh(vm.points, vm.tets, vm.labels, op, ctx_);
  ctx_.debug("Optimize: " + std::to_string(opt.tetsBelowTargetBefore) + " -> " +
             std::to_string(opt.tetsBelowTargetAfter) + " tets below target, min dihedral " +
             std::to_string(opt.minDihedralBefore) + " -> " + std::to_string(opt.minDihedralAfter));
}

void MeshingRun::toPhysical() {
  const VolumeMeshResult& vm = state_.volumeMesh;
  const PreprocessedVolume& vol = state_.grid;
  TetMesh& mesh = state_.mesh;
  mesh.points.resize(vm.points.size());
  for (size_t i = 0; i < vm.points.size(); ++i)
    mesh.points[i] = input_.canonicalToPhysical(vm.points[i]);
  mesh.tets = vm.tets;
  // A left-handed direction flips orientation: swap two vertices per tet.
  if (input_.directionDeterminant() < 0)
    for (auto& t : mesh.tets) std::swap(t[2], t[3]);
  mesh.tetLabels.resize(vm.labels.size());
  std::set<int32_t>& present = state_.meshedMaterials;
  for (size_t t = 0; t < vm.labels.size(); ++t) {
    mesh.tetLabels[t] = vol.userLabel[size_t(vm.labels[t])];
    present.insert(vm.labels[t]);
  }
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

ReportCounts MeshingRun::reportCounts() const {
  const MeshingState& s = state_;
  double sizeMin = s.edgeLength, sizeMax = s.edgeLength;
  if (s.sizingField && !s.sizingField->h.empty()) {
    const auto [mn, mx] = std::minmax_element(s.sizingField->h.begin(), s.sizingField->h.end());
    sizeMin = *mn;
    sizeMax = *mx;
  }
  ReportCounts c = {{"target_edge_length_mm", s.edgeLength},
                    {"sizing_min_mm", sizeMin},
                    {"sizing_max_mm", sizeMax},
                    {"medial_axis_voxels", double(s.medialVoxels)},
                    {"working_grid_voxels", double(s.grid.labels.size())},
                    {"materials", double(s.grid.materialCount())}};
  auto append = [&c](const ReportCounts& more) { c.insert(c.end(), more.begin(), more.end()); };
  append(femesher::reportCounts(s.samples));
  append(femesher::reportCounts(s.junctions));
  c.emplace_back("particles", double(s.particles.size()));
  append(femesher::reportCounts(s.particleSystem));
  const BoundarySurface& surface = s.surface.surface;
  const LocalDelaunayResult& ldt = s.surface.ldt;
  c.insert(c.end(), {{"delaunay_vertices", double(surface.delaunayVertices)},
                     {"delaunay_tets", double(surface.delaunayTets)},
                     {"surface_vertices", double(surface.points.size())},
                     {"surface_triangles", double(surface.triangles.size())}});
  append(femesher::reportCounts(s.volumeMesh));
  c.insert(c.end(), {{"surface_checksum", surfaceChecksum(surface)},
                     {"junction_particles_on_triple_edges", s.surface.junctionShare},
                     {"surface_open_edges", double(countOpenEdges(surface.triangles,
                                                                  surface.trianglePairs))},
                     {"surface_refinement_points", double(surface.refinementPoints)},
                     {"voxel_centre_refinement_points", double(surface.voxelCentrePoints)},
                     {"junction_refinement_points", double(surface.junctionPoints)},
                     {"ldt_open_edges", double(ldt.openEdgesAfter)},
                     {"ldt_open_edges_before_filling", double(ldt.openEdgesBefore)},
                     {"ldt_open_edges_after_loop_fill", double(ldt.openEdgesAfterFill)},
                     {"ldt_hole_loops", double(ldt.holeLoops)},
                     {"ldt_holes_filled", double(ldt.holesFilled)},
                     {"ldt_non_manifold_removed", double(ldt.nonManifoldRemoved)},
                     {"ldt_triangles", double(ldt.triangles.size())},
                     {"ldt_triangles_from_stars", double(ldt.fromStars)},
                     {"ldt_triangles_from_single_vote", double(ldt.fromSingleVote)},
                     {"ldt_triangles_from_loop_fill", double(ldt.fromLoopFill)},
                     {"ldt_triangles_from_restricted", double(ldt.fromRestricted)},
                     {"ldt_restricted_components", double(ldt.restrictedComponents)},
                     {"ldt_triangles_replaced", double(ldt.replacedTriangles)},
                     {"ldt_self_intersections_found", double(ldt.selfIntersections)},
                     {"ldt_self_intersections", double(ldt.selfIntersectionsAfter)},
                     {"ldt_triple_line_links", double(ldt.lineLinks)},
                     {"ldt_triple_line_open_ends", double(ldt.lineEnds)},
                     {"ldt_used", s.surface.ldtUsed ? 1.0 : 0.0}});
  append(femesher::reportCounts(s.optimize));
  c.insert(c.end(), {{"vertices", double(s.mesh.points.size())},
                     {"tets", double(s.mesh.tets.size())}});
  return c;
}

}  // namespace femesher
