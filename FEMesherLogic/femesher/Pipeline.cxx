// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Pipeline.h>
#include <femesher/Version.h>
#include <femesher/stages/BoundaryMesh.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/Junctions.h>
#include <femesher/stages/LabelPreprocess.h>
#include <femesher/stages/LocalDelaunay.h>
#include <femesher/stages/MedialAxis.h>
#include <femesher/stages/Optimize.h>
#include <femesher/stages/SizingField.h>
#include <femesher/stages/ParticleSystem.h>
#include <femesher/stages/SurfaceSampling.h>
#include <femesher/stages/VolumeMesh.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <set>

namespace femesher {

namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

/// Times a stage, tells the context where we are.
class StageScope {
 public:
  StageScope(RunContext& ctx, std::vector<StageTiming>& timings, const std::string& name)
      : ctx_(ctx), timings_(timings), name_(name), start_(Clock::now()) {
    ctx_.beginStage(name);
  }
  ~StageScope() {
    timings_.push_back({name_, std::chrono::duration<double>(Clock::now() - start_).count()});
  }
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

/// The automatic edge length: edge_length_factor x mean spacing, but never more than a quarter of
/// the smallest side of the labelled box (tiny volumes still get a few elements across).
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

double resolvedEdgeLength(const LabelVolume& in, const MeshingParameters& p) {
  if (p.targetEdgeLength > 0) return p.targetEdgeLength;
  const double mean = (in.spacing[0] + in.spacing[1] + in.spacing[2]) / 3.0;
  double h = p.edgeLengthFactor * mean;
  std::array<int, 3> lo{{in.dims[0], in.dims[1], in.dims[2]}}, hi{{-1, -1, -1}};
  const bool all = in.hasNoBackground();
  for (int k = 0; k < in.dims[2]; ++k)
    for (int j = 0; j < in.dims[1]; ++j)
      for (int i = 0; i < in.dims[0]; ++i)
        if (all || in.at(i, j, k) != 0) {
          lo = {std::min(lo[0], i), std::min(lo[1], j), std::min(lo[2], k)};
          hi = {std::max(hi[0], i), std::max(hi[1], j), std::max(hi[2], k)};
        }
  for (int a = 0; a < 3; ++a)
    if (hi[a] >= lo[a]) h = std::min(h, 0.25 * (hi[a] - lo[a] + 1) * in.spacing[a]);
  return h;
}

json geometryJson(const LabelVolume& in) {
  json g;
  g["path"] = in.sourcePath;
  g["dims"] = in.dims;
  g["spacing"] = in.spacing;
  g["origin"] = in.origin;
  g["direction"] = in.direction;
  g["space"] = "LPS";
  return g;
}

}  // namespace

std::vector<std::pair<std::string, double>> pipelineStagePlan(const MeshingParameters& params) {
  std::vector<std::pair<std::string, double>> plan = {
      {"LabelPreprocess", 2}, {"IndicatorFunctions", 10}, {"MedialAxis", 6},
      {"SizingField", 4},     {"SurfaceSampling", 8},     {"Junctions", 5},
      {"ParticleSystem", 18}, {"BoundaryMesh", 10},       {"VolumeMesh", 28},
      {"Optimize", 3},        {"Quality", 3}};
  if (params.sizing != "adaptive")
    plan.erase(std::remove_if(plan.begin(), plan.end(),
                              [](const auto& p) {
                                return p.first == "MedialAxis" || p.first == "SizingField";
                              }),
               plan.end());
  if (params.computeFidelity) plan.emplace_back("Fidelity", 10);
  return plan;
}

Result<PipelineResult> runPipeline(const LabelVolume& input, const MeshingParameters& params,
                                   RunContext& ctx) {
  const auto start = Clock::now();
  PipelineResult result;
  if (Status s = validate(params); !s) return s;
  if (params.threads > 0) ctx.setThreads(params.threads);
  ctx.setStagePlan(pipelineStagePlan(params));
  const double h = resolvedEdgeLength(input, params);
  try {
    // 1. Preprocess.
    PreprocessedVolume vol;
    {
      StageScope st(ctx, result.timings, "LabelPreprocess");
      LabelPreprocessParameters pp;
      pp.minVoxels = params.minVoxels;
      vol = preprocessLabels(input, pp, ctx);
      st.done();
    }
    result.droppedLabels = vol.droppedLabels;
    // 2. Indicator functions.
    std::unique_ptr<IndicatorField> field;
    {
      StageScope st(ctx, result.timings, "IndicatorFunctions");
      IndicatorParameters ip;
      ip.sigma = params.smoothingSigma;
      field = std::make_unique<IndicatorField>(computeIndicatorFunctions(vol, ip, ctx));
      st.done();
    }
    // 3. Medial axis and sizing field (adaptive sizing), on the cropped, compacted grid.
    SizingFunction sizing = [h](const Vec3&) { return h; };
    std::shared_ptr<SizingField> sizingField;
    size_t medialVoxels = 0;
    if (params.sizing == "adaptive") {
      LabelVolume work;
      work.dims = vol.dims;
      work.spacing = vol.spacing;
      work.labels.assign(vol.labels.begin(), vol.labels.end());
      LabelMedialAxes axes;
      {
        StageScope st(ctx, result.timings, "MedialAxis");
        MedialAxisParameters mp;
        mp.threads = ctx.threads();
        axes = computeAllMedialAxes(work, mp, &ctx);
        medialVoxels = axes.voxelCount();
        st.done();
      }
      {
        StageScope st(ctx, result.timings, "SizingField");
        SizingParameters sp;
        sp.scale = params.sizingScale;
        // Automatic bounds follow the uniform edge length (so presets and edge_length_factor keep
        // their meaning): from half of it in thin and curved parts to 2.5 x in simple ones.
        sp.hMin = params.sizingHMin > 0 ? params.sizingHMin : 0.5 * h;
        sp.hMax = params.sizingHMax > 0 ? params.sizingHMax : 2.5 * h;
        if (sp.hMin > 0 && sp.hMin > sp.hMax) sp.hMin = sp.hMax;
        sp.gradation = params.gradation;
        sp.threads = ctx.threads();
        auto sf = computeSizingField(work, axes, sp, ctx);
        if (!sf) throw Error(sf.status().code(), sf.status().message());
        sizingField = std::make_shared<SizingField>(std::move(sf.value()));
        // The field lives in the working grid's frame (spacing x local index).
        const Vec3 shift{vol.offset[0] * vol.spacing[0], vol.offset[1] * vol.spacing[1],
                         vol.offset[2] * vol.spacing[2]};
        sizing = [sizingField, shift](const Vec3& c) {
          return double(sizingField->at({c[0] - shift[0], c[1] - shift[1], c[2] - shift[2]}));
        };
        st.done();
      }
    }
    // 4. Isosurface + sampling.
    SurfaceSamples samples;
    {
      StageScope st(ctx, result.timings, "SurfaceSampling");
      SurfaceSamplingParameters sp;
      sp.targetEdgeLength = h;
      if (sizingField) sp.sizing = sizing;
      sp.seed = params.seed;
      samples = sampleInterfaces(*field, input, sp, ctx);
      st.done();
    }
    // 5. Junctions (crossing seeds).
    Junctions junctions;
    {
      StageScope st(ctx, result.timings, "Junctions");
      junctions = findJunctions(*field, sizing, JunctionParameters{}, ctx);
      st.done();
    }
    // 5. Particle system.
    std::vector<Vec3> particles;
    ParticleSystemResult ps;
    {
      StageScope st(ctx, result.timings, "ParticleSystem");
      if (params.particleIterations > 0) {
        ParticleSystemParameters pp;
        pp.maxIterations = params.particleIterations;
        pp.seed = params.seed;
        ps = runParticleSystem(*field, samples, junctions, sizing, input, pp, ctx);
        particles.reserve(ps.particles.size());
        for (const auto& p : ps.particles) particles.push_back(p.local);
      } else {
        for (const auto& j : junctions.particles) particles.push_back(j.local);
        for (uint32_t i : samples.selected) particles.push_back(samples.all[i].local);
      }
      st.done();
    }
    // 6. Boundary mesh.
    BoundarySurface surface;
    LocalDelaunayResult ldt;
    double junctionShare = 0;
    bool ldtUsed = false;
    const bool useLdt = params.surfaceMesher == "ldt";
    double restrictedSeconds = 0, ldtSeconds = 0;
    {
      StageScope st(ctx, result.timings, "BoundaryMesh");
      const auto boundaryStart = Clock::now();
      const double smin = std::min({vol.spacing[0], vol.spacing[1], vol.spacing[2]});
      // Points on the input's box exactly on it (as buildBoundaryMesh does), so that the
      // particles below are the surface's vertices to the bit.
      for (Vec3& l : particles) l = field->snapToBox(l);
      surface = buildBoundaryMesh(*field, particles, samples, ctx, params.facetDistance * smin,
                                  &junctions, params.voxelRefinement);
      restrictedSeconds = std::chrono::duration<double>(Clock::now() - boundaryStart).count();
      junctionShare = junctionsOnTripleEdges(surface, vol, particles, junctions.particles.size(), ctx);
      if (useLdt) {
        const auto ldtStart = Clock::now();
        // The particles as the system left them (junction particles carry their label sets).
        std::vector<Particle> plist = ps.particles;
        if (plist.empty()) {
          plist = junctionParticles(junctions);
          for (uint32_t i : samples.selected) {
            Particle p;
            p.local = samples.all[i].local;
            p.a = samples.all[i].a;
            p.b = samples.all[i].b;
            plist.push_back(p);
          }
        }
        // The local Delaunay surface is made of the particles alone: its natural neighbours and
        // its last-resort closure come from the restricted Delaunay surface of the particles,
        // without the points the refinement above inserted.
        const bool refined =
            surface.refinementPoints + surface.voxelCentrePoints + surface.junctionPoints > 0;
        BoundarySurface particlesOnly;
        if (refined) particlesOnly = buildBoundaryMesh(*field, particles, samples, ctx);
        ldt = buildLocalDelaunaySurface(*field, plist, junctions, refined ? particlesOnly : surface,
                                        ctx);
        ldtSeconds = std::chrono::duration<double>(Clock::now() - ldtStart).count();
        if (ldt.openEdgesAfter > 0 || ldt.selfIntersectionsAfter > 0) {
          // An open surface would let TetGen's regions leak into each other (wrong materials), a
          // self-intersecting one is no valid PLC: keep the restricted-Delaunay surface instead.
          ctx.warn("The local Delaunay surface still has " + std::to_string(ldt.openEdgesAfter) +
                   " open edges and " + std::to_string(ldt.selfIntersectionsAfter) +
                   " self-intersections after hole filling; the restricted Delaunay surface "
                   "(watertight) is used instead.");
        } else {
          if (ldt.fromRestricted > 0)
            ctx.info("The local Delaunay surface was closed with " +
                     std::to_string(ldt.fromRestricted) + " restricted-Delaunay triangles (" +
                     std::to_string(ldt.restrictedComponents) + " regions; " +
                     std::to_string(ldt.replacedTriangles) + " local triangles replaced).");
          // Replace the restricted-Delaunay triangles by the LDT ones (used vertices only).
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
          ldtUsed = true;
        }
      }
      for (int m : surface.repairedLabels)
        ctx.warn("Label " + std::to_string(vol.userLabel[m]) +
                 " was too small for the element size; extra points were inserted to keep it.");
      for (int m : surface.forcedLabels)
        ctx.warn("Label " + std::to_string(vol.userLabel[m]) +
                 " is far below the element size; the tets holding its voxels carry it (its shape "
                 "is not resolved: lower target_edge_length to resolve it).");
      st.done();
    }
    // 5. Volume mesh.
    VolumeMeshResult vm;
    {
      StageScope st(ctx, result.timings, "VolumeMesh");
      VolumeMeshParameters vp;
      vp.maxRadiusEdgeRatio = params.maxRadiusEdgeRatio;
      vp.minDihedralAngle = params.minDihedralAngle;
      vp.maxTetVolume = params.maxTetVolume;
      vp.preserveInterfaces = params.preserveInterfaces;
      vp.optimizationLevel = params.optimizationLevel;
      vp.perMaterial = params.volumePerMaterial;
      if (sizingField && params.volumeSizing) {
        vp.pointSizes.reserve(surface.points.size());
        for (const auto& p : surface.points) vp.pointSizes.push_back(sizing(p));
      }
      vm = buildVolumeMesh(surface, vp, ctx);
      st.done();
    }
    // Sliver removal (interfaces between materials kept).
    OptimizeResult opt;
    {
      StageScope st(ctx, result.timings, "Optimize");
      OptimizeParameters op;
      op.targetMinDihedral = params.optimizeMinDihedral;
      op.peelDistance = params.sliverPeelDistance *
                        std::min({vol.spacing[0], vol.spacing[1], vol.spacing[2]});
      opt = optimizeTetMesh(vm.points, vm.tets, vm.labels, op, ctx);
      ctx.debug("Optimize: " + std::to_string(opt.tetsBelowTargetBefore) + " -> " +
                std::to_string(opt.tetsBelowTargetAfter) + " tets below target, min dihedral " +
                std::to_string(opt.minDihedralBefore) + " -> " + std::to_string(opt.minDihedralAfter));
      st.done();
    }
    // To LPS and user labels. A left-handed direction flips orientation: swap two vertices.
    TetMesh& mesh = result.mesh;
    mesh.points.resize(vm.points.size());
    for (size_t i = 0; i < vm.points.size(); ++i)
      mesh.points[i] = input.canonicalToPhysical(vm.points[i]);
    const bool flip = input.directionDeterminant() < 0;
    mesh.tets = vm.tets;
    if (flip)
      for (auto& t : mesh.tets) std::swap(t[2], t[3]);
    mesh.tetLabels.resize(vm.labels.size());
    std::set<int32_t> present;
    for (size_t t = 0; t < vm.labels.size(); ++t) {
      mesh.tetLabels[t] = vol.userLabel[size_t(vm.labels[t])];
      present.insert(vm.labels[t]);
    }
    for (int32_t m : present) mesh.materials.push_back(vol.materials[size_t(m)]);
    for (int m = 1; m <= vol.materialCount(); ++m)
      if (!present.count(m))
        ctx.warn("Label " + std::to_string(vol.userLabel[m]) + " (" + vol.materials[m].name +
                 ") is missing from the mesh.");
    {
      StageScope st(ctx, result.timings, "Quality");
      result.quality = computeQuality(mesh, &ctx);
      st.done();
    }
    if (params.computeFidelity) {
      StageScope st(ctx, result.timings, "Fidelity");
      result.fidelity = computeFidelity(input, mesh, &ctx);
      result.hasFidelity = true;
      st.done();
    }
    double sizeMin = h, sizeMax = h;
    if (sizingField && !sizingField->h.empty()) {
      const auto [mn, mx] = std::minmax_element(sizingField->h.begin(), sizingField->h.end());
      sizeMin = *mn;
      sizeMax = *mx;
    }
    result.counts = {{"target_edge_length_mm", h},
                     {"sizing_min_mm", sizeMin},
                     {"sizing_max_mm", sizeMax},
                     {"medial_axis_voxels", double(medialVoxels)},
                     {"working_grid_voxels", double(vol.labels.size())},
                     {"materials", double(vol.materialCount())},
                     {"isosurface_triangles", double(samples.isosurfaceTriangles)},
                     {"interface_candidates", double(samples.all.size())},
                     {"surface_samples", double(samples.selected.size())},
                     {"junction_cells", double(junctions.tripleCells)},
                     {"quadruple_cells", double(junctions.quadrupleCells)},
                     {"junction_particles", double(junctions.particles.size())},
                     {"quadruple_points", double(junctions.quadruplePoints)},
                     {"particles", double(particles.size())},
                     {"particle_iterations", double(ps.iterations)},
                     {"particle_converged", ps.converged ? 1.0 : 0.0},
                     {"particle_energy", ps.finalEnergy},
                     {"particle_spacing_ratio", ps.meanSpacingRatio},
                     {"delaunay_vertices", double(surface.delaunayVertices)},
                     {"delaunay_tets", double(surface.delaunayTets)},
                     {"surface_vertices", double(surface.points.size())},
                     {"surface_triangles", double(surface.triangles.size())},
                     {"tetgen_regions", double(vm.regions)},
                     {"tetgen_runs", double(vm.tetgenRuns)},
                     {"tetgen_hole_points", double(vm.holePoints)},
                     {"surface_checksum", surfaceChecksum(surface)},
                     {"junction_particles_on_triple_edges", junctionShare},
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
                     {"ldt_used", ldtUsed ? 1.0 : 0.0},
                     {"optimize_tets_below_target_before", double(opt.tetsBelowTargetBefore)},
                     {"optimize_tets_below_target_after", double(opt.tetsBelowTargetAfter)},
                     {"optimize_tets_below_5deg_before", double(opt.tetsBelow5Before)},
                     {"optimize_tets_below_5deg_after", double(opt.tetsBelow5After)},
                     {"optimize_min_dihedral_before", opt.minDihedralBefore},
                     {"optimize_min_dihedral_after", opt.minDihedralAfter},
                     {"optimize_edge_removals", double(opt.edgeRemovals)},
                     {"optimize_face_flips", double(opt.faceFlips)},
                     {"optimize_smoothed_vertices", double(opt.smoothedVertices)},
                     {"optimize_peeled_tets", double(opt.peeledTets)},
                     {"optimize_passes", double(opt.passes)},
                     {"vertices", double(mesh.points.size())},
                     {"tets", double(mesh.tets.size())}};
    result.warnings = ctx.warnings();
    result.totalSeconds = std::chrono::duration<double>(Clock::now() - start).count();

    json report;
    report["femesher_version"] = FEMESHER_VERSION;
    report["libraries"] = {{"ITK", FEMESHER_ITK_VERSION}, {"VTK", FEMESHER_VTK_VERSION},
                           {"CGAL", FEMESHER_CGAL_VERSION}, {"TetGen", FEMESHER_TETGEN_VERSION}};
    report["input"] = geometryJson(input);
    json labels = json::array();
    for (int m = 1; m <= vol.materialCount(); ++m)
      labels.push_back({{"id", vol.userLabel[m]}, {"name", vol.materials[m].name},
                        {"color", vol.materials[m].color}, {"voxels", vol.voxelCounts[m]},
                        {"in_mesh", present.count(m) > 0}});
    report["input"]["labels"] = labels;
    report["input"]["dropped_labels"] = vol.droppedLabels;
    report["parameters"] = json::parse(parametersToJson(params));
    json stages = json::array();
    for (const auto& t : result.timings) stages.push_back({{"name", t.name}, {"seconds", t.seconds}});
    report["stages"] = stages;
    report["total_seconds"] = result.totalSeconds;
    json counts = json::object();
    for (const auto& [k, v] : result.counts) counts[k] = v;
    report["counts"] = counts;
    report["surface_mesher"] = params.surfaceMesher;
    report["surface_mesher_used"] = useLdt && !ldtUsed ? "delaunay (ldt surface not watertight)"
                                                        : params.surfaceMesher;
    // Wall seconds of the two surface meshers inside the BoundaryMesh stage (the local Delaunay
    // one runs after, and uses, the restricted Delaunay one).
    report["surface_mesher_seconds"] = {{"restricted_delaunay", restrictedSeconds},
                                        {"ldt", ldtSeconds}};
    report["volume_mesh"] = {{"method", vm.method}, {"tetgen_switches", vm.switches},
                             {"dropped_cavity_tets", vm.droppedCavityTets}};
    report["quality"] = json::parse(qualityReportToJson(result.quality, true));
    if (result.hasFidelity) report["fidelity"] = json::parse(fidelityReportToJson(result.fidelity));
    report["warnings"] = result.warnings;
    report["status"] = "ok";
    result.reportJson = report.dump(2);
  } catch (const Error& e) {
    return e.status();
  } catch (const std::bad_alloc&) {
    return Status(ErrorCode::MeshingFailed,
                  "Out of memory while meshing. Use a larger element size (target_edge_length) "
                  "or crop the label map.");
  } catch (const std::exception& e) {
    return Status(ErrorCode::Internal, std::string("Unexpected error: ") + e.what());
  }
  return result;
}

}  // namespace femesher
