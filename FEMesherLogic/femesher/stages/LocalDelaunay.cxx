// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/stages/LocalDelaunay.h>

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Constrained_triangulation_face_base_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <unordered_map>

namespace femesher {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb2 = CGAL::Triangulation_vertex_base_with_info_2<int32_t, K>;
using Fb2 = CGAL::Constrained_triangulation_face_base_2<K>;
using Tds2 = CGAL::Triangulation_data_structure_2<Vb2, Fb2>;
using Delaunay2 = CGAL::Constrained_Delaunay_triangulation_2<K, Tds2, CGAL::Exact_predicates_tag>;

double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

uint64_t edgeKey(int32_t a, int32_t b) {
  if (a > b) std::swap(a, b);
  return (uint64_t(uint32_t(a)) << 32) | uint32_t(b);
}

struct TriKey {
  std::array<int32_t, 3> v;
  uint32_t patch;
  bool operator==(const TriKey& o) const { return v == o.v && patch == o.patch; }
};
struct TriKeyHash {
  size_t operator()(const TriKey& k) const {
    uint64_t h = k.patch * 0x9E3779B97F4A7C15ull;
    for (int x : k.v) h = (h ^ uint64_t(uint32_t(x))) * 0x100000001B3ull;
    return size_t(h);
  }
};

/// Ear clipping of a closed loop (indices into pos) projected on the plane of normal n.
bool earClip(std::vector<int32_t> loop, const std::vector<Vec3>& pos, const Vec3& n,
             std::vector<std::array<int32_t, 3>>& out) {
  Vec3 t1 = std::fabs(n[0]) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
  const double d = dot(t1, n);
  for (int a = 0; a < 3; ++a) t1[a] -= d * n[a];
  const double l = std::sqrt(dot(t1, t1));
  for (auto& x : t1) x /= l;
  const Vec3 t2 = cross(n, t1);
  auto p2 = [&](int32_t i) { return std::array<double, 2>{dot(pos[i], t1), dot(pos[i], t2)}; };
  auto area2 = [&](int32_t a, int32_t b, int32_t c) {
    const auto A = p2(a), B = p2(b), C = p2(c);
    return (B[0] - A[0]) * (C[1] - A[1]) - (B[1] - A[1]) * (C[0] - A[0]);
  };
  double total = 0;
  for (size_t i = 0; i < loop.size(); ++i) total += area2(loop[0], loop[i], loop[(i + 1) % loop.size()]);
  if (total < 0) std::reverse(loop.begin(), loop.end());
  size_t guard = 0;
  while (loop.size() > 3 && guard++ < 10000) {
    bool clipped = false;
    for (size_t i = 0; i < loop.size(); ++i) {
      const int32_t a = loop[(i + loop.size() - 1) % loop.size()], b = loop[i],
                    c = loop[(i + 1) % loop.size()];
      if (area2(a, b, c) <= 0) continue;
      bool inside = false;
      for (int32_t q : loop) {
        if (q == a || q == b || q == c) continue;
        if (area2(a, b, q) > 0 && area2(b, c, q) > 0 && area2(c, a, q) > 0) {
          inside = true;
          break;
        }
      }
      if (inside) continue;
      out.push_back({a, b, c});
      loop.erase(loop.begin() + long(i));
      clipped = true;
      break;
    }
    if (!clipped) return false;
  }
  if (loop.size() == 3) out.push_back({loop[0], loop[1], loop[2]});
  return true;
}

}  // namespace

size_t countOpenEdges(const std::vector<std::array<int32_t, 3>>& triangles,
                      const std::vector<std::pair<uint16_t, uint16_t>>& pairs) {
  std::unordered_map<uint64_t, int> count;  // key: material << 48 | edge (hashed)
  std::map<std::pair<uint16_t, uint64_t>, int> perMaterial;
  for (size_t t = 0; t < triangles.size(); ++t)
    for (uint16_t m : {pairs[t].first, pairs[t].second}) {
      if (m == 0) continue;
      for (int e = 0; e < 3; ++e)
        ++perMaterial[{m, edgeKey(triangles[t][e], triangles[t][(e + 1) % 3])}];
    }
  size_t open = 0;
  for (const auto& kv : perMaterial) open += kv.second % 2;
  return open;
}

LocalDelaunayResult buildLocalDelaunaySurface(const IndicatorField& field,
                                              const std::vector<Particle>& P,
                                              const Junctions& junctions,
                                              const LabelledDelaunay& delaunay, RunContext& ctx) {
  const PreprocessedVolume& vol = field.volume();
  const size_t n = P.size();
  std::vector<Vec3> pos(n);
  for (size_t i = 0; i < n; ++i) pos[i] = vol.localToCanonical(P[i].local);
  std::vector<uint32_t> off, adj;
  delaunay.adjacency(n, off, adj);
  ctx.progress(0.1);

  // Patches and their members.
  std::map<std::pair<uint16_t, uint16_t>, uint32_t> patchId;
  std::vector<std::pair<uint16_t, uint16_t>> patchPairs;
  std::vector<std::vector<uint32_t>> membersOf;  // per particle: patches it belongs to
  membersOf.resize(n);
  auto patchOf = [&](uint16_t a, uint16_t b) {
    auto it = patchId.find({a, b});
    if (it != patchId.end()) return it->second;
    const uint32_t id = uint32_t(patchPairs.size());
    patchId[{a, b}] = id;
    patchPairs.emplace_back(a, b);
    return id;
  };
  for (size_t i = 0; i < n; ++i) {
    if (P[i].junction < 0) {
      membersOf[i].push_back(patchOf(P[i].a, P[i].b));
      continue;
    }
    const JunctionPoint& j = junctions.particles[size_t(P[i].junction)];
    for (int x = 0; x < j.count; ++x)
      for (int y = x + 1; y < j.count; ++y) membersOf[i].push_back(patchOf(j.labels[x], j.labels[y]));
  }
  auto member = [&](uint32_t i, uint32_t patch) {
    const auto& m = membersOf[i];
    return std::find(m.begin(), m.end(), patch) != m.end();
  };
  auto normalOf = [&](uint32_t i, uint32_t patch) {
    const auto [a, b] = patchPairs[patch];
    const Vec3 ga = field.gradient(a, P[i].local), gb = field.gradient(b, P[i].local);
    Vec3 g{(ga[0] - gb[0]) / vol.spacing[0], (ga[1] - gb[1]) / vol.spacing[1],
           (ga[2] - gb[2]) / vol.spacing[2]};
    const double l = std::sqrt(dot(g, g));
    if (l > 0)
      for (auto& x : g) x /= l;
    return g;
  };

  // Triple-line edges: each line particle is joined to its nearest neighbour ahead and behind
  // along the line (particles of the same triple, or quadruple points holding it). These edges
  // are constraints of every star, so all patches meeting at a line share its edges.
  std::vector<std::vector<uint32_t>> lineNb(n);
  {
    std::vector<uint32_t> jIdx;
    for (size_t i = 0; i < n; ++i)
      if (P[i].junction >= 0) jIdx.push_back(uint32_t(i));
    double hMax = 0;
    for (uint32_t i : jIdx)
      for (uint32_t k = off[i]; k < off[i + 1]; ++k) {
        const Vec3 d = sub(pos[adj[k]], pos[i]);
        hMax = std::max(hMax, std::sqrt(dot(d, d)));
      }
    for (uint32_t i : jIdx) {
      const JunctionPoint& ji = junctions.particles[size_t(P[i].junction)];
      if (ji.count != 3) continue;
      const uint16_t* l = ji.labels.data();
      const Vec3 g1 = [&] {
        const Vec3 a = field.gradient(l[0], P[i].local), b = field.gradient(l[1], P[i].local);
        return Vec3{(a[0] - b[0]) / vol.spacing[0], (a[1] - b[1]) / vol.spacing[1], (a[2] - b[2]) / vol.spacing[2]};
      }();
      const Vec3 g2 = [&] {
        const Vec3 a = field.gradient(l[0], P[i].local), b = field.gradient(l[2], P[i].local);
        return Vec3{(a[0] - b[0]) / vol.spacing[0], (a[1] - b[1]) / vol.spacing[1], (a[2] - b[2]) / vol.spacing[2]};
      }();
      const Vec3 t = cross(g1, g2);
      double ahead = 1e300, behind = 1e300;
      int32_t ja = -1, jb = -1;
      // Candidates: Delaunay 2-ring (the next line particle is at most two edges away).
      auto consider = [&](uint32_t q) {
        if (q == i || P[q].junction < 0) return;
        const JunctionPoint& jq = junctions.particles[size_t(P[q].junction)];
        if (!(jq.contains(l[0], l[1]) && jq.contains(l[0], l[2]))) return;
        const Vec3 d = sub(pos[q], pos[i]);
        const double r = std::sqrt(dot(d, d));
        if (dot(d, t) > 0 ? r < ahead : r < behind) {
          if (dot(d, t) > 0) { ahead = r; ja = int32_t(q); }
          else { behind = r; jb = int32_t(q); }
        }
      };
      for (uint32_t k = off[i]; k < off[i + 1]; ++k) {
        consider(adj[k]);
        for (uint32_t k2 = off[adj[k]]; k2 < off[adj[k] + 1]; ++k2) consider(adj[k2]);
      }
      for (int32_t q : {ja, jb})
        if (q >= 0) {
          lineNb[i].push_back(uint32_t(q));
          lineNb[size_t(q)].push_back(i);
        }
    }
    for (auto& v : lineNb) {
      std::sort(v.begin(), v.end());
      v.erase(std::unique(v.begin(), v.end()), v.end());
    }
    (void)hMax;
  }

  // A triangle whose three corners all lie on one triple line of this patch spans the outside of
  // the patch (the sheet ends at the line): never part of the surface.
  auto alongOneLine = [&](int32_t u, int32_t v, int32_t w, uint32_t patch) {
    if (P[size_t(u)].junction < 0 || P[size_t(v)].junction < 0 || P[size_t(w)].junction < 0)
      return false;
    const auto [pa, pb] = patchPairs[patch];
    const JunctionPoint& ju = junctions.particles[size_t(P[size_t(u)].junction)];
    const JunctionPoint& jv = junctions.particles[size_t(P[size_t(v)].junction)];
    const JunctionPoint& jw = junctions.particles[size_t(P[size_t(w)].junction)];
    for (int k = 0; k < ju.count; ++k) {
      const uint16_t c = ju.labels[k];
      if (c == pa || c == pb) continue;
      if (jv.contains(pa, c) && jv.contains(pb, c) && jw.contains(pa, c) && jw.contains(pb, c))
        return true;
    }
    return false;
  };

  // Stars, in parallel over particles; votes merged per chunk.
  const int threads = resolveThreads(ctx.threads());
  const int chunks = threads * 4;
  std::vector<std::vector<std::pair<TriKey, Vec3>>> found(static_cast<size_t>(chunks));
  parallelFor(n, threads, [&](size_t b, size_t e, int chunk) {
    std::vector<uint32_t> cand;
    for (size_t i = b; i < e; ++i) {
      if ((i & 0x3FF) == 0 && ctx.isCanceled()) return;
      for (uint32_t patch : membersOf[i]) {
        const Vec3 np = normalOf(uint32_t(i), patch);
        cand.clear();
        for (uint32_t k = off[i]; k < off[i + 1]; ++k) {
          const uint32_t q = adj[k];
          if (member(q, patch)) cand.push_back(q);
          for (uint32_t k2 = off[q]; k2 < off[q + 1]; ++k2)
            if (adj[k2] != i && member(adj[k2], patch)) cand.push_back(adj[k2]);
        }
        std::sort(cand.begin(), cand.end());
        cand.erase(std::unique(cand.begin(), cand.end()), cand.end());
        Vec3 t1 = std::fabs(np[0]) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
        const double d = dot(t1, np);
        for (int a = 0; a < 3; ++a) t1[a] -= d * np[a];
        const double l = std::sqrt(dot(t1, t1));
        if (l == 0) continue;
        for (auto& x : t1) x /= l;
        const Vec3 t2 = cross(np, t1);
        std::vector<std::pair<K::Point_2, int32_t>> pts;
        pts.emplace_back(K::Point_2(0, 0), int32_t(i));
        for (uint32_t q : cand) {
          if (dot(normalOf(q, patch), np) < 0.3) continue;
          const Vec3 dq = sub(pos[q], pos[i]);
          pts.emplace_back(K::Point_2(dot(dq, t1), dot(dq, t2)), int32_t(q));
        }
        if (pts.size() < 3) continue;
        Delaunay2 dt;
        std::unordered_map<int32_t, Delaunay2::Vertex_handle> handle;
        for (const auto& [pt, id] : pts) {
          auto v = dt.insert(pt);
          v->info() = id;
          handle[id] = v;
        }
        const auto [pa, pb] = patchPairs[patch];
        for (const auto& [pt, id] : pts)
          for (uint32_t q : lineNb[size_t(id)]) {
            if (int32_t(q) < id) continue;
            auto it = handle.find(int32_t(q));
            if (it == handle.end()) continue;
            const JunctionPoint& jq = junctions.particles[size_t(P[q].junction)];
            if (!jq.contains(pa, pb)) continue;
            if (handle[id] != it->second) dt.insert_constraint(handle[id], it->second);
          }
        auto hp = handle.find(int32_t(i));
        if (hp == handle.end()) continue;
        Delaunay2::Vertex_handle vp = hp->second;
        auto fc = dt.incident_faces(vp), done = fc;
        if (fc == nullptr) continue;
        do {
          if (!dt.is_infinite(fc) && !alongOneLine(fc->vertex(0)->info(), fc->vertex(1)->info(),
                                                    fc->vertex(2)->info(), patch)) {
            TriKey key{{fc->vertex(0)->info(), fc->vertex(1)->info(), fc->vertex(2)->info()}, patch};
            std::sort(key.v.begin(), key.v.end());
            found[size_t(chunk)].emplace_back(key, np);
          }
        } while (++fc != done);
      }
    }
  }, chunks);
  ctx.checkCancel();
  ctx.progress(0.5);

  struct Vote {
    int count = 0;
    Vec3 normal{0, 0, 0};
  };
  std::unordered_map<TriKey, Vote, TriKeyHash> votes;
  for (const auto& f : found)
    for (const auto& [key, nrm] : f) {
      Vote& v = votes[key];
      ++v.count;
      for (int a = 0; a < 3; ++a) v.normal[a] += nrm[a];
    }
  found.clear();

  // Accepted triangles (>= 2 votes), deterministic order; 1-vote triangles are kept aside.
  struct Tri {
    TriKey key;
    int votes;
    Vec3 normal;
  };
  std::vector<Tri> tris, pool;
  for (const auto& [key, v] : votes) (v.count >= 2 ? tris : pool).push_back({key, v.count, v.normal});
  auto byVotes = [](const Tri& a, const Tri& b) {
    if (a.votes != b.votes) return a.votes > b.votes;
    if (a.key.patch != b.key.patch) return a.key.patch < b.key.patch;
    return a.key.v < b.key.v;
  };
  std::sort(tris.begin(), tris.end(), byVotes);
  std::sort(pool.begin(), pool.end(), byVotes);
  LocalDelaunayResult res;
  // Manifold per patch: at most two triangles per edge, most-voted first.
  std::unordered_map<uint64_t, int> edgeUse;  // key mixes patch and edge
  auto patchEdge = [](int32_t a, int32_t b, uint32_t patch) {
    return edgeKey(a, b) * 1000003ull + patch;
  };
  auto isRim = [&](int32_t a, int32_t b) {
    return P[size_t(a)].junction >= 0 && P[size_t(b)].junction >= 0;
  };
  std::vector<Tri> kept;
  auto tryAdd = [&](const Tri& t) {
    uint64_t keys[3];
    for (int e = 0; e < 3; ++e) {
      keys[e] = patchEdge(t.key.v[e], t.key.v[(e + 1) % 3], t.key.patch);
      if (edgeUse[keys[e]] >= 2) return false;
    }
    for (uint64_t k : keys) ++edgeUse[k];
    kept.push_back(t);
    return true;
  };
  for (const Tri& t : tris)
    if (!tryAdd(t)) ++res.nonManifoldRemoved;
  // Resolve disagreements: a triangle seen by one star only is added when it closes an open
  // (non-rim) edge of its patch without breaking manifoldness and opens no new non-rim edge
  // that was closed... repeated until nothing changes.
  for (int round = 0; round < 4; ++round) {
    bool changed = false;
    for (Tri& t : pool) {
      if (t.votes < 0) continue;  // already used
      int closes = 0, opens = 0;
      bool blocked = false;
      for (int e = 0; e < 3; ++e) {
        const int32_t a = t.key.v[e], b = t.key.v[(e + 1) % 3];
        const int use = edgeUse[patchEdge(a, b, t.key.patch)];
        if (use >= 2) blocked = true;
        else if (use == 1) ++closes;
        else if (!isRim(a, b)) ++opens;
      }
      if (blocked || closes < 2 || closes <= opens) continue;
      if (tryAdd(t)) {
        t.votes = -1;
        changed = true;
      }
    }
    if (!changed) break;
  }
  auto emit = [&](const std::array<int32_t, 3>& v, uint32_t patch, const Vec3& normal) {
    std::array<int32_t, 3> tri = v;
    const Vec3 nn = cross(sub(pos[tri[1]], pos[tri[0]]), sub(pos[tri[2]], pos[tri[0]]));
    if (dot(nn, normal) < 0) std::swap(tri[1], tri[2]);
    res.triangles.push_back(tri);
    res.trianglePairs.push_back(patchPairs[patch]);
  };
  for (const Tri& t : kept) emit(t.key.v, t.key.patch, t.normal);
  res.openEdgesBefore = countOpenEdges(res.triangles, res.trianglePairs);
  ctx.progress(0.8);

  // Hole filling per patch: loops of edges used once by the patch, except rims (edges whose two
  // ends are junction particles: the patch legitimately ends there).
  std::map<uint32_t, std::map<uint64_t, std::pair<int32_t, int32_t>>> boundary;
  std::map<uint32_t, Vec3> patchNormalSum;
  for (size_t t = 0; t < res.triangles.size(); ++t) {
    const uint32_t patch = patchId[res.trianglePairs[t]];
    for (int e = 0; e < 3; ++e) {
      const int32_t a = res.triangles[t][e], b = res.triangles[t][(e + 1) % 3];
      auto& bd = boundary[patch];
      const uint64_t k = edgeKey(a, b);
      auto it = bd.find(k);
      if (it == bd.end()) bd[k] = {a, b};
      else bd.erase(it);
    }
  }
  for (auto& [patch, edges] : boundary) {
    std::unordered_map<int32_t, std::vector<int32_t>> next;
    for (const auto& [k, e] : edges) {
      if (P[size_t(e.first)].junction >= 0 && P[size_t(e.second)].junction >= 0) continue;  // rim
      next[e.second].push_back(e.first);  // walk against the triangle orientation
    }
    std::unordered_map<int32_t, bool> used;
    for (const auto& [start, unused] : next) {
      if (used[start]) continue;
      std::vector<int32_t> loop{start};
      int32_t cur = start;
      bool closed = false;
      for (size_t guard = 0; guard < 64; ++guard) {
        used[cur] = true;
        auto it = next.find(cur);
        if (it == next.end() || it->second.empty()) break;
        const int32_t nx = it->second.front();
        if (nx == start) {
          closed = true;
          break;
        }
        if (used[nx]) break;
        loop.push_back(nx);
        cur = nx;
      }
      if (!closed || loop.size() < 3) continue;
      Vec3 nrm{0, 0, 0};
      for (int32_t v : loop) {
        const Vec3 nv = normalOf(uint32_t(v), patch);
        for (int a = 0; a < 3; ++a) nrm[a] += nv[a];
      }
      const double l = std::sqrt(dot(nrm, nrm));
      if (l == 0) continue;
      for (auto& x : nrm) x /= l;
      std::vector<std::array<int32_t, 3>> fill;
      if (earClip(loop, pos, nrm, fill)) {
        for (const auto& f : fill) emit(f, patch, nrm);
        ++res.holesFilled;
      }
    }
  }
  res.openEdgesAfter = countOpenEdges(res.triangles, res.trianglePairs);
  ctx.progress(1.0);
  return res;
}

}  // namespace femesher
