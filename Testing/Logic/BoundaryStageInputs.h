// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Generated multi-material shapes and the stages up to the boundary mesh (preprocess, indicator
// functions, sampling, junctions, particle system, unrefined restricted Delaunay surface), for
// the ParticleSystem, BoundaryMesh and LocalDelaunay tests. The stage parameters the tests
// depend on are set here explicitly (not left to the structs' defaults).
#include "TestShapes.h"

#include <femesher/MeshingRun.h>
#include <femesher/RunContext.h>
#include <femesher/Types.h>
#include <femesher/stages/BoundaryMesh.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/Junctions.h>
#include <femesher/stages/LabelPreprocess.h>
#include <femesher/stages/LocalDelaunay.h>
#include <femesher/stages/ParticleSystem.h>
#include <femesher/stages/SurfaceSampling.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <set>
#include <utility>
#include <vector>

namespace femesher::testing {

// The generated shapes of TestShapes.h, by their plain names here.
using test::fourAtAPoint;
using test::makeVolume;
using test::threeSlabs;
using test::twoSpheres;

/// Two touching spheres, three slabs on a line, four materials at a point, by name.
inline std::vector<std::pair<const char*, LabelVolume>> namedShapes() {
  return {{"two spheres", twoSpheres()},
          {"three slabs", threeSlabs()},
          {"four at a point", fourAtAPoint()}};
}

/// The stage outputs up to the boundary mesh: a MeshingRun (the pipeline's own stage glue) run
/// through the particle system, plus the particles' unrefined restricted Delaunay surface.
struct StageRun {
  StageRun(std::shared_ptr<const LabelVolume> in, std::unique_ptr<RunContext> context,
           std::unique_ptr<MeshingRun> meshingRun)
      : input(std::move(in)), ctx(std::move(context)), run(std::move(meshingRun)),
        vol(run->state().grid), field(run->state().field), samples(run->state().samples),
        junctions(run->state().junctions), ps(run->state().particleSystem),
        points(run->state().particles) {}
  std::shared_ptr<const LabelVolume> input;
  std::unique_ptr<RunContext> ctx;
  std::unique_ptr<MeshingRun> run;
  const PreprocessedVolume& vol;
  const std::unique_ptr<IndicatorField>& field;
  const SurfaceSamples& samples;
  const Junctions& junctions;
  const ParticleSystemResult& ps;
  const std::vector<Vec3>& points;  ///< the particles' local positions (junction particles first)
  BoundarySurface surface;          ///< restricted Delaunay surface of `points`, no refinement
};

/// Runs the stages on `v` with sampling spacing h (mm) and the given sizing: indicator smoothing
/// sigma 0.8 voxel, 30 particle-system iterations, the other stages at their defaults.
inline StageRun runStages(const LabelVolume& v, double h, const SizingFunction& sizing) {
  MeshingParameters p;
  p.indicators.sigma = 0.8;
  p.particles.maxIterations = 30;
  p.sizing.mode = SizingMode::Uniform;
  p.sizing.targetEdgeLength = h;
  auto input = std::make_shared<const LabelVolume>(v);
  auto ctx = std::make_unique<RunContext>();
  auto run = std::make_unique<MeshingRun>(*input, p, *ctx);
  run->runThrough(StageId::IndicatorFunctions);
  run->setSizing(sizing);
  run->runThrough(StageId::ParticleSystem);
  StageRun r(std::move(input), std::move(ctx), std::move(run));
  BoundaryMeshParameters unrefined;
  unrefined.facetDistance = 0;
  r.surface = buildBoundaryMesh(*r.field, r.points, r.samples, nullptr, unrefined, *r.ctx);
  return r;
}

/// runStages at a uniform spacing of 2 mm.
inline StageRun runStages(const LabelVolume& v) {
  return runStages(v, 2.0, [](const Vec3&) { return 2.0; });
}

/// The particles' canonical positions (the vertex positions of a local Delaunay surface).
inline std::vector<Vec3> canonicalPositions(const StageRun& r) {
  std::vector<Vec3> pos;
  for (const auto& p : r.ps.particles) pos.push_back(r.vol.localToCanonical(p.local));
  return pos;
}

/// The local Delaunay surface of r's particles on r's restricted Delaunay surface (threads 0 =
/// all).
inline LocalDelaunayResult localDelaunay(const StageRun& r, const LocalDelaunayParameters& p = {},
                                         int threads = 0) {
  RunContext ctx;
  ctx.setThreads(threads);
  return buildLocalDelaunaySurface(*r.field, r.ps.particles, r.junctions, r.surface, p, ctx);
}

/// A crippled star phase (neighbours must have almost the same normal, 3 votes needed) that
/// leaves holes, with no loop filling and no restricted closure.
inline LocalDelaunayParameters crippledStars() {
  LocalDelaunayParameters p;
  p.normalAgreement = 0.97;
  p.minVotes = 3;
  p.fillLoops = false;
  p.restrictedClosure = false;
  return p;
}

/// Number of junction particles of `r` (their positions put on the input's box as
/// buildBoundaryMesh does) that are vertices of an edge shared by triangles of >= 3 materials of
/// `s`, i.e. where the triple lines appear as edges of the surface.
inline size_t junctionParticlesOnTripleEdges(const BoundarySurface& s, const StageRun& r) {
  std::map<Vec3, int> vid;
  for (size_t i = 0; i < s.points.size(); ++i) vid[s.points[i]] = int(i);
  std::map<std::pair<int, int>, std::set<int>> edgeMaterials;
  for (size_t t = 0; t < s.triangles.size(); ++t)
    for (int e = 0; e < 3; ++e) {
      int a = s.triangles[t][e], b = s.triangles[t][(e + 1) % 3];
      if (a > b) std::swap(a, b);
      edgeMaterials[{a, b}].insert(s.trianglePairs[t].first);
      edgeMaterials[{a, b}].insert(s.trianglePairs[t].second);
    }
  std::map<int, size_t> best;
  for (const auto& [e, m] : edgeMaterials) {
    best[e.first] = std::max(best[e.first], m.size());
    best[e.second] = std::max(best[e.second], m.size());
  }
  size_t ok = 0;
  for (const auto& p : r.ps.particles) {
    if (p.junction < 0) continue;
    auto it = vid.find(r.vol.localToCanonical(r.field->snapToBox(p.local)));
    if (it != vid.end() && best[it->second] >= 3) ++ok;
  }
  return ok;
}

/// Share of the junction particles on triple edges of `s` (0 without junction particles).
inline double junctionShare(const BoundarySurface& s, const StageRun& r) {
  const auto total = std::count_if(r.ps.particles.begin(), r.ps.particles.end(),
                                   [](const Particle& p) { return p.junction >= 0; });
  return total ? double(junctionParticlesOnTripleEdges(s, r)) / double(total) : 0.0;
}

/// Voxel centres of the working grid next to another label (6-neighbourhood) that lie in a tet
/// of `ld` of another label (or in none); with `boundaryVoxels`, the number of such centres.
inline size_t misplacedBoundaryCentres(const PreprocessedVolume& vol, const LabelledDelaunay& ld,
                                       size_t* boundaryVoxels = nullptr) {
  size_t wrong = 0, boundary = 0;
  for (int k = 0; k < vol.dims[2]; ++k)
    for (int j = 0; j < vol.dims[1]; ++j)
      for (int i = 0; i < vol.dims[0]; ++i) {
        const int l = vol.at(i, j, k);
        bool edge = false;
        for (int a = 0; a < 3 && !edge; ++a)
          for (int s : {-1, 1}) {
            int q[3] = {i, j, k};
            q[a] += s;
            if (q[a] >= 0 && q[a] < vol.dims[a] && vol.at(q[0], q[1], q[2]) != l) edge = true;
          }
        if (!edge) continue;
        ++boundary;
        if (ld.labelAt(vol.localToCanonical({double(i), double(j), double(k)})) != l) ++wrong;
      }
  if (boundaryVoxels) *boundaryVoxels = boundary;
  return wrong;
}

/// Each patch (label pair) of a local Delaunay surface is an oriented 2-manifold with boundary:
/// every edge used by at most two of its triangles, two in opposite directions; no vertex triple
/// used twice (in any patch); every vertex a particle.
inline void expectOrientedManifoldPatches(const LocalDelaunayResult& ldt, size_t particles,
                                          const char* name) {
  std::map<std::pair<std::pair<uint16_t, uint16_t>, std::pair<int32_t, int32_t>>, int> directed;
  std::set<std::array<int32_t, 3>> triples;
  size_t repeated = 0, overused = 0, sameDirection = 0, foreign = 0;
  for (size_t t = 0; t < ldt.triangles.size(); ++t) {
    std::array<int32_t, 3> v = ldt.triangles[t];
    for (int32_t x : v) foreign += x < 0 || size_t(x) >= particles;
    for (int e = 0; e < 3; ++e) {
      const int32_t a = v[size_t(e)], b = v[size_t((e + 1) % 3)];
      ++directed[{ldt.trianglePairs[t], {a, b}}];
    }
    std::sort(v.begin(), v.end());
    repeated += !triples.insert(v).second;
  }
  for (const auto& [key, n] : directed) {
    const auto& [patch, e] = key;
    const auto back = directed.find({patch, {e.second, e.first}});
    const int reverse = back == directed.end() ? 0 : back->second;
    sameDirection += n > 1;
    overused += e.first < e.second && n + reverse > 2;
  }
  EXPECT_EQ(foreign, 0u) << name;
  EXPECT_EQ(repeated, 0u) << name << ": vertex triples used twice";
  EXPECT_EQ(overused, 0u) << name << ": patch edges used by more than two triangles";
  EXPECT_EQ(sameDirection, 0u) << name << ": patch edges used twice in the same direction";
}

}  // namespace femesher::testing
