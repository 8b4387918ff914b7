// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Generated multi-material shapes and the stages up to the boundary mesh (preprocess, indicator
// functions, sampling, junctions, particle system, unrefined restricted Delaunay surface), for
// the ParticleSystem, BoundaryMesh and LocalDelaunay tests. The stage parameters the tests
// depend on are set here explicitly (not left to the structs' defaults).
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

/// An n^3 volume, spacing 1, labelled by `label(x, y, z)` with (x, y, z) the voxel centre
/// relative to the volume's centre.
inline LabelVolume makeVolume(int n, const std::function<int(double, double, double)>& label) {
  LabelVolume v;
  v.dims = {n, n, n};
  v.labels.resize(size_t(n) * n * n);
  const double c = (n - 1) / 2.0;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) v.labels[v.index(i, j, k)] = label(i - c, j - c, k - c);
  return v;
}

/// Two touching balls (1 at x < 0, 2 at x >= 0, radius 8 voxels, centres 14 voxels apart) in 36^3.
inline LabelVolume twoSpheres() {
  return makeVolume(36, [](double x, double y, double z) {
    if ((x + 7) * (x + 7) + y * y + z * z < 64) return 1;
    if ((x - 7) * (x - 7) + y * y + z * z < 64 && x >= 0) return 2;
    return 0;
  });
}

/// Three slabs (1, 2, 3: angular sectors about the z axis) meeting on the z axis, inside a ball
/// of radius 15 voxels in 36^3: one triple line of (1, 2, 3), ending on the ball's surface.
inline LabelVolume threeSlabs() {
  return makeVolume(36, [](double x, double y, double z) {
    if (x * x + y * y + z * z >= 15 * 15) return 0;
    const double a = std::atan2(y, x);
    return a < -1.0 ? 1 : (a < 1.2 ? 2 : 3);
  });
}

/// Four materials meeting at a point (octant-like sectors inside a ball of radius 15 voxels,
/// 36^3): a quadruple point of (1, 2, 3, 4) near the centre.
inline LabelVolume fourAtAPoint() {
  return makeVolume(36, [](double x, double y, double z) {
    if (x * x + y * y + z * z >= 15 * 15) return 0;
    if (z < 0.3) return x < 0.2 ? 1 : 2;
    return y < -0.4 ? 3 : 4;
  });
}

/// The three shapes above, by name.
inline std::vector<std::pair<const char*, LabelVolume>> namedShapes() {
  return {{"two spheres", twoSpheres()},
          {"three slabs", threeSlabs()},
          {"four at a point", fourAtAPoint()}};
}

/// The stage outputs up to the boundary mesh.
struct StageRun {
  PreprocessedVolume vol;
  std::unique_ptr<IndicatorField> field;
  SurfaceSamples samples;
  Junctions junctions;
  ParticleSystemResult ps;
  std::vector<Vec3> points;  ///< the particles' local positions (junction particles first)
  BoundarySurface surface;   ///< restricted Delaunay surface of `points`, no refinement
};

/// Runs the stages on `v` with sampling spacing h (mm) and the given sizing: indicator smoothing
/// sigma 0.8 voxel, 30 particle-system iterations, the other stages at their defaults.
inline StageRun runStages(const LabelVolume& v, double h, const SizingFunction& sizing) {
  StageRun r;
  RunContext ctx;
  r.vol = preprocessLabels(v, {}, ctx);
  IndicatorParameters ip;
  ip.sigma = 0.8;
  r.field = std::make_unique<IndicatorField>(computeIndicatorFunctions(r.vol, ip, ctx));
  SurfaceSamplingParameters sp;
  sp.targetEdgeLength = h;
  sp.sizing = sizing;
  r.samples = sampleInterfaces(*r.field, v, sp, ctx);
  r.junctions = findJunctions(*r.field, sizing, {}, ctx);
  ParticleSystemParameters pp;
  pp.maxIterations = 30;
  r.ps = runParticleSystem(*r.field, r.samples, r.junctions, sizing, v, pp, ctx);
  for (const auto& p : r.ps.particles) r.points.push_back(p.local);
  BoundaryMeshParameters unrefined;
  unrefined.facetDistance = 0;
  r.surface = buildBoundaryMesh(*r.field, r.points, r.samples, nullptr, unrefined, ctx);
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
  return buildLocalDelaunaySurface(*r.field, r.ps.particles, r.junctions, r.surface, ctx, p);
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
