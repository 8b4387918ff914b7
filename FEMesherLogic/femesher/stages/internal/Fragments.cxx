// SPDX-License-Identifier: GPL-3.0-or-later
// What the Optimize stage removes from the outer boundary (see Optimize.h): peeling of flat tets
// with an outer face, the specks a peeled tet cuts off, and floating fragments
// (OptimizeParameters::minFragmentVoxels); and eraseTets, the compaction they use.
#include <femesher/Parallel.h>
#include <femesher/VecMath.h>
#include <femesher/stages/internal/OptimizeEditor.h>

#include <algorithm>
#include <numeric>
#include <unordered_set>

namespace femesher {
namespace optimize_detail {

namespace {

/// True when a face (other than of tet t) on the outer boundary holds both u and v.
bool outerEdge(const Editor& m, uint32_t t, int32_t u, int32_t v) {
  for (uint32_t s : m.around[size_t(u)]) {
    if (s == t || !m.has(s, v)) continue;
    for (int k = 0; k < 4; ++k) {
      const int32_t w = m.tets[s][size_t(k)];
      if (w == u || w == v) continue;
      const auto f = m.face(s, k);
      if (m.across(s, f[0], f[1], f[2]) < 0) return true;
    }
  }
  return false;
}

/// True when the three vertices of f lie on one plane of the volume's box.
bool onBoxPlane(const Editor& m, const OptimizeInterfaces& in, const std::array<int32_t, 3>& f) {
  return (in.boxPlanes(m.pts[size_t(f[0])]) & in.boxPlanes(m.pts[size_t(f[1])]) &
          in.boxPlanes(m.pts[size_t(f[2])])) != 0;
}

/// The facet-distance rule of peeling (Optimize.h): t's outer faces on the box have their apex
/// within the facet distance of the box plane, its other
/// faces, which become outer faces of the tets behind them, lie within the facet distance of
/// those tets' interface with the background, and the outer boundary stays a manifold (the edge
/// or vertex that comes to the surface is not on it already). nb: the tet across each face.
bool peelKeepsFacetDistance(const Editor& m, uint32_t t, const int64_t nb[4], int outer,
                            const OptimizeInterfaces& in) {
  if (!in.enabled() || outer == 0 || outer == 4 || !(m.thickness(t) <= 2 * in.facetDistance))
    return false;
  const auto& T = m.tets[t];
  std::vector<int32_t> up;  // the vertices opposite t's outer faces
  for (int k = 0; k < 4; ++k) {
    const auto f = m.face(t, k);
    if (nb[k] < 0) {
      // A face on the volume's box gives way only to faces within the facet distance of its
      // plane (the apex is that close): the box stays flat to that distance.
      const int planes = onBoxPlane(m, in, f) ? in.boxPlanes(m.pts[size_t(f[0])]) &
                                                    in.boxPlanes(m.pts[size_t(f[1])]) &
                                                    in.boxPlanes(m.pts[size_t(f[2])])
                                              : 0;
      for (size_t a = 0; a < 3; ++a)
        for (int side = 0; side < 2; ++side)
          if (planes & ((1 + side) << (2 * a))) {
            const double plane = side ? in.boxHi[a] : in.boxLo[a];
            if (std::fabs(m.pts[size_t(T[size_t(k)])][a] - plane) > in.facetDistance) return false;
          }
      up.push_back(T[size_t(k)]);
      continue;
    }
    const double d = faceDistance(m, in, f, 0, m.labels[size_t(nb[k])]);
    if (d < 0 || d > in.facetDistance) return false;
  }
  if (outer == 2 && outerEdge(m, t, up[0], up[1])) return false;
  if (outer == 1) {  // the vertex opposite the outer face must be inside the mesh
    int32_t inner = -1;
    for (int k = 0; k < 4; ++k)
      if (nb[k] < 0) inner = T[size_t(k)];
    for (uint32_t s : m.around[size_t(inner)])
      for (int k = 0; k < 4; ++k) {
        if (s == t || m.tets[s][size_t(k)] == inner) continue;
        const auto f = m.face(s, k);
        if (m.across(s, f[0], f[1], f[2]) < 0) return false;
      }
  }
  return true;
}

}  // namespace

// peel: see OptimizeEditor.h.
bool peel(Editor& m, uint32_t t, const OptimizeParameters& params, double share,
          const OptimizeInterfaces& in, std::vector<uint32_t>& fresh, bool overBudget) {
  const double tolerance = params.peelDistance * params.voxelSize;
  const size_t label = size_t(m.labels[t]);
  if (tolerance <= 0 || m.perLabel[label] <= 1) return false;
  int64_t nb[4];
  int outer = 0;
  for (int k = 0; k < 4; ++k) {
    const auto f = m.face(t, k);
    nb[k] = m.across(t, f[0], f[1], f[2]);
    outer += nb[k] < 0;
  }
  if (outer == 0) return false;
  // A cap (three or four outer faces) may be as thick as the facet distance: removing it
  // replaces its outer faces by the one below them.
  const double capTolerance = in.enabled() ? in.facetDistance : 0.0;
  if (!(m.thickness(t) <= (outer >= 3 ? std::max(tolerance, capTolerance) : tolerance)) &&
      !peelKeepsFacetDistance(m, t, nb, outer, in))
    return false;
  const double fragment = params.minFragmentVoxels * params.voxelVolume;
  std::vector<uint32_t> specks;
  specksCutOff(m, t, nb, fragment, kBadFragmentFactor * fragment, params.targetMinDihedral, specks);
  std::vector<double> cost(m.perLabel.size(), 0);
  std::vector<size_t> count(m.perLabel.size(), 0);
  cost[label] += m.volume(t);
  ++count[label];
  for (uint32_t s : specks) {
    cost[size_t(m.labels[s])] += std::fabs(m.volume(s));
    ++count[size_t(m.labels[s])];
  }
  for (size_t l = 0; l < cost.size(); ++l)
    if (count[l] > 0 && (count[l] >= m.perLabel[l] || (!overBudget && !m.peelFits(l, cost[l], share))))
      return false;
  for (size_t l = 0; l < cost.size(); ++l) m.peeledVolume[l] += cost[l];
  for (uint32_t s : specks) m.kill(s);
  m.kill(t);
  for (int64_t s : nb)
    if (s >= 0) fresh.push_back(uint32_t(s));
  return true;
}


// specksCutOff: see OptimizeEditor.h.
void specksCutOff(const Editor& m, uint32_t t, const int64_t nb[4], double minVolume,
                  double badMinVolume, double target, std::vector<uint32_t>& specks) {
  specks.clear();
  if (!(minVolume > 0)) return;
  constexpr size_t kMaxTets = 4096;  // a piece of more tets counts as heavy
  const double limit = std::max(minVolume, badMinVolume);
  std::unordered_set<uint32_t> seen{t};
  std::vector<uint32_t> piece, stack;
  std::vector<std::vector<uint32_t>> pieces;  // the light pieces found whole
  std::vector<double> weights;
  size_t wholeTets = 0;
  bool heavy = false;
  for (int k = 0; k < 4; ++k) {
    if (nb[k] < 0 || seen.count(uint32_t(nb[k]))) continue;
    seen.insert(uint32_t(nb[k]));
    piece.assign(1, uint32_t(nb[k]));
    stack.assign(1, uint32_t(nb[k]));
    double volume = 0, worst = 180;
    while (!stack.empty() && volume < limit && piece.size() < kMaxTets) {
      const uint32_t s = stack.back();
      stack.pop_back();
      volume += std::fabs(m.volume(s));
      worst = std::min(worst, m.quality(s));
      for (int j = 0; j < 4; ++j) {
        const auto f = m.face(s, j);
        const int64_t o = m.across(s, f[0], f[1], f[2]);
        if (o < 0 || !seen.insert(uint32_t(o)).second) continue;
        piece.push_back(uint32_t(o));
        stack.push_back(uint32_t(o));
      }
    }
    if (!stack.empty()) {
      heavy = true;
      continue;
    }
    wholeTets += piece.size();
    if (volume < minVolume || (volume < badMinVolume && worst < target)) {
      pieces.push_back(piece);
      weights.push_back(volume);
    }
  }
  // When the pieces found hold every other tet of the mesh (a mesh lighter than the limit), the
  // heaviest of them is the mesh that stays, not a speck.
  size_t alive = 0;
  for (size_t n : m.perLabel) alive += n;
  if (!heavy && wholeTets + 1 >= alive && !pieces.empty()) {
    const size_t keep = size_t(std::max_element(weights.begin(), weights.end()) - weights.begin());
    pieces.erase(pieces.begin() + long(keep));
  }
  for (const auto& p : pieces) specks.insert(specks.end(), p.begin(), p.end());
}

// removeFragments: see OptimizeEditor.h.
void removeFragments(std::vector<Vec3>& points, std::vector<std::array<int32_t, 4>>& tets,
                     std::vector<int32_t>& labels, double minVolume, double badMinVolume,
                     double target, int threads, OptimizeResult& r) {
  const size_t n = tets.size();
  if (n == 0) return;
  // Union-find over tets sharing a face; each piece's root is its first tet. Each face is found
  // at its smallest vertex: the faces of that vertex's tets whose other two vertices are larger,
  // sorted by those two (vertex -> tets in compressed rows: no sort of the 4 n faces, and each
  // vertex's tets read once).
  std::vector<uint32_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  const size_t np = points.size();
  std::vector<uint32_t> first(np + 1, 0), incident(4 * n);
  for (const auto& T : tets)
    for (int32_t v : T) ++first[size_t(v) + 1];
  for (size_t v = 0; v < np; ++v) first[v + 1] += first[v];
  {
    std::vector<uint32_t> fill(first.begin(), first.end() - 1);
    for (uint32_t t = 0; t < n; ++t)
      for (int32_t v : tets[t]) incident[fill[size_t(v)]++] = t;
  }
  // In parallel: per vertex the pairs of tets sharing a face whose smallest vertex it is (in
  // chunks of vertices, joined in vertex order), per tet its volume and the cosine of its
  // smallest angle. The pieces (each rooted at its first tet, whatever order the unions come in)
  // and the sums per piece, taken in tet order, do not depend on the thread count.
  constexpr int kChunks = 64;
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> across(kChunks);
  parallelFor(
      np, threads,
      [&](size_t begin, size_t end, int chunk) {
        auto& pairs = across[size_t(chunk)];
        std::vector<std::pair<std::array<int32_t, 2>, uint32_t>> keys;
        for (size_t a = begin; a < end; ++a) {
          keys.clear();
          for (uint32_t i = first[a]; i < first[a + 1]; ++i) {
            const uint32_t t = incident[i];
            const auto& T = tets[t];
            for (int k = 0; k < 4; ++k) {  // the faces of t holding a: opposite another vertex
              if (T[size_t(k)] == int32_t(a)) continue;
              std::array<int32_t, 2> o{};
              int m = 0;
              for (int c = 0; c < 4; ++c)
                if (c != k && T[size_t(c)] != int32_t(a)) o[size_t(m++)] = T[size_t(c)];
              if (o[0] > o[1]) std::swap(o[0], o[1]);
              if (o[0] > int32_t(a)) keys.push_back({o, t});
            }
          }
          std::sort(keys.begin(), keys.end());
          for (size_t x = 0; x + 1 < keys.size(); ++x)
            for (size_t y = x + 1; y < keys.size() && keys[y].first == keys[x].first; ++y)
              pairs.push_back({keys[x].second, keys[y].second});
        }
      },
      kChunks);
  std::vector<double> tetVolume(n), tetCos(n);
  parallelFor(n, threads, [&](size_t begin, size_t end, int) {
    for (size_t t = begin; t < end; ++t) {
      const auto& T = tets[t];
      const Vec3 &A = points[size_t(T[0])], &B = points[size_t(T[1])], &C = points[size_t(T[2])],
                 &D = points[size_t(T[3])];
      tetVolume[t] = std::fabs(dot(cross(sub(B, A), sub(C, A)), sub(D, A))) / 6;
      tetCos[t] = tetMaxDihedralCos(A, B, C, D);
    }
  });
  for (auto& pairs : across) {
    for (const auto& [t, s] : pairs) {
      const uint32_t x = find(t), y = find(s);
      if (x != y) parent[std::max(x, y)] = std::min(x, y);
    }
    std::vector<std::pair<uint32_t, uint32_t>>().swap(pairs);
  }
  std::vector<uint32_t>().swap(incident);
  std::vector<uint32_t>().swap(first);
  std::vector<double> volume(n, 0), worstCos(n, -1);
  std::vector<size_t> perLabel;
  for (uint32_t t = 0; t < n; ++t) {
    volume[find(t)] += tetVolume[t];
    worstCos[find(t)] = std::max(worstCos[find(t)], tetCos[t]);
    if (size_t(labels[t]) >= perLabel.size()) perLabel.resize(size_t(labels[t]) + 1, 0);
    ++perLabel[size_t(labels[t])];
  }
  // Lightest pieces first, so that a material keeps its largest piece when all are light.
  auto light = [&](uint32_t root) {
    return volume[root] < minVolume ||
           (volume[root] < badMinVolume && cosToDegrees(worstCos[root]) < target);
  };
  std::vector<uint32_t> roots;
  for (uint32_t t = 0; t < n; ++t)
    if (find(t) == t && light(t)) roots.push_back(t);
  std::sort(roots.begin(), roots.end(),
            [&](uint32_t a, uint32_t b) { return volume[a] != volume[b] ? volume[a] < volume[b] : a < b; });
  std::vector<uint32_t> slot(roots.empty() ? 0 : n, 0);  // root -> 1 + its place in `roots`
  for (size_t i = 0; i < roots.size(); ++i) slot[roots[i]] = uint32_t(i + 1);
  std::vector<std::vector<uint32_t>> members(roots.size());
  for (uint32_t t = 0; t < n && !roots.empty(); ++t)
    if (const uint32_t i = slot[find(t)]) members[i - 1].push_back(t);
  std::vector<char> drop(n, 0);
  for (size_t i = 0; i < roots.size(); ++i) {
    const uint32_t root = roots[i];
    const auto& piece = members[i];
    std::vector<size_t> take(perLabel.size(), 0);
    for (uint32_t t : piece) ++take[size_t(labels[t])];
    bool last = false;
    for (size_t l = 0; l < take.size(); ++l) last |= take[l] > 0 && take[l] >= perLabel[l];
    if (last) continue;
    for (size_t l = 0; l < take.size(); ++l) perLabel[l] -= take[l];
    for (uint32_t t : piece) drop[t] = 1;
    ++r.fragments;
    r.fragmentTets += piece.size();
    r.fragmentVolume += volume[root];
  }
  if (r.fragmentTets > 0) eraseTets(points, tets, labels, drop);
}

}  // namespace optimize_detail

// eraseTets: see Optimize.h (the compaction removeFragments, MeshCheck and Optimize share).
void eraseTets(std::vector<Vec3>& points, std::vector<std::array<int32_t, 4>>& tets,
               std::vector<int32_t>& labels, const std::vector<char>& erase) {
  size_t n = 0;
  for (size_t t = 0; t < tets.size(); ++t)
    if (!erase[t]) {
      tets[n] = tets[t];
      labels[n++] = labels[t];
    }
  tets.resize(n);
  labels.resize(n);
  std::vector<int32_t> newIndex(points.size(), -1);
  for (const auto& T : tets)
    for (int32_t v : T) newIndex[size_t(v)] = 0;
  size_t m = 0;
  for (size_t i = 0; i < points.size(); ++i)
    if (newIndex[i] == 0) {
      newIndex[i] = int32_t(m);
      points[m++] = points[i];
    }
  points.resize(m);
  for (auto& T : tets)
    for (int32_t& v : T) v = newIndex[size_t(v)];
}

}  // namespace femesher
