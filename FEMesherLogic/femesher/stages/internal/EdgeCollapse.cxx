// SPDX-License-Identifier: GPL-3.0-or-later
// Optimize stage: collapse of a bad tet's short edge (see collapseShortEdge in OptimizeEditor.h).
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

bool collapseShortEdge(Editor& m, uint32_t t, double maxLength, const OptimizeInterfaces& in,
                       std::vector<uint32_t>& fresh) {
  const auto T = m.tets[t];
  int bi = -1, bj = -1;
  double best = maxLength;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) {
      const double len = norm(sub(m.pts[size_t(T[size_t(j)])], m.pts[size_t(T[size_t(i)])]));
      if (len < best) best = len, bi = i, bj = j;
    }
  if (bi < 0) return false;
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
  for (int attempt = 0; attempt < 2; ++attempt) {
    const int32_t keep = T[size_t(attempt == 0 ? bi : bj)],
                  gone = T[size_t(attempt == 0 ? bj : bi)];
    m.tetsOnEdge(keep, gone, ring);
    const bool edgeOuter = materialsAndOuter(ring, keep, gone, edgeMats);
    const bool goneOuter = materialsAndOuter(m.around[size_t(gone)], gone, -1, goneMats);
    if (edgeMats != goneMats || (goneOuter && !edgeOuter)) continue;
    // A vertex on the volume's box keeps every box plane it is on: the box stays exact.
    const int goneBox = boxPlanes(in, m.pts[size_t(gone)]);
    if ((goneBox & boxPlanes(in, m.pts[size_t(keep)])) != goneBox) continue;
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
      ok =
          ok && std::fabs(m.movedVolume[size_t(l)] + c) <= kVolumeBudget * m.startVolume[size_t(l)];
    if (!ok) continue;
    for (const auto& [l, c] : change) m.movedVolume[size_t(l)] += c;
    for (uint32_t s : ring) m.kill(s);
    for (const auto& [s, N] : moved) {
      const int32_t label = m.labels[s];
      m.kill(s);
      fresh.push_back(m.add(N, label));
    }
    return true;
  }
  return false;
}

}  // namespace optimize_detail
}  // namespace femesher
