// SPDX-License-Identifier: GPL-3.0-or-later
// Optimize stage: collapse of a bad tet's edge (short, or checked against the facet distance)
// and interior coarsening (see collapseEdge and coarsenInterior in OptimizeEditor.h).
#include <femesher/Parallel.h>
#include <femesher/VecMath.h>
#include <femesher/stages/internal/OptimizeEditor.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

namespace femesher {
namespace optimize_detail {

namespace {

/// The link of vertex x, or of edge (x, y) when y >= 0, in the sub-complex of the tets of one
/// label (all tets with label -1), closed by a ghost vertex joined to every face of it that no
/// other tet of the sub-complex shares (outer boundary, or interface for one material): its
/// vertices, edges and triangles, each sorted.
struct Link {
  std::vector<int32_t> vertices;
  std::vector<std::array<int32_t, 2>> edges;
  std::vector<std::array<int32_t, 3>> triangles;
};

constexpr int32_t kGhost = std::numeric_limits<int32_t>::max();

Link linkOf(const Editor& m, int32_t x, int32_t y, int32_t label) {
  Link L;
  auto addEdge = [&](int32_t a, int32_t b) { L.edges.push_back({std::min(a, b), std::max(a, b)}); };
  auto inSub = [&](int64_t s) { return s >= 0 && (label < 0 || m.labels[size_t(s)] == label); };
  for (uint32_t t : m.around[size_t(x)]) {
    if (!inSub(t) || (y >= 0 && !m.has(t, y))) continue;
    std::array<int32_t, 3> rest{};
    int n = 0;
    for (int32_t v : m.tets[t])
      if (v != x && v != y) rest[size_t(n++)] = v;
    for (int i = 0; i < n; ++i) L.vertices.push_back(rest[size_t(i)]);
    if (n == 3) {
      std::array<int32_t, 3> tri = rest;
      std::sort(tri.begin(), tri.end());
      L.triangles.push_back(tri);
      addEdge(rest[0], rest[1]);
      addEdge(rest[0], rest[2]);
      addEdge(rest[1], rest[2]);
    } else {
      addEdge(rest[0], rest[1]);
    }
    // Faces of t holding x (and y) without another tet of the sub-complex: the ghost's cone.
    for (int k = 0; k < 4; ++k) {
      const int32_t opposite = m.tets[t][size_t(k)];
      if (opposite == x || opposite == y) continue;
      const auto f = m.face(t, k);
      if (inSub(m.across(t, f[0], f[1], f[2]))) continue;
      std::array<int32_t, 2> others{};
      int c = 0;
      for (int32_t v : f)
        if (v != x && v != y) others[size_t(c++)] = v;
      L.vertices.push_back(kGhost);
      if (c == 2) {
        std::array<int32_t, 3> tri{others[0], others[1], kGhost};
        std::sort(tri.begin(), tri.end());
        L.triangles.push_back(tri);
        addEdge(others[0], kGhost);
        addEdge(others[1], kGhost);
      } else {
        addEdge(others[0], kGhost);
      }
    }
  }
  auto uniq = [](auto& v) {
    std::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end()), v.end());
  };
  uniq(L.vertices);
  uniq(L.edges);
  uniq(L.triangles);
  return L;
}

/// The link condition for collapsing edge (u, v): Lk(u) ∩ Lk(v) = Lk(uv), in the sub-complex of
/// one label (or all with label -1). When it holds the collapse keeps the complex a manifold of
/// the same topology.
bool linkCondition(const Editor& m, int32_t u, int32_t v, int32_t label) {
  const Link a = linkOf(m, u, -1, label), b = linkOf(m, v, -1, label), e = linkOf(m, u, v, label);
  auto same = [](const auto& x, const auto& y, const auto& want) {
    std::remove_const_t<std::remove_reference_t<decltype(want)>> both;
    std::set_intersection(x.begin(), x.end(), y.begin(), y.end(), std::back_inserter(both));
    return both == want;
  };
  return same(a.vertices, b.vertices, e.vertices) && same(a.edges, b.edges, e.edges) &&
         same(a.triangles, b.triangles, e.triangles);
}

}  // namespace

bool collapseEdge(Editor& m, uint32_t t, double maxLength, const OptimizeInterfaces& in,
                  bool checkFacets, std::vector<uint32_t>& fresh) {
  const auto T = m.tets[t];
  std::vector<std::pair<double, std::pair<int, int>>> edges;  // shortest first
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) {
      const double len = norm(sub(m.pts[size_t(T[size_t(j)])], m.pts[size_t(T[size_t(i)])]));
      if (len < maxLength) edges.push_back({len, {i, j}});
    }
  std::sort(edges.begin(), edges.end());
  // Without the facet check only the shortest edge is tried (the interfaces move by less than
  // maxLength, the facet distance).
  if (!(checkFacets && in.enabled()) && edges.size() > 1) edges.resize(1);
  auto materialsAndOuter = [&](const std::vector<uint32_t>& tets, int32_t x, int32_t y,
                               std::vector<int32_t>& mats) {
    bool outer = false;
    mats.clear();
    for (uint32_t s : tets) {
      mats.push_back(m.labels[s]);
      for (int k = 0; k < 4; ++k) {
        const int32_t opposite = m.tets[s][size_t(k)];
        if (opposite == x || opposite == y) continue;
        const auto f = m.face(s, k);
        if (m.across(s, f[0], f[1], f[2]) < 0) outer = true;
      }
    }
    std::sort(mats.begin(), mats.end());
    mats.erase(std::unique(mats.begin(), mats.end()), mats.end());
    return outer;
  };
  std::vector<uint32_t> ring;
  std::vector<int32_t> edgeMats, goneMats;
  for (int e = 0; e < 2 * int(edges.size()); ++e) {
    const int bi = edges[size_t(e / 2)].second.first, bj = edges[size_t(e / 2)].second.second;
    const int attempt = e % 2;
    const int32_t keep = T[size_t(attempt == 0 ? bi : bj)],
                  gone = T[size_t(attempt == 0 ? bj : bi)];
    m.tetsOnEdge(keep, gone, ring);
    const bool edgeOuter = materialsAndOuter(ring, keep, gone, edgeMats);
    const bool goneOuter = materialsAndOuter(m.around[size_t(gone)], gone, -1, goneMats);
    if (edgeMats != goneMats || (goneOuter && !edgeOuter)) continue;
    // A vertex on the volume's box keeps every box plane it is on: the box stays exact.
    const int goneBox = in.boxPlanes(m.pts[size_t(gone)]);
    if ((goneBox & in.boxPlanes(m.pts[size_t(keep)])) != goneBox) continue;
    if (!linkCondition(m, keep, gone, -1)) continue;
    bool ok = true;
    for (int32_t label : goneMats) ok = ok && linkCondition(m, keep, gone, label);
    if (!ok) continue;
    double oldMin = 1e300, newMin = 1e300;
    std::vector<std::pair<uint32_t, std::array<int32_t, 4>>> moved;
    for (uint32_t s : m.around[size_t(gone)]) {
      oldMin = std::min(oldMin, m.quality(s));
      if (m.has(s, keep)) continue;
      auto N = m.tets[s];
      for (auto& v : N)
        if (v == gone) v = keep;
      moved.emplace_back(s, N);
    }
    const double oldVolume = [&] {
      double v = 0;
      for (uint32_t s : m.around[size_t(gone)]) v += std::fabs(m.volume(s));
      return v;
    }();
    std::vector<double> movedVolume;
    for (const auto& [s, N] : moved) {
      movedVolume.push_back(m.volume(N));
      if (!(movedVolume.back() > 1e-9 * oldVolume)) ok = false;
      newMin = std::min(newMin, m.quality(N));
    }
    if (!ok || !(newMin > oldMin + kEps)) continue;
    // The materials' volumes change by the ring's tets and the moved ones' difference: within the
    // budget interface moves share.
    std::vector<std::pair<int32_t, double>> change;
    auto account = [&](int32_t label, double v) {
      for (auto& [l, c] : change)
        if (l == label) return void(c += v);
      change.emplace_back(label, v);
    };
    for (uint32_t s : m.around[size_t(gone)]) account(m.labels[s], -m.volume(s));
    for (size_t i = 0; i < moved.size(); ++i) account(m.labels[moved[i].first], movedVolume[i]);
    for (const auto& [l, c] : change)
      ok = ok && m.moveFits(size_t(l), c);
    if (!ok) continue;
    for (uint32_t s : ring) m.kill(s);
    std::vector<uint32_t> made;
    for (const auto& [s, N] : moved) {
      const int32_t label = m.labels[s];
      m.kill(s);
      made.push_back(m.add(N, label));
    }
    if (checkFacets && in.enabled() && !starWithinFacetDistance(m, in, keep)) {
      for (uint32_t s : made) m.kill(s);
      for (uint32_t s : ring) m.revive(s);
      for (const auto& [s, N] : moved) m.revive(s);
      continue;
    }
    for (const auto& [l, c] : change) m.movedVolume[size_t(l)] += c;
    fresh.insert(fresh.end(), made.begin(), made.end());
    return true;
  }
  return false;
}

namespace {

/// Collapses interior vertex v onto the neighbour that leaves the best worst tet among those the
/// coarsening rules allow (coarsenInterior); true when done, with the kept neighbour in `kept`
/// and v's neighbours in `nbrs`.
bool removeInteriorVertex(Editor& m, int32_t v, const OptimizeParameters& p, int32_t& kept,
                          std::vector<int32_t>& nbrs) {
  const auto& star = m.around[size_t(v)];
  if (star.empty()) return false;
  const int32_t label = m.labels[star[0]];
  double oldCos = -1;  // cosine of the star's worst angle (comparisons without acos)
  nbrs.clear();
  for (uint32_t s : star) {
    if (m.labels[s] != label) return false;
    oldCos = std::max(oldCos, m.qualityCos(m.tets[s]));
    for (int32_t w : m.tets[s])
      if (w != v) nbrs.push_back(w);
  }
  std::sort(nbrs.begin(), nbrs.end());
  nbrs.erase(std::unique(nbrs.begin(), nbrs.end()), nbrs.end());
  const Vec3 pv = m.pts[size_t(v)];
  // One size for the whole star: the sizing field changes by at most its gradation (well below
  // 1 mm per mm) across it.
  const double h = p.sizeAt(pv);
  if (!(h > 0)) return false;
  // New tets at least min(coarsenMinDihedral, the star's worst): cosines at most floorCos.
  const double floorCos = std::max(std::cos(p.coarsenMinDihedral * kDegToRad), oldCos);
  // The eight nearest neighbours within coarsenShortEdge × h are tried.
  std::vector<std::pair<double, int32_t>> near;
  for (int32_t u : nbrs) {
    const double len = norm(sub(m.pts[size_t(u)], pv));
    if (len < p.coarsenShortEdge * h) near.emplace_back(len, u);
  }
  std::sort(near.begin(), near.end());
  if (near.size() > 8) near.resize(8);
  std::vector<std::pair<double, int32_t>> candidates;  // (cosine of the worst new tet, u)
  for (const auto& [len, u] : near) {
    const Vec3& pu = m.pts[size_t(u)];
    bool ok = true;
    for (int32_t w : nbrs)
      if (w != u && norm(sub(m.pts[size_t(w)], pu)) > p.coarsenLongEdge * h) {
        ok = false;
        break;
      }
    double newCos = -1;
    for (size_t i = 0; ok && i < star.size(); ++i) {
      if (m.has(star[i], u)) continue;
      auto N = m.tets[star[i]];
      for (auto& x : N)
        if (x == v) x = u;
      const double c = m.qualityCos(N);  // 2 when flat or inverted
      newCos = std::max(newCos, c);
      ok = c <= floorCos;
    }
    if (ok) candidates.emplace_back(newCos, u);
  }
  std::sort(candidates.begin(), candidates.end());  // best worst tet first, then lower index
  for (const auto& [c, u] : candidates) {
    // v's tets are all of one material, so the link condition in that material's sub-complex
    // follows from the one in the whole mesh (Lk(v) and Lk(uv) are the same in both).
    if (!linkCondition(m, u, v, -1)) continue;
    std::vector<std::array<int32_t, 4>> moved;
    std::vector<uint32_t> old(star.begin(), star.end());
    for (uint32_t s : old) {
      if (!m.has(s, u)) {
        moved.push_back(m.tets[s]);
        for (auto& x : moved.back())
          if (x == v) x = u;
      }
      m.kill(s);
    }
    for (const auto& N : moved) m.add(N, label);
    kept = u;
    return true;
  }
  return false;
}

}  // namespace

size_t coarsenInterior(Editor& m, const OptimizeParameters& p, int threads) {
  if (!(p.coarsenMinDihedral > 0) || !p.sizeAt) return 0;
  size_t removed = 0;
  constexpr int kChunks = 64;  // fixed: the candidates come in vertex order
  // Collapsing an interior vertex changes no interface or outer face: which vertices are interior
  // is known once for all sweeps.
  std::vector<char> interior(m.pts.size(), 0);
  parallelFor(m.pts.size(), threads, [&](size_t begin, size_t end, int) {
    std::vector<std::array<int32_t, 2>> scratch;
    for (size_t v = begin; v < end; ++v)
      interior[v] = !m.around[v].empty() && !m.computeFixed(int32_t(v), scratch);
  });
  // The first sweep looks at every interior vertex, later ones at the neighbours of a removal.
  std::vector<char> look = interior, touched(m.pts.size(), 0), receiver(m.pts.size(), 0);
  std::vector<int32_t> nbrs;
  for (int sweep = 0; sweep < 2; ++sweep) {
    // Interior vertices with an edge shorter than coarsenShortEdge × size, shortest first.
    auto order = parallelCollect<std::pair<double, int32_t>>(
        m.pts.size(), threads, kChunks,
        [&](size_t begin, size_t end, std::vector<std::pair<double, int32_t>>& found) {
          for (int32_t v = int32_t(begin); v < int32_t(end); ++v) {
            if (!look[size_t(v)] || !interior[size_t(v)] || m.around[size_t(v)].empty()) continue;
            const Vec3& pv = m.pts[size_t(v)];
            const double h = p.sizeAt(pv);
            if (!(h > 0)) continue;
            double shortest = 1e300;
            for (uint32_t s : m.around[size_t(v)])
              for (int32_t w : m.tets[s])
                if (w != v) shortest = std::min(shortest, norm(sub(m.pts[size_t(w)], pv)) / h);
            if (shortest < p.coarsenShortEdge) found.emplace_back(shortest, v);
          }
        });
    std::sort(order.begin(), order.end());
    size_t done = 0;
    for (const auto& [ratio, v] : order) {
      if (m.around[size_t(v)].empty()) continue;
      int32_t u = -1;
      if (removeInteriorVertex(m, v, p, u, nbrs)) {
        ++done;
        for (int32_t w : nbrs) touched[size_t(w)] = 1;
        receiver[size_t(u)] = 1;
      }
    }
    removed += done;
    // The vertex that took a removal carries the stretched tets: smooth it (when interior)
    // before the next sweep. Smoothing every neighbour gains about 2 % fewer tets on the knee for
    // two thirds more time.
    for (int32_t u = 0; u < int32_t(receiver.size()); ++u)
      if (receiver[size_t(u)] && interior[size_t(u)] && !m.around[size_t(u)].empty())
        smoothVertex(m, u, nullptr);
    std::fill(receiver.begin(), receiver.end(), 0);
    look.swap(touched);
    std::fill(touched.begin(), touched.end(), 0);
    if (done == 0) break;
  }
  return removed;
}

}  // namespace optimize_detail
}  // namespace femesher
