// SPDX-License-Identifier: GPL-3.0-or-later
#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Constrained_triangulation_face_base_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>
#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/VecMath.h>
#include <femesher/stages/BoundaryMesh.h>
#include <femesher/stages/LocalDelaunay.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <numeric>
#include <unordered_map>
#include <unordered_set>

namespace femesher {

namespace {

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
using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, int32_t>;

constexpr double kPi = 3.14159265358979323846;
constexpr double kTwoPi = 2 * kPi;

Vec3 normalized(const Vec3& a) {
  const double l = norm(a);
  return l > 0 ? scale(a, 1.0 / l) : Vec3{0, 0, 0};
}
double wrapAngle(double x) {
  x = std::fmod(x, kTwoPi);
  return x < 0 ? x + kTwoPi : x;
}

/// Orthonormal tangent frame of a unit normal.
struct Frame {
  Vec3 t1{1, 0, 0}, t2{0, 1, 0}, n{0, 0, 1};
};
Frame frameOf(const Vec3& n) {
  Frame f;
  f.n = n;
  Vec3 t = std::fabs(n[0]) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
  t = normalized(sub(t, scale(n, dot(t, n))));
  f.t1 = t;
  f.t2 = cross(n, t);
  return f;
}
double angleIn(const Frame& f, const Vec3& d) { return std::atan2(dot(d, f.t2), dot(d, f.t1)); }

uint64_t edgeKey(int32_t a, int32_t b) {
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
Triple sorted(Triple t) {
  std::sort(t.begin(), t.end());
  return t;
}
/// +1 when the cyclic triangle t runs a -> b, -1 when b -> a, 0 when the edge is not in t.
int direction(const Triple& t, int32_t a, int32_t b) {
  for (int k = 0; k < 3; ++k) {
    if (t[k] == a && t[(k + 1) % 3] == b) return 1;
    if (t[k] == b && t[(k + 1) % 3] == a) return -1;
  }
  return 0;
}

/// 2 x inradius / circumradius (1 for the equilateral triangle, 0 for a degenerate one).
double shapeQuality(const Vec3& p0, const Vec3& p1, const Vec3& p2) {
  const double a = norm(sub(p1, p2)), b = norm(sub(p0, p2)), c = norm(sub(p0, p1));
  const double area = 0.5 * norm(cross(sub(p1, p0), sub(p2, p0)));
  const double denom = (a + b + c) * a * b * c;
  return denom > 0 ? 16.0 * area * area / denom : 0.0;
}

/// Exact test: do triangles A and B (vertex ids into pos) intersect other than in what they share?
bool trianglesIntersect(const Triple& A, const Triple& B, const std::vector<Vec3>& pos) {
  auto pt = [&](int32_t i) {
    return K::Point_3(pos[size_t(i)][0], pos[size_t(i)][1], pos[size_t(i)][2]);
  };
  int shared = 0;
  int sa[3] = {-1, -1, -1}, sb[3] = {-1, -1, -1};  // index in B of A's vertex k, and vice versa
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (A[i] == B[j]) {
        sa[i] = j;
        sb[j] = i;
        ++shared;
      }
  if (shared == 3) return true;  // the same triangle twice
  const K::Triangle_3 ta(pt(A[0]), pt(A[1]), pt(A[2])), tb(pt(B[0]), pt(B[1]), pt(B[2]));
  if (shared == 0) return CGAL::do_intersect(ta, tb);
  if (shared == 2) {
    int u = -1, v = -1, wa = -1, wb = -1;
    for (int i = 0; i < 3; ++i) {
      if (sa[i] < 0)
        wa = A[i];
      else if (u < 0)
        u = A[i];
      else
        v = A[i];
      if (sb[i] < 0) wb = B[i];
    }
    const K::Point_3 pu = pt(u), pv = pt(v), pa = pt(wa), pb = pt(wb);
    if (!CGAL::coplanar(pu, pv, pa, pb)) return false;
    if (CGAL::collinear(pu, pv, pa) || CGAL::collinear(pu, pv, pb)) return true;  // degenerate
    return CGAL::coplanar_orientation(pu, pv, pa, pb) == CGAL::POSITIVE;          // folded onto A
  }
  // One shared vertex: the intersection, if more than the vertex, ends on an opposite edge.
  Triple oa{}, ob{};
  int ka = 0, kb = 0;
  for (int i = 0; i < 3; ++i) {
    if (sa[i] < 0) oa[size_t(ka++)] = A[i];
    if (sb[i] < 0) ob[size_t(kb++)] = B[i];
  }
  const K::Segment_3 ea(pt(oa[0]), pt(oa[1])), eb(pt(ob[0]), pt(ob[1]));
  return CGAL::do_intersect(ea, tb) || CGAL::do_intersect(eb, ta);
}

/// For every material, the edges used an odd number of times by the triangles bounding it.
std::vector<std::pair<uint16_t, uint64_t>> oddEdges(
    const std::vector<Triple>& triangles, const std::vector<std::pair<uint16_t, uint16_t>>& pairs) {
  std::vector<std::pair<uint16_t, uint64_t>> uses;
  uses.reserve(triangles.size() * 6);
  for (size_t t = 0; t < triangles.size(); ++t)
    for (uint16_t m : {pairs[t].first, pairs[t].second}) {
      if (m == 0) continue;
      for (int e = 0; e < 3; ++e)
        uses.emplace_back(m, edgeKey(triangles[t][e], triangles[t][(e + 1) % 3]));
    }
  std::sort(uses.begin(), uses.end());
  std::vector<std::pair<uint16_t, uint64_t>> odd;
  for (size_t i = 0; i < uses.size();) {
    size_t j = i;
    while (j < uses.size() && uses[j] == uses[i]) ++j;
    if ((j - i) % 2) odd.push_back(uses[i]);
    i = j;
  }
  return odd;
}

/// Pairs (a, b), a in `suspects`, b any triangle, that intersect (each unordered pair once).
std::vector<std::pair<int32_t, int32_t>> intersectingPairs(const std::vector<Triple>& tris,
                                                           const std::vector<char>& suspect,
                                                           const std::vector<Vec3>& pos) {
  std::vector<Box> all, sus;
  all.reserve(tris.size());
  for (size_t t = 0; t < tris.size(); ++t) {
    CGAL::Bbox_3 b;
    for (int32_t v : tris[t]) {
      const Vec3& p = pos[size_t(v)];
      b += CGAL::Bbox_3(p[0], p[1], p[2], p[0], p[1], p[2]);
    }
    all.emplace_back(b, int32_t(t));
    if (suspect[t]) sus.emplace_back(b, int32_t(t));
  }
  std::vector<std::pair<int32_t, int32_t>> out;
  CGAL::box_intersection_d(sus.begin(), sus.end(), all.begin(), all.end(),
                           [&](const Box& a, const Box& b) {
                             const int32_t x = a.info(), y = b.info();
                             if (x == y || (suspect[size_t(y)] && y < x)) return;
                             if (trianglesIntersect(tris[size_t(x)], tris[size_t(y)], pos))
                               out.emplace_back(std::min(x, y), std::max(x, y));
                           });
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

struct UnionFind {
  std::vector<int32_t> parent;
  explicit UnionFind(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int32_t find(int32_t x) {
    while (parent[size_t(x)] != x) x = parent[size_t(x)] = parent[size_t(parent[size_t(x)])];
    return x;
  }
  void unite(int32_t a, int32_t b) {
    a = find(a);
    b = find(b);
    if (a != b) parent[size_t(std::max(a, b))] = std::min(a, b);
  }
};

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
  void fillHoles();
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

uint32_t Builder::patchFor(uint16_t a, uint16_t b) {
  if (a > b) std::swap(a, b);
  auto it = patchId_.find({a, b});
  if (it != patchId_.end()) return it->second;
  const uint32_t id = uint32_t(patchPairs_.size());
  patchId_[{a, b}] = id;
  patchPairs_.emplace_back(a, b);
  return id;
}

Vec3 Builder::gradientMm(uint16_t m, int32_t i) const {
  const Vec3 g = field_.gradient(m, P_[size_t(i)].local);
  return {g[0] / vol_.spacing[0], g[1] / vol_.spacing[1], g[2] / vol_.spacing[2]};
}

Vec3 Builder::normalAt(const Vec3& local, uint32_t patch) const {
  const auto [a, b] = patchPairs_[patch];
  const Vec3 ga = field_.gradient(a, local), gb = field_.gradient(b, local);
  return normalized({(gb[0] - ga[0]) / vol_.spacing[0], (gb[1] - ga[1]) / vol_.spacing[1],
                     (gb[2] - ga[2]) / vol_.spacing[2]});
}

void Builder::buildPatches() {
  memOff_.assign(n_ + 1, 0);
  std::vector<std::vector<uint32_t>> mem(n_);
  for (size_t i = 0; i < n_; ++i) {
    if (P_[i].junction < 0) {
      mem[i].push_back(patchFor(P_[i].a, P_[i].b));
      continue;
    }
    const JunctionPoint& j = J_.particles[size_t(P_[i].junction)];
    for (int x = 0; x < j.count; ++x)
      for (int y = x + 1; y < j.count; ++y) mem[i].push_back(patchFor(j.labels[x], j.labels[y]));
  }
  for (size_t i = 0; i < n_; ++i) memOff_[i + 1] = memOff_[i] + uint32_t(mem[i].size());
  memPatch_.resize(memOff_[n_]);
  frame_.resize(memOff_[n_]);
  for (size_t i = 0; i < n_; ++i)
    std::copy(mem[i].begin(), mem[i].end(), memPatch_.begin() + memOff_[i]);
  // Normals: the gradient of f_b - f_a at the particle, averaged over the particle and its
  // Delaunay neighbours on the same patch (the gradient is noisy at the voxel scale on thin and
  // curved parts); a neighbour whose normal points the other way (the far sheet of a thin layer)
  // is left out.
  std::vector<Vec3> nrm(memPatch_.size()), next(memPatch_.size());
  parallelFor(n_, ctx_.threads(), [&](size_t b, size_t e, int) {
    for (size_t i = b; i < e; ++i)
      for (uint32_t s = memOff_[i]; s < memOff_[i + 1]; ++s)
        nrm[s] = normalAt(P_[i].local, memPatch_[s]);
  });
  for (int pass = 0; pass < prm_.normalSmoothing; ++pass) {
    parallelFor(n_, ctx_.threads(), [&](size_t b, size_t e, int) {
      for (size_t i = b; i < e; ++i)
        for (uint32_t s = memOff_[i]; s < memOff_[i + 1]; ++s) {
          Vec3 sum = nrm[s];
          for (uint32_t k = off_[i]; k < off_[i + 1]; ++k) {
            const int sq = slotOf(int32_t(adj_[k]), memPatch_[s]);
            if (sq >= 0 && dot(nrm[size_t(sq)], nrm[s]) > -0.5) sum = add(sum, nrm[size_t(sq)]);
          }
          next[s] = norm(sum) > 0 ? normalized(sum) : nrm[s];
        }
    });
    nrm.swap(next);
  }
  for (size_t s = 0; s < nrm.size(); ++s) frame_[s] = frameOf(nrm[s]);
  fan_.assign(memPatch_.size(), {});
}

void Builder::mapRestricted() {
  struct VecHash {
    size_t operator()(const Vec3& v) const {
      uint64_t h = 0xCBF29CE484222325ull;
      for (double x : v) {
        uint64_t b;
        std::memcpy(&b, &x, sizeof b);
        h = (h ^ b) * 0x100000001B3ull;
      }
      return size_t(h);
    }
  };
  std::unordered_map<Vec3, int32_t, VecHash> id;
  id.reserve(n_);
  for (size_t i = 0; i < n_; ++i) id.emplace(pos_[i], int32_t(i));
  std::vector<int32_t> map(rdt_.points.size(), -1);
  for (size_t k = 0; k < rdt_.points.size(); ++k) {
    auto it = id.find(rdt_.points[k]);
    if (it != id.end()) map[k] = it->second;
  }
  for (size_t t = 0; t < rdt_.triangles.size(); ++t) {
    Triple v;
    bool ok = true;
    for (int k = 0; k < 3; ++k) {
      v[size_t(k)] = map[size_t(rdt_.triangles[t][size_t(k)])];
      ok = ok && v[size_t(k)] >= 0;
    }
    if (!ok) {
      ++res_.unmappedRestricted;
      continue;
    }
    const uint32_t patch = patchFor(rdt_.trianglePairs[t].first, rdt_.trianglePairs[t].second);
    rtris_.push_back({v, patch});
    rset_.insert({sorted(v), patch});
  }
}

std::vector<uint32_t> Builder::triplesOf(int32_t i) {
  std::vector<uint32_t> out;
  if (P_[size_t(i)].junction < 0) return out;
  const JunctionPoint& j = J_.particles[size_t(P_[size_t(i)].junction)];
  for (int x = 0; x < j.count; ++x)
    for (int y = x + 1; y < j.count; ++y)
      for (int z = y + 1; z < j.count; ++z) {
        const std::array<uint16_t, 3> t{j.labels[x], j.labels[y], j.labels[z]};
        auto it = tripleId_.find(t);
        if (it == tripleId_.end()) {
          it = tripleId_.emplace(t, uint32_t(triples_.size())).first;
          triples_.push_back(t);
        }
        out.push_back(it->second);
      }
  return out;
}

void Builder::buildLines() {
  links_.assign(n_, {});
  std::vector<int32_t> junction;
  for (size_t i = 0; i < n_; ++i)
    if (P_[i].junction >= 0) junction.push_back(int32_t(i));
  std::unordered_map<int32_t, std::vector<uint32_t>> tri;
  std::unordered_map<int32_t, Vec3> tangent;  // triple particles: direction of the line
  for (int32_t i : junction) {
    tri[i] = triplesOf(i);
    const JunctionPoint& j = J_.particles[size_t(P_[size_t(i)].junction)];
    if (j.count == 3) {
      const Vec3 g0 = gradientMm(j.labels[0], i), g1 = gradientMm(j.labels[1], i),
                 g2 = gradientMm(j.labels[2], i);
      const Vec3 t = cross(sub(g0, g1), sub(g0, g2));
      const double l = norm(t), s = norm(sub(g0, g1)) * norm(sub(g0, g2));
      if (s > 0 && l > 0.1 * s) tangent[i] = scale(t, 1.0 / l);
    }
  }
  struct Cand {
    double len;
    int32_t i, j;
    uint32_t triple;
    bool operator<(const Cand& o) const {
      if (len != o.len) return len < o.len;
      if (i != o.i) return i < o.i;
      if (j != o.j) return j < o.j;
      return triple < o.triple;
    }
  };
  auto needs = [&](int32_t i) {
    return J_.particles[size_t(P_[size_t(i)].junction)].count == 4 ? 1 : 2;
  };
  auto linksIn = [&](int32_t i, uint32_t t) {
    int used = 0;
    for (const Link& l : links_[size_t(i)]) used += l.triple == t;
    return used;
  };
  // A particle takes at most two links per line, pointing apart; a triple particle with a defined
  // tangent links roughly along it.
  const double apart = prm_.lineTurn, along = prm_.lineAlongTangent;
  auto slotFree = [&](int32_t i, int32_t j, uint32_t t) {
    const Vec3 d = normalized(sub(pos_[size_t(j)], pos_[size_t(i)]));
    int used = 0;
    for (const Link& l : links_[size_t(i)]) {
      if (l.triple != t) continue;
      if (l.other == j) return false;
      ++used;
      const Vec3 e = normalized(sub(pos_[size_t(l.other)], pos_[size_t(i)]));
      if (dot(d, e) > apart) return false;
    }
    if (used >= 2) return false;
    auto tg = tangent.find(i);
    if (tg != tangent.end() && std::fabs(dot(d, tg->second)) < along) return false;
    return true;
  };
  std::vector<Cand> cands;
  std::vector<int32_t> near, ring;
  // Pass 1: Delaunay 2-ring pairs, shortest first. Pass 2: line ends to line ends within the
  // 3-ring (gaps left by the junction sampling).
  for (int pass = 0; pass < 2; ++pass) {
    cands.clear();
    for (int32_t i : junction) {
      if (pass == 1) {
        bool open = false;
        for (uint32_t t : tri[i]) open = open || linksIn(i, t) < needs(i);
        if (!open) continue;
      }
      near.assign(1, i);
      for (int hop = 0; hop < (pass == 0 ? 2 : 3); ++hop) {
        ring = near;
        for (int32_t q : ring)
          for (uint32_t k = off_[size_t(q)]; k < off_[size_t(q) + 1]; ++k)
            near.push_back(int32_t(adj_[k]));
        std::sort(near.begin(), near.end());
        near.erase(std::unique(near.begin(), near.end()), near.end());
      }
      for (int32_t j : near) {
        if (j <= i || P_[size_t(j)].junction < 0) continue;
        const double len = norm(sub(pos_[size_t(j)], pos_[size_t(i)]));
        for (uint32_t t : tri[i]) {
          if (std::find(tri[j].begin(), tri[j].end(), t) == tri[j].end()) continue;
          if (pass == 1 && (linksIn(i, t) >= needs(i) || linksIn(j, t) >= needs(j))) continue;
          cands.push_back({len, i, j, t});
        }
      }
    }
    std::sort(cands.begin(), cands.end());
    for (const Cand& c : cands) {
      if (pass == 1 &&
          (linksIn(c.i, c.triple) >= needs(c.i) || linksIn(c.j, c.triple) >= needs(c.j)))
        continue;
      if (!slotFree(c.i, c.j, c.triple) || !slotFree(c.j, c.i, c.triple)) continue;
      links_[size_t(c.i)].push_back({c.j, c.triple});
      links_[size_t(c.j)].push_back({c.i, c.triple});
      ++res_.lineLinks;
    }
  }
  for (int32_t i : junction)
    for (uint32_t t : tri[i]) {
      int used = 0;
      for (const Link& l : links_[size_t(i)]) used += l.triple == t;
      const bool quad = J_.particles[size_t(P_[size_t(i)].junction)].count == 4;
      if (used < (quad ? 1 : 2)) ++res_.lineEnds;
    }
}

bool Builder::farSideOfRim(int32_t x, int32_t y, int32_t z, uint32_t patch) const {
  for (const Link& l : links_[size_t(x)]) {
    if (l.other != y || !tripleHasPatch(l.triple, patch)) continue;
    const uint16_t c = thirdLabel(l.triple, patch);
    const Vec3 e = normalized(sub(pos_[size_t(y)], pos_[size_t(x)]));
    Vec3 d = sub(pos_[size_t(z)], scale(add(pos_[size_t(x)], pos_[size_t(y)]), 0.5));
    d = sub(d, scale(e, dot(d, e)));
    Vec3 g = add(gradientMm(c, x), gradientMm(c, y));
    g = sub(g, scale(e, dot(g, e)));
    if (dot(d, g) > 0) return true;
  }
  return false;
}

bool Builder::alongOneLine(const Triple& t, uint32_t patch) const {
  for (int32_t v : t)
    if (P_[size_t(v)].junction < 0) return false;
  const auto [pa, pb] = patchPairs_[patch];
  const JunctionPoint& ju = J_.particles[size_t(P_[size_t(t[0])].junction)];
  const JunctionPoint& jv = J_.particles[size_t(P_[size_t(t[1])].junction)];
  const JunctionPoint& jw = J_.particles[size_t(P_[size_t(t[2])].junction)];
  for (int k = 0; k < ju.count; ++k) {
    const uint16_t c = ju.labels[size_t(k)];
    if (c == pa || c == pb) continue;
    if (ju.contains(pa, pb) && jv.contains(pa, c) && jv.contains(pb, c) && jw.contains(pa, c) &&
        jw.contains(pb, c))
      return true;
  }
  return false;
}

void Builder::star(int32_t i, uint32_t patch, const Frame& fr, std::vector<uint32_t>& cand,
                   std::vector<TriKey>& out) const {
  auto agrees = [&](uint32_t q) {
    const int s = slotOf(int32_t(q), patch);
    return s >= 0 && dot(frame_[size_t(s)].n, fr.n) >= prm_.normalAgreement;
  };
  // Local spacing: the sixth-nearest agreeing Delaunay neighbour; candidates lie within
  // `candidateRadius` times that (a flat, cospherical sample has Delaunay edges of any length).
  std::vector<double> d2;
  for (uint32_t k = off_[size_t(i)]; k < off_[size_t(i) + 1]; ++k)
    if (agrees(adj_[k])) {
      const Vec3 d = sub(pos_[adj_[k]], pos_[size_t(i)]);
      d2.push_back(dot(d, d));
    }
  if (d2.empty()) return;
  const size_t kth = std::min<size_t>(5, d2.size() - 1);
  std::nth_element(d2.begin(), d2.begin() + long(kth), d2.end());
  const double r2 = d2[kth] * prm_.candidateRadius * prm_.candidateRadius;
  auto within = [&](uint32_t q) {
    const Vec3 d = sub(pos_[q], pos_[size_t(i)]);
    return dot(d, d) <= r2;
  };
  auto gather = [&](bool twoRing) {
    cand.clear();
    for (uint32_t k = off_[size_t(i)]; k < off_[size_t(i) + 1]; ++k) {
      const uint32_t q = adj_[k];
      if (!within(q)) continue;
      if (!agrees(q)) continue;
      cand.push_back(q);
      if (!twoRing) continue;
      for (uint32_t k2 = off_[q]; k2 < off_[q + 1]; ++k2)
        if (adj_[k2] != uint32_t(i) && within(adj_[k2]) && agrees(adj_[k2]))
          cand.push_back(adj_[k2]);
    }
    for (const Link& l : links_[size_t(i)])
      if (tripleHasPatch(l.triple, patch) && agrees(uint32_t(l.other)))
        cand.push_back(uint32_t(l.other));
    std::sort(cand.begin(), cand.end());
    cand.erase(std::unique(cand.begin(), cand.end()), cand.end());
  };
  if (prm_.candidateRings == 2) {
    gather(true);
    starOf(i, patch, fr, cand, out);
  } else {
    gather(false);
    starOf(i, patch, fr, cand, out);
  }
}

/// Triangulates p's candidates in its tangent plane and appends p's star. False when p lies on
/// the hull of the projected candidates other than along a rim link of the patch.
bool Builder::starOf(int32_t i, uint32_t patch, const Frame& fr, const std::vector<uint32_t>& cand,
                     std::vector<TriKey>& out) const {
  if (cand.size() < 2) return false;
  Cdt dt;
  std::vector<Cdt::Vertex_handle> hv(cand.size());
  auto project = [&](uint32_t q) {
    const Vec3 d = sub(pos_[q], pos_[size_t(i)]);
    return K::Point_2(dot(d, fr.t1), dot(d, fr.t2));
  };
  const Cdt::Vertex_handle vi = dt.insert(K::Point_2(0, 0));
  vi->info().id = i;
  for (size_t k = 0; k < cand.size(); ++k) {
    hv[k] = dt.insert(project(cand[k]));
    if (hv[k]->info().id < 0) hv[k]->info().id = int32_t(cand[k]);
  }
  // Rim links as constraints (never two that cross: that would add a vertex).
  std::vector<std::pair<Cdt::Vertex_handle, Cdt::Vertex_handle>> segs;
  auto handleOf = [&](int32_t q) -> Cdt::Vertex_handle {
    if (q == i) return vi;
    auto it = std::lower_bound(cand.begin(), cand.end(), uint32_t(q));
    if (it == cand.end() || *it != uint32_t(q)) return Cdt::Vertex_handle();
    return hv[size_t(it - cand.begin())];
  };
  auto crosses = [&](Cdt::Vertex_handle a, Cdt::Vertex_handle b) {
    for (const auto& [c, d] : segs) {
      const int shared = (a == c) + (a == d) + (b == c) + (b == d);
      if (shared == 2) return true;
      const K::Point_2 &pa = a->point(), &pb = b->point(), &pc = c->point(), &pd = d->point();
      if (shared == 0) {
        if (CGAL::do_intersect(K::Segment_2(pa, pb), K::Segment_2(pc, pd))) return true;
        continue;
      }
      const K::Point_2& s = (a == c || a == d) ? pa : pb;
      const K::Point_2& o1 = (a == c || a == d) ? pb : pa;
      const K::Point_2& o2 = (c == a || c == b) ? pd : pc;
      if (CGAL::orientation(s, o1, o2) == CGAL::COLLINEAR &&
          (o1.x() - s.x()) * (o2.x() - s.x()) + (o1.y() - s.y()) * (o2.y() - s.y()) > 0)
        return true;
    }
    return false;
  };
  for (size_t k = 0; k <= cand.size(); ++k) {
    const int32_t x = k < cand.size() ? int32_t(cand[k]) : i;
    for (const Link& l : links_[size_t(x)]) {
      if (l.other < x || !tripleHasPatch(l.triple, patch)) continue;
      const Cdt::Vertex_handle a = handleOf(x), b = handleOf(l.other);
      if (a == Cdt::Vertex_handle() || b == Cdt::Vertex_handle() || a == b) continue;
      if (a->info().id != x || b->info().id != l.other || crosses(a, b)) continue;
      dt.insert_constraint(a, b);
      segs.emplace_back(a, b);
    }
  }
  if (vi->info().id != i || dt.dimension() < 2) return false;
  bool closed = true;
  auto fc = dt.incident_faces(vi), done = fc;
  if (fc == nullptr) return false;
  do {
    if (dt.is_infinite(fc)) {  // p on the hull: along a rim link is fine
      const int k = fc->index(vi);
      const Cdt::Vertex_handle a = fc->vertex((k + 1) % 3), b = fc->vertex((k + 2) % 3);
      const Cdt::Vertex_handle o = dt.is_infinite(a) ? b : a;
      if (!isRim(i, o->info().id, patch)) closed = false;
      continue;
    }
    const Triple t{fc->vertex(0)->info().id, fc->vertex(1)->info().id, fc->vertex(2)->info().id};
    if (t[0] < 0 || t[1] < 0 || t[2] < 0) continue;
    if (alongOneLine(t, patch)) continue;
    bool far = false;
    for (int e = 0; e < 3 && !far; ++e)
      far = farSideOfRim(t[size_t(e)], t[size_t((e + 1) % 3)], t[size_t((e + 2) % 3)], patch);
    if (far) continue;
    out.push_back({sorted(t), patch});
  } while (++fc != done);
  return closed;
}

std::vector<Builder::Candidate> Builder::computeCandidates() {
  const int threads = resolveThreads(ctx_.threads());
  const int chunks = threads * 8;
  std::vector<std::vector<TriKey>> found(static_cast<size_t>(chunks));
  parallelFor(
      n_, threads,
      [&](size_t b, size_t e, int chunk) {
        std::vector<uint32_t> cand;
        for (size_t i = b; i < e; ++i) {
          if ((i & 0x3FF) == 0 && ctx_.isCanceled()) return;
          for (uint32_t s = memOff_[i]; s < memOff_[i + 1]; ++s)
            star(int32_t(i), memPatch_[s], frame_[s], cand, found[size_t(chunk)]);
        }
      },
      chunks);
  ctx_.checkCancel();
  std::vector<TriKey> all;
  size_t total = 0;
  for (const auto& f : found) total += f.size();
  all.reserve(total);
  for (auto& f : found) {
    all.insert(all.end(), f.begin(), f.end());
    std::vector<TriKey>().swap(f);
  }
  std::sort(all.begin(), all.end());
  std::vector<Candidate> cands;
  for (size_t i = 0; i < all.size();) {
    size_t j = i;
    while (j < all.size() && all[j] == all[i]) ++j;
    const Triple& v = all[i].v;
    cands.push_back({all[i], int(j - i), rset_.count(all[i]) > 0,
                     shapeQuality(pos_[size_t(v[0])], pos_[size_t(v[1])], pos_[size_t(v[2])])});
    i = j;
  }
  res_.starTriangles = cands.size();
  return cands;
}

Triple Builder::orient(Triple v, uint32_t patch) const {
  const Vec3 nrm = cross(sub(pos_[size_t(v[1])], pos_[size_t(v[0])]),
                         sub(pos_[size_t(v[2])], pos_[size_t(v[0])]));
  const Vec3 ref =
      add(add(vertexNormal(v[0], patch), vertexNormal(v[1], patch)), vertexNormal(v[2], patch));
  if (dot(nrm, ref) < 0) std::swap(v[1], v[2]);
  return v;
}

/// Angular sector of triangle (u, v, w) (counter-clockwise about the frame normal) at corner u:
/// from the direction of v, `width` radians counter-clockwise. False when the triangle is flipped
/// or degenerate seen from u.
bool Builder::sector(int32_t u, int32_t v, int32_t w, const Frame& f, double& start,
                     double& width) const {
  start = angleIn(f, sub(pos_[size_t(v)], pos_[size_t(u)]));
  const double end = angleIn(f, sub(pos_[size_t(w)], pos_[size_t(u)]));
  width = wrapAngle(end - start);
  return width > 1e-6 && width < kPi - 1e-6;
}

bool Builder::canAdd(const Triple& v, uint32_t patch, bool sectors) const {
  if (byVerts_.count(sorted(v))) return false;
  const Vec3& p0 = pos_[size_t(v[0])];
  const Vec3& p1 = pos_[size_t(v[1])];
  const Vec3& p2 = pos_[size_t(v[2])];
  const double longest = std::max({norm(sub(p1, p0)), norm(sub(p2, p1)), norm(sub(p0, p2))});
  if (norm(cross(sub(p1, p0), sub(p2, p0))) <= 1e-9 * longest * longest) return false;
  for (int e = 0; e < 3; ++e) {
    const int32_t a = v[size_t(e)], b = v[size_t((e + 1) % 3)];
    auto it = edges_.find({edgeKey(a, b), patch});
    if (it == edges_.end()) continue;
    const EdgeRec& r = it->second;
    if (r.count >= (isRim(a, b, patch) ? 1 : 2)) return false;
    if (r.count == 1 && direction(tris_[size_t(r.t[0])].v, a, b) != -1) return false;
  }
  for (int c = 0; c < 3; ++c) {
    const int32_t u = v[size_t(c)];
    const int s = slotOf(u, patch);
    if (s < 0) return false;
    if (!sectors) continue;
    const Frame& f = frame_[size_t(s)];
    double a0, w0;
    if (!sector(u, v[size_t((c + 1) % 3)], v[size_t((c + 2) % 3)], f, a0, w0)) return false;
    for (int32_t t : fan_[size_t(s)]) {
      const Triple& o = tris_[size_t(t)].v;
      const int k = o[0] == u ? 0 : (o[1] == u ? 1 : 2);
      double a1, w1;
      sector(u, o[size_t((k + 1) % 3)], o[size_t((k + 2) % 3)], f, a1, w1);
      const double d = wrapAngle(a1 - a0);
      if (d < w0 - 1e-9 || d + w1 > kTwoPi + 1e-9) return false;
    }
  }
  return true;
}

int32_t Builder::addTri(const Triple& v, uint32_t patch, Source src) {
  const int32_t id = int32_t(tris_.size());
  tris_.push_back({v, patch, src, true});
  for (int e = 0; e < 3; ++e) {
    EdgeRec& r = edges_[{edgeKey(v[size_t(e)], v[size_t((e + 1) % 3)]), patch}];
    if (r.count < 2) r.t[r.count] = id;
    ++r.count;
  }
  byVerts_[sorted(v)] = id;
  for (int32_t u : v) fan_[size_t(slotOf(u, patch))].push_back(id);
  return id;
}

void Builder::removeTri(int32_t id) {
  Tri& t = tris_[size_t(id)];
  if (!t.alive) return;
  t.alive = false;
  for (int e = 0; e < 3; ++e) {
    auto it = edges_.find({edgeKey(t.v[size_t(e)], t.v[size_t((e + 1) % 3)]), t.patch});
    EdgeRec& r = it->second;
    if (r.t[0] == id) r.t[0] = r.t[1];
    r.t[1] = -1;
    if (--r.count == 0) edges_.erase(it);
  }
  byVerts_.erase(sorted(t.v));
  for (int32_t u : t.v) {
    auto& f = fan_[size_t(slotOf(u, t.patch))];
    f.erase(std::remove(f.begin(), f.end(), id), f.end());
  }
}

void Builder::select(std::vector<Candidate>& cands) {
  std::sort(cands.begin(), cands.end(), [](const Candidate& a, const Candidate& b) {
    if (a.votes != b.votes) return a.votes > b.votes;
    if (a.restricted != b.restricted) return a.restricted;
    if (a.quality != b.quality) return a.quality > b.quality;
    return a.key < b.key;
  });
  std::vector<char> taken(cands.size(), 0);
  for (size_t c = 0; c < cands.size(); ++c) {
    if (cands[c].votes < prm_.minVotes) break;
    const Triple v = orient(cands[c].key.v, cands[c].key.patch);
    if (canAdd(v, cands[c].key.patch)) {
      addTri(v, cands[c].key.patch, kStar);
      taken[c] = 1;
    } else {
      ++res_.nonManifoldRemoved;
    }
  }
  ctx_.checkCancel();
  // Closing triangles: any candidate not taken that closes at least two open edges of its patch
  // (more than it opens), until nothing changes.
  for (int round = 0; round < 6; ++round) {
    bool changed = false;
    for (size_t c = 0; c < cands.size(); ++c) {
      if (taken[c]) continue;
      const uint32_t patch = cands[c].key.patch;
      const Triple& v = cands[c].key.v;
      int closes = 0, opens = 0;
      for (int e = 0; e < 3; ++e) {
        const int32_t a = v[size_t(e)], b = v[size_t((e + 1) % 3)];
        const int use = edgeCount(a, b, patch);
        if (isRim(a, b, patch))
          closes += use == 0;
        else if (use == 1)
          ++closes;
        else if (use == 0)
          ++opens;
      }
      if (closes < 2 || closes <= opens) continue;
      const Triple o = orient(v, patch);
      if (!canAdd(o, patch)) continue;
      addTri(o, patch, cands[c].votes >= prm_.minVotes ? kStar : kSingleVote);
      taken[c] = 1;
      changed = true;
    }
    if (!changed) break;
  }
}

bool Builder::planarFill(const std::vector<int32_t>& loop, uint32_t patch,
                         std::vector<Triple>& fill) const {
  const size_t k = loop.size();
  // Plane of the loop: Newell normal, which must agree with the patch normals.
  Vec3 newell{0, 0, 0}, ref{0, 0, 0};
  for (size_t i = 0; i < k; ++i) {
    const Vec3& a = pos_[size_t(loop[i])];
    const Vec3& b = pos_[size_t(loop[(i + 1) % k])];
    newell = add(newell, {(a[1] - b[1]) * (a[2] + b[2]), (a[2] - b[2]) * (a[0] + b[0]),
                          (a[0] - b[0]) * (a[1] + b[1])});
    ref = add(ref, vertexNormal(loop[i], patch));
  }
  if (norm(newell) == 0 || dot(normalized(newell), normalized(ref)) < 0.3) return false;
  const Frame f = frameOf(normalized(newell));
  std::vector<K::Point_2> q(k);
  for (size_t i = 0; i < k; ++i) {
    const Vec3 d = sub(pos_[size_t(loop[i])], pos_[size_t(loop[0])]);
    q[i] = K::Point_2(dot(d, f.t1), dot(d, f.t2));
  }
  // Simple polygon only (a crossing would need a new vertex).
  for (size_t i = 0; i < k; ++i)
    for (size_t j = i + 1; j < k; ++j) {
      const size_t i2 = (i + 1) % k, j2 = (j + 1) % k;
      if (j == i2 || i == j2) {  // adjacent: must not fold back onto each other
        const K::Point_2& s = j == i2 ? q[j] : q[i];
        const K::Point_2& o1 = j == i2 ? q[i] : q[i2];
        const K::Point_2& o2 = j == i2 ? q[j2] : q[j];
        if (CGAL::orientation(o1, s, o2) == CGAL::COLLINEAR &&
            (o1.x() - s.x()) * (o2.x() - s.x()) + (o1.y() - s.y()) * (o2.y() - s.y()) > 0)
          return false;
        continue;
      }
      if (CGAL::do_intersect(K::Segment_2(q[i], q[i2]), K::Segment_2(q[j], q[j2]))) return false;
    }
  Cdt dt;
  std::vector<Cdt::Vertex_handle> hv(k);
  for (size_t i = 0; i < k; ++i) {
    hv[i] = dt.insert(q[i]);
    hv[i]->info().id = int32_t(i);
  }
  if (dt.number_of_vertices() != k) return false;
  for (size_t i = 0; i < k; ++i) dt.insert_constraint(hv[i], hv[(i + 1) % k]);
  if (dt.number_of_vertices() != k) return false;
  // Inside = not reachable from the infinite face without crossing the loop.
  for (auto fh = dt.all_faces_begin(); fh != dt.all_faces_end(); ++fh) fh->info() = 0;
  std::vector<Cdt::Face_handle> stack{dt.infinite_face()};
  dt.infinite_face()->info() = 1;
  while (!stack.empty()) {
    auto fh = stack.back();
    stack.pop_back();
    for (int e = 0; e < 3; ++e) {
      auto nb = fh->neighbor(e);
      if (nb->info() == 0 && !dt.is_constrained({fh, e})) {
        nb->info() = 1;
        stack.push_back(nb);
      }
    }
  }
  fill.clear();
  for (auto fh = dt.finite_faces_begin(); fh != dt.finite_faces_end(); ++fh)
    if (fh->info() == 0)
      fill.push_back({loop[size_t(fh->vertex(0)->info().id)],
                      loop[size_t(fh->vertex(1)->info().id)],
                      loop[size_t(fh->vertex(2)->info().id)]});
  return fill.size() == k - 2;
}

bool Builder::spatialFill(const std::vector<int32_t>& loop, uint32_t patch,
                          std::vector<Triple>& fill) const {
  // Minimum-weight triangulation of the 3-D polygon (largest dihedral angle, then area; CGAL),
  // each loop edge's neighbouring triangle given so the fill does not fold onto it.
  const size_t k = loop.size();
  std::vector<K::Point_3> pts, third;
  for (size_t i = 0; i < k; ++i) {
    const int32_t a = loop[i], b = loop[(i + 1) % k];
    const Vec3& p = pos_[size_t(a)];
    pts.emplace_back(p[0], p[1], p[2]);
    Vec3 apex;
    auto it = edges_.find({edgeKey(a, b), patch});
    if (it != edges_.end() && it->second.count >= 1) {
      const Triple& t = tris_[size_t(it->second.t[0])].v;
      apex = pos_[size_t(t[0] != a && t[0] != b ? t[0] : (t[1] != a && t[1] != b ? t[1] : t[2]))];
    } else {  // an unused rim link: the patch lies away from the line's third material
      const Vec3 e = sub(pos_[size_t(b)], p);
      Vec3 g{0, 0, 0};
      for (const Link& l : links_[size_t(a)])
        if (l.other == b && tripleHasPatch(l.triple, patch))
          g = add(gradientMm(thirdLabel(l.triple, patch), a),
                  gradientMm(thirdLabel(l.triple, patch), b));
      g = sub(g, scale(normalized(e), dot(g, normalized(e))));
      apex = add(add(p, scale(e, 0.5)), scale(normalized(g), 0.5 * norm(e)));
    }
    third.emplace_back(apex[0], apex[1], apex[2]);
  }
  struct Out {
    int a, b, c;
    Out(int x, int y, int z) : a(x), b(y), c(z) {}
  };
  std::vector<Out> out;
  CGAL::Polygon_mesh_processing::triangulate_hole_polyline(
      pts, third, std::back_inserter(out),
      CGAL::parameters::use_delaunay_triangulation(true).do_not_use_cubic_algorithm(k > 80));
  if (out.size() != k - 2) return false;
  fill.clear();
  for (const Out& o : out) {
    if (o.a < 0 || o.b < 0 || o.c < 0 || size_t(std::max({o.a, o.b, o.c})) >= k) return false;
    fill.push_back({loop[size_t(o.a)], loop[size_t(o.b)], loop[size_t(o.c)]});
  }
  return true;
}

bool Builder::fillLoop(const std::vector<int32_t>& loop, uint32_t patch) {
  const size_t k = loop.size();
  if (k < 3 || k > 300) return false;
  std::vector<Triple> fill;
  if (k == 3)
    fill.push_back({loop[0], loop[1], loop[2]});
  else if (!planarFill(loop, patch, fill) && !spatialFill(loop, patch, fill))
    return false;
  std::sort(fill.begin(), fill.end());
  std::vector<int32_t> added;
  for (const Triple& v : fill) {
    if (!canAdd(v, patch, false)) {
      for (int32_t t : added) removeTri(t);
      tris_.resize(tris_.size() - added.size());
      return false;
    }
    added.push_back(addTri(v, patch, kLoopFill));
  }
  return true;
}

void Builder::fillHoles() {
  // Hole edges, directed so that the hole is on their left (counter-clockwise about the normal).
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
  std::vector<HoleEdge> hole;
  for (const auto& [key, r] : edges_) {
    if (r.count != 1) continue;
    const int32_t a = int32_t(key.edge >> 32), b = int32_t(key.edge & 0xFFFFFFFFu);
    if (isRim(a, b, key.patch)) continue;
    const int d = direction(tris_[size_t(r.t[0])].v, a, b);
    hole.push_back(d > 0 ? HoleEdge{key.patch, b, a, false} : HoleEdge{key.patch, a, b, false});
  }
  // Rim links a patch does not use yet, where the patch is present at one of their ends.
  for (size_t x = 0; x < n_; ++x)
    for (const Link& l : links_[x]) {
      if (l.other < int32_t(x)) continue;
      const auto& t = triples_[l.triple];
      for (int p = 0; p < 3; ++p)
        for (int q = p + 1; q < 3; ++q) {
          auto it = patchId_.find({t[size_t(p)], t[size_t(q)]});
          if (it == patchId_.end()) continue;
          const uint32_t patch = it->second;
          if (edgeCount(int32_t(x), l.other, patch) != 0) continue;
          const int sx = slotOf(int32_t(x), patch), sy = slotOf(l.other, patch);
          if (sx < 0 || sy < 0 || (fan_[size_t(sx)].empty() && fan_[size_t(sy)].empty())) continue;
          hole.push_back({patch, int32_t(x), l.other, true});
        }
    }
  // Open edges a patch that does not use them may have to: an edge open for exactly two materials
  // a, b (the outside counted) -> patch (a,b); an edge between two junction particles sharing a
  // label triple that holds an open material -> each patch of that triple (a piece of triple line
  // the links missed). Either direction.
  {
    std::vector<std::pair<uint16_t, uint64_t>> uses;
    for (const Tri& t : tris_) {
      if (!t.alive) continue;
      for (uint16_t m : {patchPairs_[t.patch].first, patchPairs_[t.patch].second})
        for (int e = 0; e < 3; ++e)
          uses.emplace_back(m, edgeKey(t.v[size_t(e)], t.v[size_t((e + 1) % 3)]));
    }
    std::sort(uses.begin(), uses.end());
    std::map<uint64_t, std::vector<uint16_t>> odd;
    for (size_t i = 0; i < uses.size();) {
      size_t j = i;
      while (j < uses.size() && uses[j] == uses[i]) ++j;
      if ((j - i) % 2) odd[uses[i].second].push_back(uses[i].first);
      i = j;
    }
    std::vector<uint32_t> patches;
    for (const auto& [e, ms] : odd) {
      const int32_t a = int32_t(e >> 32), b = int32_t(e & 0xFFFFFFFFu);
      patches.clear();
      if (ms.size() == 2) {
        auto it = patchId_.find({std::min(ms[0], ms[1]), std::max(ms[0], ms[1])});
        if (it != patchId_.end()) patches.push_back(it->second);
      }
      if (P_[size_t(a)].junction >= 0 && P_[size_t(b)].junction >= 0) {
        const std::vector<uint32_t> ta = triplesOf(a), tb = triplesOf(b);
        for (uint32_t t : ta) {
          if (std::find(tb.begin(), tb.end(), t) == tb.end()) continue;
          const auto& lab = triples_[t];
          bool holdsOpen = false;
          for (uint16_t m : ms) holdsOpen = holdsOpen || m == lab[0] || m == lab[1] || m == lab[2];
          if (!holdsOpen) continue;
          for (int p = 0; p < 3; ++p)
            for (int q = p + 1; q < 3; ++q) {
              auto it = patchId_.find({lab[size_t(p)], lab[size_t(q)]});
              if (it != patchId_.end()) patches.push_back(it->second);
            }
        }
      }
      std::sort(patches.begin(), patches.end());
      patches.erase(std::unique(patches.begin(), patches.end()), patches.end());
      for (uint32_t patch : patches) {
        const int sa = slotOf(a, patch), sb = slotOf(b, patch);
        if (sa < 0 || sb < 0 || edgeCount(a, b, patch) != 0 || isRim(a, b, patch)) continue;
        if (fan_[size_t(sa)].empty() && fan_[size_t(sb)].empty()) continue;
        hole.push_back({patch, a, b, true});
      }
    }
  }
  std::sort(hole.begin(), hole.end());
  hole.erase(std::unique(hole.begin(), hole.end(),
                         [](const HoleEdge& a, const HoleEdge& b) {
                           return a.patch == b.patch && a.from == b.from && a.to == b.to &&
                                  a.rim == b.rim;
                         }),
             hole.end());
  for (size_t h0 = 0; h0 < hole.size();) {
    const uint32_t patch = hole[h0].patch;
    size_t h1 = h0;
    while (h1 < hole.size() && hole[h1].patch == patch) ++h1;
    // from -> (to, flag); both directions of an unused rim link share one flag.
    std::map<int32_t, std::vector<std::pair<int32_t, size_t>>> out;
    std::vector<char> usedFlag(h1 - h0, 0), undirected(h1 - h0, 0);
    for (size_t h = h0; h < h1; ++h) {
      out[hole[h].from].push_back({hole[h].to, h - h0});
      if (hole[h].rim) out[hole[h].to].push_back({hole[h].from, h - h0});
      undirected[h - h0] = hole[h].rim;
    }
    // Each loop starts on an unused directed edge and is the first simple cycle back to its start
    // found depth first, the smallest turn in the tangent plane tried first (the tightest loop);
    // dead ends are backtracked, within a step budget.
    std::vector<std::vector<int32_t>> loops;
    auto options = [&](int32_t prev, int32_t cur) {
      std::vector<std::pair<double, size_t>> opt;  // (turn, index in out[cur])
      auto it = out.find(cur);
      const int s = slotOf(cur, patch);
      if (it == out.end() || s < 0) return opt;
      const Frame& f = frame_[size_t(s)];
      const double back = angleIn(f, sub(pos_[size_t(prev)], pos_[size_t(cur)]));
      for (size_t o = 0; o < it->second.size(); ++o) {
        if (usedFlag[it->second[o].second]) continue;
        double turn =
            wrapAngle(back - angleIn(f, sub(pos_[size_t(it->second[o].first)], pos_[size_t(cur)])));
        if (turn == 0) turn = kTwoPi;
        opt.emplace_back(turn, o);
      }
      std::sort(opt.begin(), opt.end());
      return opt;
    };
    struct Step {
      int32_t v;
      std::vector<std::pair<double, size_t>> next;
      size_t k;
      size_t via;  // flag of the edge that led here
    };
    for (auto& [start, list] : out) {
      for (size_t li = 0; li < list.size(); ++li) {
        if (usedFlag[list[li].second] || undirected[list[li].second]) continue;
        usedFlag[list[li].second] = 1;
        std::vector<Step> stack;
        std::unordered_set<int32_t> onPath{start, list[li].first};
        stack.push_back({list[li].first, options(start, list[li].first), 0, list[li].second});
        bool closed = false;
        for (size_t steps = 0; !stack.empty() && steps < 20000; ++steps) {
          Step& top = stack.back();
          if (top.k >= top.next.size()) {  // dead end: back up
            if (stack.size() > 1) usedFlag[top.via] = 0;
            onPath.erase(top.v);
            stack.pop_back();
            continue;
          }
          const auto [to, flag] = out[top.v][top.next[top.k++].second];
          if (usedFlag[flag]) continue;
          if (to == start) {
            if (stack.size() < 2) continue;
            usedFlag[flag] = 1;
            closed = true;
            break;
          }
          if (onPath.count(to) || stack.size() >= 300) continue;
          usedFlag[flag] = 1;
          onPath.insert(to);
          const int32_t from = top.v;
          stack.push_back({to, options(from, to), 0, flag});
        }
        if (closed) {
          std::vector<int32_t> loop{start};
          for (const Step& st : stack) loop.push_back(st.v);
          loops.push_back(std::move(loop));
        } else {
          for (size_t k = 1; k < stack.size(); ++k) usedFlag[stack[k].via] = 0;
        }
      }
    }
    res_.holeLoops += loops.size();
    for (const auto& loop : loops)
      if (fillLoop(loop, patch)) ++res_.holesFilled;
    h0 = h1;
  }
}

void Builder::collect(std::vector<Triple>& tris,
                      std::vector<std::pair<uint16_t, uint16_t>>& pairs) const {
  tris.clear();
  pairs.clear();
  for (const Tri& t : tris_) {
    if (!t.alive) continue;
    tris.push_back(t.v);
    pairs.push_back(patchPairs_[t.patch]);
  }
}

void Builder::restrictedClosure() {
  // Entries: every alive local triangle and every restricted one, keyed by vertices and patch.
  struct Entry {
    Triple v;  // oriented
    uint32_t patch;
    bool inL = false, inR = false;
    Source source = kRestricted;
  };
  std::vector<Entry> entries;
  std::unordered_map<TriKey, int32_t, TriKeyHash> index;
  for (const Tri& t : tris_) {
    if (!t.alive) continue;
    index.emplace(TriKey{sorted(t.v), t.patch}, int32_t(entries.size()));
    entries.push_back({t.v, t.patch, true, false, t.source});
  }
  for (const RTri& r : rtris_) {
    auto [it, fresh] = index.emplace(TriKey{sorted(r.v), r.patch}, int32_t(entries.size()));
    if (fresh)
      entries.push_back({r.v, r.patch, false, true, kRestricted});
    else
      entries[size_t(it->second)].inR = true;
  }
  const size_t m = entries.size();
  auto differs = [&](size_t e) { return entries[e].inL != entries[e].inR; };
  // Pair, at every edge, a local and a restricted triangle on the same side of the same patch;
  // everything else at the edge is grouped.
  struct Inc {
    uint64_t edge;
    uint32_t patch;
    int side;
    int32_t entry;
    bool operator<(const Inc& o) const {
      if (edge != o.edge) return edge < o.edge;
      if (patch != o.patch) return patch < o.patch;
      if (side != o.side) return side < o.side;
      return entry < o.entry;
    }
  };
  std::vector<Inc> inc;
  for (size_t e = 0; e < m; ++e) {
    if (!differs(e)) continue;
    const Triple& v = entries[e].v;
    for (int k = 0; k < 3; ++k) {
      const int32_t a = v[size_t(k)], b = v[size_t((k + 1) % 3)];
      inc.push_back({edgeKey(a, b), entries[e].patch, a < b ? 1 : -1, int32_t(e)});
    }
  }
  std::sort(inc.begin(), inc.end());
  UnionFind uf(m);
  std::unordered_map<uint64_t, int32_t> leftover;  // edge -> an entry of its leftover group
  for (size_t i = 0; i < inc.size();) {
    size_t j = i;
    while (j < inc.size() && inc[j].edge == inc[i].edge) ++j;
    int32_t rest = -1;
    for (size_t s = i; s < j;) {
      size_t t = s;
      while (t < j && inc[t].patch == inc[s].patch && inc[t].side == inc[s].side) ++t;
      int nl = 0, nr = 0;
      for (size_t x = s; x < t; ++x) (entries[size_t(inc[x].entry)].inL ? nl : nr)++;
      if (nl == 1 && nr == 1) {
        uf.unite(inc[s].entry, inc[s + 1].entry);
      } else {
        for (size_t x = s; x < t; ++x) {
          if (rest >= 0)
            uf.unite(rest, inc[x].entry);
          else
            rest = inc[x].entry;
        }
      }
      s = t;
    }
    if (rest >= 0) leftover[inc[i].edge] = rest;
    i = j;
  }
  std::vector<char> swapped(m, 0), needed(m, 0);
  auto currentSet = [&](std::vector<Triple>& tris,
                        std::vector<std::pair<uint16_t, uint16_t>>& pairs,
                        std::vector<int32_t>& which) {
    tris.clear();
    pairs.clear();
    which.clear();
    for (size_t e = 0; e < m; ++e) {
      const Entry& en = entries[e];
      const bool on = en.inL && en.inR ? true
                                       : (en.inL ? !swapped[size_t(uf.find(int32_t(e)))]
                                                 : swapped[size_t(uf.find(int32_t(e)))] != 0);
      if (!on) continue;
      tris.push_back(en.v);
      pairs.push_back(patchPairs_[en.patch]);
      which.push_back(int32_t(e));
    }
  };
  std::vector<Triple> tris;
  std::vector<std::pair<uint16_t, uint16_t>> pairs;
  std::vector<int32_t> which;
  currentSet(tris, pairs, which);
  // Open edges: swap the component of the leftover group at each.
  for (const auto& [mat, edge] : oddEdges(tris, pairs)) {
    auto it = leftover.find(edge);
    if (it != leftover.end()) needed[size_t(uf.find(it->second))] = 1;
  }
  // Self-intersections: kept triangles that are not restricted facets (those cannot cross each
  // other) against all; a vertex triple in two patches counts as one. The first test is on the
  // local surface alone; then swap, retest, until nothing new has to be swapped.
  for (int round = 0; round < 50; ++round) {
    ctx_.checkCancel();
    std::vector<char> suspect(tris.size(), 0);
    for (size_t t = 0; t < tris.size(); ++t) suspect[t] = !entries[size_t(which[t])].inR;
    const auto pairsX = intersectingPairs(tris, suspect, pos_);
    if (round == 0) res_.selfIntersections = pairsX.size();
    res_.selfIntersectionsAfter = pairsX.size();
    for (const auto& [x, y] : pairsX)
      for (int32_t t : {x, y}) {
        const size_t e = size_t(which[size_t(t)]);
        if (differs(e)) needed[size_t(uf.find(int32_t(e)))] = 1;
      }
    bool any = false;
    for (size_t r = 0; r < m; ++r)
      if (needed[r] && !swapped[r]) {
        swapped[r] = 1;
        any = true;
      }
    if (!any) break;
    currentSet(tris, pairs, which);
  }
  // Write the result back into the builder's triangle list (provenance kept).
  std::vector<Tri> out;
  for (size_t e = 0; e < m; ++e) {
    const Entry& en = entries[e];
    const bool sw = swapped[size_t(uf.find(int32_t(e)))] != 0;
    if (en.inL && (en.inR || !sw))
      out.push_back({en.v, en.patch, en.source, true});
    else if (!en.inL && sw)
      out.push_back({en.v, en.patch, kRestricted, true});
    if (en.inL && !en.inR && sw) ++res_.replacedTriangles;
  }
  for (size_t r = 0; r < m; ++r)
    if (swapped[r] && uf.find(int32_t(r)) == int32_t(r)) ++res_.restrictedComponents;
  tris_ = std::move(out);
}

void Builder::run() {
  pos_.resize(n_);
  for (size_t i = 0; i < n_; ++i) pos_[i] = vol_.localToCanonical(P_[i].local);
  rdt_.delaunay->adjacency(n_, off_, adj_);
  buildPatches();
  mapRestricted();
  buildLines();
  ctx_.progress(0.1);
  std::vector<Candidate> cands = computeCandidates();
  ctx_.progress(0.5);
  edges_.reserve(cands.size() * 2);
  byVerts_.reserve(cands.size());
  select(cands);
  std::vector<Candidate>().swap(cands);
  std::vector<Triple> tris;
  std::vector<std::pair<uint16_t, uint16_t>> pairs;
  collect(tris, pairs);
  res_.openEdgesBefore = oddEdges(tris, pairs).size();
  res_.openEdgesAfterFill = res_.openEdgesBefore;
  ctx_.progress(0.6);
  if (prm_.fillLoops && res_.openEdgesBefore > 0) {
    fillHoles();
    collect(tris, pairs);
    res_.openEdgesAfterFill = oddEdges(tris, pairs).size();
  }
  ctx_.progress(0.7);
  if (prm_.restrictedClosure) restrictedClosure();
  ctx_.progress(0.95);
  // Deterministic output order: by patch, then by vertices.
  std::vector<size_t> order;
  for (size_t t = 0; t < tris_.size(); ++t)
    if (tris_[t].alive) order.push_back(t);
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    const auto &pa = patchPairs_[tris_[a].patch], &pb = patchPairs_[tris_[b].patch];
    if (pa != pb) return pa < pb;
    return sorted(tris_[a].v) < sorted(tris_[b].v);
  });
  for (size_t t : order) {
    res_.triangles.push_back(tris_[t].v);
    res_.trianglePairs.push_back(patchPairs_[tris_[t].patch]);
    switch (tris_[t].source) {
      case kStar:
        ++res_.fromStars;
        break;
      case kSingleVote:
        ++res_.fromSingleVote;
        break;
      case kLoopFill:
        ++res_.fromLoopFill;
        break;
      case kRestricted:
        ++res_.fromRestricted;
        break;
    }
  }
  res_.openEdgesAfter = oddEdges(res_.triangles, res_.trianglePairs).size();
  if (!prm_.restrictedClosure) {
    std::vector<char> all(res_.triangles.size(), 1);
    res_.selfIntersectionsAfter = intersectingPairs(res_.triangles, all, pos_).size();
  }
  ctx_.progress(1.0);
}

}  // namespace

size_t countOpenEdges(const std::vector<std::array<int32_t, 3>>& triangles,
                      const std::vector<std::pair<uint16_t, uint16_t>>& pairs) {
  return oddEdges(triangles, pairs).size();
}

size_t countSelfIntersections(const std::vector<Vec3>& points,
                              const std::vector<std::array<int32_t, 3>>& triangles) {
  std::vector<char> all(triangles.size(), 1);
  return intersectingPairs(triangles, all, points).size();
}

LocalDelaunayResult buildLocalDelaunaySurface(const IndicatorField& field,
                                              const std::vector<Particle>& particles,
                                              const Junctions& junctions,
                                              const BoundarySurface& restricted, RunContext& ctx,
                                              const LocalDelaunayParameters& params) {
  LocalDelaunayResult res;
  if (!restricted.delaunay) return res;
  Builder(field, particles, junctions, restricted, ctx, params, res).run();
  return res;
}

}  // namespace femesher
