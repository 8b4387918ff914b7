// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/RunContext.h>
#include <femesher/Status.h>
#include <femesher/stages/BoundaryMesh.h>
#include <femesher/stages/SurfaceRefinement.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>

namespace femesher {

namespace {

using Clock = std::chrono::steady_clock;

double smallestSpacing(const PreprocessedVolume& vol) {
  return std::min({vol.spacing[0], vol.spacing[1], vol.spacing[2]});
}

/// Labels that no tet carries get their dense interface samples and (up to 4,000 of) their voxel
/// centres inserted, and the tets are relabelled; up to 3 rounds. Appends each such label to
/// `repaired` (once per round it is missing).
void repairMissingLabels(const IndicatorField& field, const SurfaceSamples& samples,
                         LabelledDelaunay& ld, std::vector<int>& repaired, RunContext& ctx) {
  const PreprocessedVolume& vol = field.volume();
  for (int round = 0; round < 3; ++round) {
    const auto counts = ld.tetsPerLabel();
    std::vector<int> missing;
    for (int m = 1; m <= vol.materialCount(); ++m)
      if (counts[m] == 0 && vol.voxelCounts[m] > 0) missing.push_back(m);
    if (missing.empty()) break;
    std::vector<Vec3> extra;
    std::mt19937_64 rng(1234 + round);
    for (int m : missing) {
      repaired.push_back(m);
      for (const auto& s : samples.all)
        if (s.a == m || s.b == m) extra.push_back(vol.localToCanonical(s.local));
      std::vector<Vec3> centres;
      for (int k = 0; k < vol.dims[2]; ++k)
        for (int j = 0; j < vol.dims[1]; ++j)
          for (int i = 0; i < vol.dims[0]; ++i)
            if (vol.at(i, j, k) == m)
              centres.push_back(vol.localToCanonical({double(i), double(j), double(k)}));
      std::shuffle(centres.begin(), centres.end(), rng);
      if (centres.size() > 4000) centres.resize(4000);
      extra.insert(extra.end(), centres.begin(), centres.end());
    }
    ld.insertRepairPoints(extra);
    ld.label(field, ctx);
  }
}

/// Last resort for a label that still has no tet (a feature far below the sampling, e.g. one
/// voxel): the Delaunay tets that contain its voxel centres (up to 64) take its label. Appends
/// each such label to `forcedLabels`.
void forceMissingLabels(const PreprocessedVolume& vol, LabelledDelaunay& ld,
                        std::vector<int>& forcedLabels) {
  const auto counts = ld.tetsPerLabel();
  for (int m = 1; m <= vol.materialCount(); ++m) {
    if (counts[m] != 0 || vol.voxelCounts[m] == 0) continue;
    size_t forced = 0;
    for (int k = 0; k < vol.dims[2] && forced < 64; ++k)
      for (int j = 0; j < vol.dims[1] && forced < 64; ++j)
        for (int i = 0; i < vol.dims[0] && forced < 64; ++i)
          if (vol.at(i, j, k) == m &&
              ld.forceLabelAt(vol.localToCanonical({double(i), double(j), double(k)}), m))
            ++forced;
    if (forced) forcedLabels.push_back(m);
  }
}

/// Share of junction particles that are vertices of an edge shared by the triangles of three or
/// more materials (i.e. the triple lines appear as mesh edges there).
double junctionsOnTripleEdges(const BoundarySurface& s, const PreprocessedVolume& vol,
                              const std::vector<Vec3>& particlesLocal, size_t junctionCount,
                              RunContext& ctx) {
  if (junctionCount == 0) return 1.0;
  // Per surface vertex: the most materials an edge of it separates (the edges' materials from
  // the triangles' pairs, sorted: no map of sets).
  std::vector<std::array<int32_t, 3>> edgeMaterial;  // (a, b, material), a < b
  edgeMaterial.reserve(6 * s.triangles.size());
  for (size_t t = 0; t < s.triangles.size(); ++t)
    for (int e = 0; e < 3; ++e) {
      int32_t a = s.triangles[t][e], b = s.triangles[t][(e + 1) % 3];
      if (a > b) std::swap(a, b);
      edgeMaterial.push_back({a, b, s.trianglePairs[t].first});
      edgeMaterial.push_back({a, b, s.trianglePairs[t].second});
    }
  std::sort(edgeMaterial.begin(), edgeMaterial.end());
  std::vector<size_t> best(s.points.size(), 0);
  for (size_t i = 0; i < edgeMaterial.size();) {
    size_t j = i, distinct = 0;
    for (; j < edgeMaterial.size() && edgeMaterial[j][0] == edgeMaterial[i][0] &&
           edgeMaterial[j][1] == edgeMaterial[i][1];
         ++j)
      distinct += j == i || edgeMaterial[j][2] != edgeMaterial[j - 1][2];
    for (int32_t v : {edgeMaterial[i][0], edgeMaterial[i][1]})
      best[size_t(v)] = std::max(best[size_t(v)], distinct);
    i = j;
  }
  // The surface vertex at a junction particle's position (the first of equal positions).
  std::vector<std::pair<Vec3, int32_t>> at;
  at.reserve(s.points.size());
  for (size_t i = 0; i < s.points.size(); ++i) at.push_back({s.points[i], int32_t(i)});
  std::sort(at.begin(), at.end());
  size_t ok = 0, notVertex = 0;
  for (size_t j = 0; j < junctionCount && j < particlesLocal.size(); ++j) {
    const Vec3 p = vol.localToCanonical(particlesLocal[j]);
    const auto it = std::lower_bound(at.begin(), at.end(), std::make_pair(p, int32_t(-1)));
    if (it == at.end() || it->first != p)
      ++notVertex;
    else if (best[size_t(it->second)] >= 3)
      ++ok;
  }
  ctx.debug("Junction particles: " + std::to_string(junctionCount) + ", on triple edges " +
            std::to_string(ok) + ", not a surface vertex " + std::to_string(notVertex));
  return double(ok) / double(junctionCount);
}

/// The local Delaunay surface of the particles (LocalDelaunay.h), on `restricted` (the restricted
/// Delaunay surface built with `params`, whose points were `particles`).
void addLocalDelaunaySurface(const IndicatorField& field, const std::vector<Vec3>& particles,
                             const std::vector<Particle>& systemParticles,
                             const SurfaceSamples& samples, const Junctions& junctions,
                             InterfaceSurface& out, RunContext& ctx) {
  const PreprocessedVolume& vol = field.volume();
  BoundarySurface& surface = out.surface;
  LocalDelaunayResult& ldt = out.ldt;
  const auto ldtStart = Clock::now();
  // The particles as the system left them (junction particles carry their label sets).
  std::vector<Particle> plist = systemParticles;
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
      surface.refinementPoints + surface.shapePoints + surface.voxelCentrePoints +
          surface.junctionPoints >
      0;
  BoundarySurface particlesOnly;
  if (refined) {
    BoundaryMeshParameters unrefined;
    unrefined.facetDistance = 0;
    particlesOnly = buildBoundaryMesh(field, particles, samples, nullptr, unrefined, ctx);
  }
  ldt = buildLocalDelaunaySurface(field, plist, junctions, refined ? particlesOnly : surface,
                                  LocalDelaunayParameters{}, ctx);
  out.ldtSeconds = std::chrono::duration<double>(Clock::now() - ldtStart).count();
  if (ldt.openEdgesAfter > 0 || ldt.selfIntersectionsAfter > 0) {
    // An open surface would let TetGen's regions leak into each other (wrong materials), a
    // self-intersecting one is no valid PLC: keep the restricted-Delaunay surface instead.
    ctx.warn("The local Delaunay surface still has " + std::to_string(ldt.openEdgesAfter) +
             " open edges and " + std::to_string(ldt.selfIntersectionsAfter) +
             " self-intersections after hole filling; the restricted Delaunay surface "
             "(watertight) is used instead.");
    return;
  }
  if (ldt.fromRestricted > 0)
    ctx.info("The local Delaunay surface was closed with " + std::to_string(ldt.fromRestricted) +
             " restricted-Delaunay triangles (" + std::to_string(ldt.restrictedComponents) +
             " regions; " + std::to_string(ldt.replacedTriangles) + " local triangles replaced).");
  // Replace the restricted-Delaunay triangles by the LDT ones (used vertices only).
  std::vector<int32_t> id(plist.size(), -1);
  surface.points.clear();
  surface.triangles.clear();
  surface.trianglePairs = ldt.trianglePairs;
  surface.fromDelaunay = false;
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

}  // namespace

BoundarySurface buildBoundaryMesh(const IndicatorField& field, const std::vector<Vec3>& points,
                                  const SurfaceSamples& samples, const Junctions* junctions,
                                  const BoundaryMeshParameters& params, RunContext& ctx) {
  const PreprocessedVolume& vol = field.volume();
  const double facetDistance = params.facetDistance * smallestSpacing(vol);  // mm
  auto ld = std::make_shared<LabelledDelaunay>(vol.materialCount());
  std::vector<Vec3> pts;
  pts.reserve(points.size());
  for (const Vec3& l : points) pts.push_back(vol.localToCanonical(field.snapToBox(l)));
  const bool particlesAreVertices = pts.size() >= 4;
  if (pts.size() < 4) {
    // Tiny inputs: the sampling spacing exceeds the whole structure; use every interface vertex.
    pts.clear();
    for (const auto& smp : samples.all)
      pts.push_back(vol.localToCanonical(field.snapToBox(smp.local)));
  }
  if (pts.size() < 4)
    throw Error(ErrorCode::MeshingFailed, "Too few interface samples (" +
                                              std::to_string(pts.size()) +
                                              ") to build a mesh: lower target_edge_length.");
  ld->insert(pts);
  ctx.progress(0.4);
  ld->label(field, ctx);
  ctx.progress(0.5);
  BoundarySurface out;
  if (facetDistance > 0) {
    out.refinementPoints = refineFacetDistance(field, *ld, facetDistance, ctx);
    if (params.sizeAt && params.facetShape.minAngleDegrees > 0)
      out.shapePoints = refineFacetShape(field, *ld, params.sizeAt, params.facetShape, ctx);
    if (params.voxelRefinement) out.voxelCentrePoints = refineVoxelCentres(field, *ld, ctx);
  }
  if (junctions && !junctions->particles.empty() && facetDistance > 0 && particlesAreVertices &&
      points.size() >= junctions->particles.size()) {
    const JunctionRefinement jr = refineJunctionEdges(field, *ld, *junctions, ctx);
    out.junctionPoints = jr.inserted;
    out.junctionsOffLines = jr.stillOff;
  }
  ctx.progress(0.6);
  repairMissingLabels(field, samples, *ld, out.repairedLabels, ctx);
  forceMissingLabels(vol, *ld, out.forcedLabels);
  ctx.progress(0.8);
  ld->interfaceTriangles(out.points, out.triangles, out.trianglePairs);
  out.delaunayVertices = ld->vertexCount();
  out.delaunayTets = ld->tetCount();
  out.delaunay = ld;
  ctx.progress(1.0);
  return out;
}

InterfaceSurface buildInterfaceSurface(const IndicatorField& field, std::vector<Vec3> particles,
                                       const std::vector<Particle>& systemParticles,
                                       const SurfaceSamples& samples, const Junctions& junctions,
                                       const BoundaryMeshParameters& params, RunContext& ctx) {
  const PreprocessedVolume& vol = field.volume();
  InterfaceSurface out;
  const auto boundaryStart = Clock::now();
  // Points on the input's box exactly on it (as buildBoundaryMesh does), so that the particles
  // below are the surface's vertices to the bit.
  for (Vec3& l : particles) l = field.snapToBox(l);
  out.surface = buildBoundaryMesh(field, particles, samples, &junctions, params, ctx);
  out.restrictedSeconds = std::chrono::duration<double>(Clock::now() - boundaryStart).count();
  out.junctionShare =
      junctionsOnTripleEdges(out.surface, vol, particles, junctions.particles.size(), ctx);
  if (params.mesher == SurfaceMesher::LocalDelaunay)
    addLocalDelaunaySurface(field, particles, systemParticles, samples, junctions, out, ctx);
  for (int m : out.surface.repairedLabels)
    ctx.warn("Label " + std::to_string(vol.userLabel[m]) +
             " was too small for the element size; extra points were inserted to keep it.");
  for (int m : out.surface.forcedLabels)
    ctx.warn("Label " + std::to_string(vol.userLabel[m]) +
             " is far below the element size; the tets holding its voxels carry it (its shape "
             "is not resolved: lower target_edge_length to resolve it).");
  return out;
}

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

std::vector<std::pair<std::string, double>> reportCounts(const InterfaceSurface& s) {
  const BoundarySurface& surface = s.surface;
  const LocalDelaunayResult& ldt = s.ldt;
  return {{"delaunay_vertices", double(surface.delaunayVertices)},
          {"delaunay_tets", double(surface.delaunayTets)},
          {"surface_vertices", double(surface.points.size())},
          {"surface_triangles", double(surface.triangles.size())},
          {"surface_checksum", surfaceChecksum(surface)},
          {"junction_particles_on_triple_edges", s.junctionShare},
          {"surface_open_edges", double(countOpenEdges(surface.triangles, surface.trianglePairs))},
          {"surface_refinement_points", double(surface.refinementPoints)},
          {"facet_shape_refinement_points", double(surface.shapePoints)},
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
          {"ldt_used", s.ldtUsed ? 1.0 : 0.0}};
}

}  // namespace femesher
