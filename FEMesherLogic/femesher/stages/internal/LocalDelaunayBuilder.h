// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file LocalDelaunayBuilder.h
/// Private to the logic library (CGAL types): the builder of the local Delaunay surface
/// (LocalDelaunay.h) and the small types its phases share. Each phase is in its own file:
/// LocalDelaunayPatches.cxx (patches, normals, restricted triangles, triple lines),
/// LocalDelaunayStars.cxx (stars, candidates, selection), LocalDelaunayHoles.cxx (hole loops and
/// their filling), LocalDelaunayClosure.cxx (restricted closure and self-intersections), and
/// LocalDelaunay.cxx (the run and the entry points). Include it from those files only.

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Constrained_triangulation_face_base_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <femesher/VecMath.h>
#include <femesher/stages/BoundaryMesh.h>
#include <femesher/stages/IndicatorFunctions.h>
#include <femesher/stages/Junctions.h>
#include <femesher/stages/LocalDelaunay.h>
#include <femesher/stages/ParticleSystem.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

namespace femesher {

class RunContext;

namespace ldt {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
struct VInfo {
  int32_t id = -1;
};
using Vb2 = CGAL::Triangulation_vertex_base_with_info_2<VInfo, K>;
using Fb2 =
    CGAL::Triangulation_face_base_with_info_2<int, K,
                                              CGAL::Constrained_triangulation_face_base_2<K>>;
using Tds2 = CGAL::Triangulation_data_structure_2<Vb2, Fb2>;
using Cdt = CGAL::Constrained_Delaunay_triangulation_2<K, Tds2, CGAL::Exact_predicates_tag>;

constexpr double kPi = 3.14159265358979323846;
constexpr double kTwoPi = 2 * kPi;

inline Vec3 normalized(const Vec3& a) {
  const double l = norm(a);
  return l > 0 ? scale(a, 1.0 / l) : Vec3{0, 0, 0};
}
inline double wrapAngle(double x) {
  x = std::fmod(x, kTwoPi);
  return x < 0 ? x + kTwoPi : x;
}

/// Orthonormal tangent frame of a unit normal.
struct Frame {
  Vec3 t1{1, 0, 0}, t2{0, 1, 0}, n{0, 0, 1};
};
inline Frame frameOf(const Vec3& n) {
  Frame f;
  f.n = n;
  Vec3 t = std::fabs(n[0]) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
  t = normalized(sub(t, scale(n, dot(t, n))));
  f.t1 = t;
  f.t2 = cross(n, t);
  return f;
}
inline double angleIn(const Frame& f, const Vec3& d) {
  return std::atan2(dot(d, f.t2), dot(d, f.t1));
}

inline uint64_t edgeKey(int32_t a, int32_t b) {
  if (a > b) std::swap(a, b);
  return (uint64_t(uint32_t(a)) << 32) | uint32_t(b);
}

struct PatchEdge {
  uint64_t edge;
  uint32_t patch;
  bool operator==(const PatchEdge& o) const { return edge == o.edge && patch == o.patch; }
};
struct PatchEdgeHash {
  size_t operator()(const PatchEdge& k) const {
    return size_t((k.edge ^ (uint64_t(k.patch) * 0x9E3779B97F4A7C15ull)) * 0xBF58476D1CE4E5B9ull);
  }
};
using Triple = std::array<int32_t, 3>;
struct TripleHash {
  size_t operator()(const Triple& t) const {
    uint64_t h = 0xCBF29CE484222325ull;
    for (int32_t x : t) h = (h ^ uint64_t(uint32_t(x))) * 0x100000001B3ull;
    return size_t(h);
  }
};
struct TriKey {
  Triple v;  // sorted
  uint32_t patch;
  bool operator==(const TriKey& o) const { return v == o.v && patch == o.patch; }
  bool operator<(const TriKey& o) const { return patch != o.patch ? patch < o.patch : v < o.v; }
};
struct TriKeyHash {
  size_t operator()(const TriKey& k) const {
    return TripleHash()(k.v) ^ size_t(uint64_t(k.patch) * 0x9E3779B97F4A7C15ull);
  }
};
inline Triple sorted(Triple t) {
  std::sort(t.begin(), t.end());
  return t;
}
/// +1 when the cyclic triangle t runs a -> b, -1 when b -> a, 0 when the edge is not in t.
inline int direction(const Triple& t, int32_t a, int32_t b) {
  for (int k = 0; k < 3; ++k) {
    if (t[k] == a && t[(k + 1) % 3] == b) return 1;
    if (t[k] == b && t[(k + 1) % 3] == a) return -1;
  }
  return 0;
}

/// For every material, the edges used an odd number of times by the triangles bounding it
/// (label 0 = outside not counted), as (material, edgeKey), sorted.
std::vector<std::pair<uint16_t, uint64_t>> oddEdges(
    const std::vector<Triple>& triangles, const std::vector<std::pair<uint16_t, uint16_t>>& pairs);

/// Pairs (a, b), a in `suspects`, b any triangle, that intersect (each unordered pair once).
std::vector<std::pair<int32_t, int32_t>> intersectingPairs(const std::vector<Triple>& tris,
                                                           const std::vector<char>& suspect,
                                                           const std::vector<Vec3>& pos);

/// The local Delaunay surface under construction and the inputs it is built from.
class Builder {
 public:
  Builder(const IndicatorField& field, const std::vector<Particle>& particles,
          const Junctions& junctions, const BoundarySurface& restricted, RunContext& ctx,
          const LocalDelaunayParameters& params, LocalDelaunayResult& res)
      : field_(field),
        vol_(field.volume()),
        P_(particles),
        J_(junctions),
        rdt_(restricted),
        ctx_(ctx),
        prm_(params),
        res_(res),
        n_(particles.size()) {}

  void run();

 private:
  enum Source : uint8_t { kStar, kSingleVote, kLoopFill, kRestricted };
  struct Tri {
    Triple v;  // oriented: normal from the patch's first label into its second
    uint32_t patch;
    Source source;
    bool alive;
  };
  struct EdgeRec {
    int32_t t[2] = {-1, -1};
    int32_t count = 0;
  };
  struct Candidate {
    TriKey key;
    int votes;
    bool restricted;
    double quality;
  };
  struct Link {
    int32_t other;
    uint32_t triple;
  };

  // Setup.
  void buildPatches();
  uint32_t patchFor(uint16_t a, uint16_t b);
  int slotOf(int32_t i, uint32_t patch) const {
    for (uint32_t s = memOff_[size_t(i)]; s < memOff_[size_t(i) + 1]; ++s)
      if (memPatch_[s] == patch) return int(s);
    return -1;
  }
  Vec3 normalAt(const Vec3& local, uint32_t patch) const;
  Vec3 vertexNormal(int32_t i, uint32_t patch) const {
    const int s = slotOf(i, patch);
    return s >= 0 ? frame_[size_t(s)].n : normalAt(P_[size_t(i)].local, patch);
  }
  Vec3 gradientMm(uint16_t m, int32_t i) const;
  void mapRestricted();
  // Triple lines.
  std::vector<uint32_t> triplesOf(int32_t i);
  bool tripleHasPatch(uint32_t triple, uint32_t patch) const {
    const auto& t = triples_[triple];
    const auto [a, b] = patchPairs_[patch];
    auto has = [&](uint16_t x) { return t[0] == x || t[1] == x || t[2] == x; };
    return has(a) && has(b);
  }
  uint16_t thirdLabel(uint32_t triple, uint32_t patch) const {
    const auto [a, b] = patchPairs_[patch];
    for (uint16_t x : triples_[triple])
      if (x != a && x != b) return x;
    return 0;
  }
  void buildLines();
  bool isRim(int32_t u, int32_t v, uint32_t patch) const {
    for (const Link& l : links_[size_t(u)])
      if (l.other == v && tripleHasPatch(l.triple, patch)) return true;
    return false;
  }
  bool farSideOfRim(int32_t x, int32_t y, int32_t z, uint32_t patch) const;
  bool alongOneLine(const Triple& t, uint32_t patch) const;
  // Stars and selection.
  void star(int32_t i, uint32_t patch, const Frame& fr, std::vector<uint32_t>& cand,
            std::vector<TriKey>& out) const;
  bool starOf(int32_t i, uint32_t patch, const Frame& fr, const std::vector<uint32_t>& cand,
              std::vector<TriKey>& out) const;
  std::vector<Candidate> computeCandidates();
  Triple orient(Triple v, uint32_t patch) const;
  bool sector(int32_t u, int32_t v, int32_t w, const Frame& f, double& start, double& width) const;
  bool canAdd(const Triple& v, uint32_t patch, bool sectors = true) const;
  int32_t addTri(const Triple& v, uint32_t patch, Source src);
  void removeTri(int32_t t);
  int edgeCount(int32_t a, int32_t b, uint32_t patch) const {
    auto it = edges_.find({edgeKey(a, b), patch});
    return it == edges_.end() ? 0 : it->second.count;
  }
  void select(std::vector<Candidate>& cands);
  // Holes.
  /// A hole edge, directed so that the hole is on its left (counter-clockwise about the normal).
  struct HoleEdge {
    uint32_t patch;
    int32_t from, to;
    bool rim;  // a rim link the patch does not use yet: either direction
    bool operator<(const HoleEdge& o) const {
      if (patch != o.patch) return patch < o.patch;
      if (from != o.from) return from < o.from;
      if (to != o.to) return to < o.to;
      return rim < o.rim;
    }
  };
  void fillHoles();
  /// Every hole edge, sorted by patch, unique.
  std::vector<HoleEdge> holeEdges();
  /// The hole loops of one patch traced through its hole edges [first, last).
  std::vector<std::vector<int32_t>> traceLoops(const HoleEdge* first, const HoleEdge* last) const;
  bool fillLoop(const std::vector<int32_t>& loop, uint32_t patch);
  bool planarFill(const std::vector<int32_t>& loop, uint32_t patch,
                  std::vector<Triple>& fill) const;
  bool spatialFill(const std::vector<int32_t>& loop, uint32_t patch,
                   std::vector<Triple>& fill) const;
  // Restricted closure.
  void restrictedClosure();
  void collect(std::vector<Triple>& tris, std::vector<std::pair<uint16_t, uint16_t>>& pairs) const;

  const IndicatorField& field_;
  const PreprocessedVolume& vol_;
  const std::vector<Particle>& P_;
  const Junctions& J_;
  const BoundarySurface& rdt_;
  RunContext& ctx_;
  const LocalDelaunayParameters& prm_;
  LocalDelaunayResult& res_;
  size_t n_;

  std::vector<Vec3> pos_;
  std::vector<uint32_t> off_, adj_;
  std::map<std::pair<uint16_t, uint16_t>, uint32_t> patchId_;
  std::vector<std::pair<uint16_t, uint16_t>> patchPairs_;
  std::vector<uint32_t> memOff_, memPatch_;  // per particle: its patches (CSR)
  std::vector<Frame> frame_;                 // per membership: tangent frame
  std::vector<std::array<uint16_t, 3>> triples_;
  std::map<std::array<uint16_t, 3>, uint32_t> tripleId_;
  std::vector<std::vector<Link>> links_;
  struct RTri {
    Triple v;
    uint32_t patch;
  };
  std::vector<RTri> rtris_;
  std::unordered_set<TriKey, TriKeyHash> rset_;

  std::vector<Tri> tris_;
  std::unordered_map<PatchEdge, EdgeRec, PatchEdgeHash> edges_;
  std::unordered_map<Triple, int32_t, TripleHash> byVerts_;
  std::vector<std::vector<int32_t>> fan_;  // per membership: alive triangles at that corner
};

}  // namespace ldt

}  // namespace femesher
