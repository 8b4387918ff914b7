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

/// The automatic edge length: edge_length_factor x mean spacing, but never more than a quarter of
/// the smallest side of the labelled box (tiny volumes still get a few elements across).
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
    InterfaceSurface interfaceSurface;
    const bool useLdt = params.surfaceMesher == "ldt";
    {
      StageScope st(ctx, result.timings, "BoundaryMesh");
      BoundaryMeshParameters bp;
      bp.facetDistance = params.facetDistance;
      bp.voxelRefinement = params.voxelRefinement;
      bp.mesher = useLdt ? SurfaceMesher::LocalDelaunay : SurfaceMesher::RestrictedDelaunay;
      interfaceSurface =
          buildInterfaceSurface(*field, particles, ps.particles, samples, junctions, bp, ctx);
      st.done();
    }
    const BoundarySurface& surface = interfaceSurface.surface;
    const LocalDelaunayResult& ldt = interfaceSurface.ldt;
    const double junctionShare = interfaceSurface.junctionShare;
    const bool ldtUsed = interfaceSurface.ldtUsed;
    const double restrictedSeconds = interfaceSurface.restrictedSeconds;
    const double ldtSeconds = interfaceSurface.ldtSeconds;
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
