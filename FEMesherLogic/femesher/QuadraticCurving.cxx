// SPDX-License-Identifier: GPL-3.0-or-later
// Curved mid-edge nodes of 10-node tets: onto the smooth interfaces where every element stays
// valid.
#include <femesher/QuadraticCurving.h>
#include <femesher/RunContext.h>
#include <femesher/VecMath.h>

#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <vector>

namespace femesher {

namespace {

/// The material pairs of the faces around one surface edge (at most three kept).
struct SurfaceEdge {
  std::array<std::array<int, 2>, 3> pairs{};
  int count = 0;
  bool overflow = false;  ///< more than three different pairs
  bool box = false;       ///< on a face that lies on the volume's box

  void add(int a, int b) {
    for (int i = 0; i < count; ++i)
      if (pairs[size_t(i)][0] == a && pairs[size_t(i)][1] == b) return;
    if (count == 3) {
      overflow = true;
      return;
    }
    pairs[size_t(count++)] = {{a, b}};
  }
  /// The three materials of a triple line (pairs ab, ac, bc of three materials), sorted.
  bool tripleLine(std::array<int, 3>& abc) const {
    if (count != 3 || overflow) return false;
    std::vector<int> m;
    for (const auto& p : pairs) m.insert(m.end(), p.begin(), p.end());
    std::sort(m.begin(), m.end());
    m.erase(std::unique(m.begin(), m.end()), m.end());
    if (m.size() != 3) return false;
    abc = {{m[0], m[1], m[2]}};
    return true;
  }
};

/// Puts `p` on every box plane of `planes` and inside the box.
void keepInBox(const OptimizeInterfaces& in, int planes, Vec3& p) {
  if (!in.hasBox) return;
  for (size_t a = 0; a < 3; ++a) {
    p[a] = std::clamp(p[a], in.boxLo[a], in.boxHi[a]);
    if (planes & (1 << (2 * a))) p[a] = in.boxLo[a];
    if (planes & (2 << (2 * a))) p[a] = in.boxHi[a];
  }
}

/// Vertex -> incident tets, compressed rows.
struct Incidence {
  std::vector<int32_t> start, tets;
  explicit Incidence(const TetMesh& m) : start(m.points.size() + 1, 0), tets(m.tets.size() * 4) {
    for (const auto& t : m.tets)
      for (int32_t v : t) ++start[size_t(v) + 1];
    for (size_t i = 1; i < start.size(); ++i) start[i] += start[i - 1];
    std::vector<int32_t> fill(start.begin(), start.end() - 1);
    for (size_t t = 0; t < m.tets.size(); ++t)
      for (int32_t v : m.tets[t]) tets[size_t(fill[size_t(v)]++)] = int32_t(t);
  }
  /// Tets around the edge (u, v).
  void around(int32_t u, int32_t v, std::vector<int32_t>& out) const {
    out.clear();
    for (int32_t i = start[size_t(u)]; i < start[size_t(u) + 1]; ++i) {
      const int32_t t = tets[size_t(i)];
      for (int32_t j = start[size_t(v)]; j < start[size_t(v) + 1]; ++j)
        if (tets[size_t(j)] == t) {
          out.push_back(t);
          break;
        }
    }
  }
};

/// Number of unique edges (each vertex counts its higher neighbours).
size_t uniqueEdgeCount(const TetMesh& m, const Incidence& inc) {
  size_t n = 0;
  std::vector<int32_t> nb;
  for (size_t u = 0; u < m.points.size(); ++u) {
    nb.clear();
    for (int32_t i = inc.start[u]; i < inc.start[u + 1]; ++i)
      for (int32_t v : m.tets[size_t(inc.tets[size_t(i)])])
        if (v > int32_t(u)) nb.push_back(v);
    std::sort(nb.begin(), nb.end());
    n += size_t(std::unique(nb.begin(), nb.end()) - nb.begin());
  }
  return n;
}

/// The ten nodes of tet t with the mid-edge node of `key` at `at` and the others as curved so far.
std::array<Vec3, 10> tetNodes(const TetMesh& m, size_t t, const MidEdgePositions& curved,
                              uint64_t key, const Vec3& at) {
  std::array<Vec3, 10> x;
  const auto& T = m.tets[t];
  for (size_t k = 0; k < 4; ++k) x[k] = m.points[size_t(T[k])];
  for (size_t k = 0; k < 6; ++k) {
    const int32_t a = T[size_t(kTet10Edges[k][0])], b = T[size_t(kTet10Edges[k][1])];
    const uint64_t e = tetEdgeKey(a, b);
    if (e == key) {
      x[4 + k] = at;
      continue;
    }
    const auto it = curved.find(e);
    x[4 + k] =
        it != curved.end() ? it->second : scale(add(m.points[size_t(a)], m.points[size_t(b)]), 0.5);
  }
  return x;
}

}  // namespace

QuadraticCurvingResult curveMidEdgeNodes(const TetMesh& mesh, const OptimizeInterfaces& in,
                                         const QuadraticCurvingParameters& params,
                                         RunContext& ctx) {
  QuadraticCurvingResult r;
  const Incidence inc(mesh);
  r.midEdgeNodes = uniqueEdgeCount(mesh, inc);
  if (!in.projectOntoInterface) return r;

  // The material pairs of the interface and outer faces around every surface edge.
  std::unordered_map<uint64_t, SurfaceEdge> surface;
  for (const InterfaceTriangle& f : extractInterfaces(mesh)) {
    const bool outer = f.labelB == kExteriorLabel;
    const bool onBox = outer && (in.boxPlanes(mesh.points[size_t(f.v[0])]) &
                                 in.boxPlanes(mesh.points[size_t(f.v[1])]) &
                                 in.boxPlanes(mesh.points[size_t(f.v[2])])) != 0;
    const int a = outer ? 0 : std::min(f.labelA, f.labelB);
    const int b = outer ? f.labelA : std::max(f.labelA, f.labelB);
    for (int k = 0; k < 3; ++k) {
      SurfaceEdge& e = surface[tetEdgeKey(f.v[size_t(k)], f.v[size_t((k + 1) % 3)])];
      if (onBox)
        e.box = true;
      else
        e.add(a, b);
    }
  }
  std::vector<uint64_t> keys;
  keys.reserve(surface.size());
  for (const auto& kv : surface) keys.push_back(kv.first);
  std::sort(keys.begin(), keys.end());

  std::vector<int32_t> tets;
  double moved = 0;
  size_t movedCount = 0, visited = 0;
  for (uint64_t key : keys) {
    if (++visited % 4096 == 0) ctx.checkCancel();
    const SurfaceEdge& e = surface.at(key);
    const int32_t u = int32_t(key >> 32), v = int32_t(key & 0xffffffffu);
    const Vec3 &pu = mesh.points[size_t(u)], &pv = mesh.points[size_t(v)];
    const int planes = in.boxPlanes(pu) & in.boxPlanes(pv);
    // Flat box faces and box edges are exact already: their nodes stay at the midpoint.
    if (e.box && (e.count == 0 || __builtin_popcount(unsigned(planes)) >= 2)) continue;
    ++r.surfaceNodes;
    const Vec3 mid = scale(add(pu, pv), 0.5);
    const double length = norm(sub(pu, pv));
    Vec3 p = mid;
    bool ok = false;
    std::array<int, 3> abc{};
    const bool triple = !e.box && e.tripleLine(abc) && bool(in.projectOntoJunction);
    if (e.overflow || (e.count != 1 && !triple)) {
      ok = false;  // junction of four or more materials, pinched interface, or box trace of many
    } else if (triple) {
      ok = in.projectOntoJunction(abc, p);
    } else if (planes == 0) {
      ok = in.projectOntoInterface(e.pairs[0][0], e.pairs[0][1], p);
    } else {
      // The interface's trace on the box plane(s): project and go back to the plane in turn.
      ok = true;
      for (int it = 0; it < 6 && ok; ++it) {
        ok = in.projectOntoInterface(e.pairs[0][0], e.pairs[0][1], p);
        const Vec3 before = p;
        keepInBox(in, planes, p);
        if (ok && norm(sub(before, p)) < 1e-4 * length) break;
        if (it == 5) ok = false;
      }
    }
    if (ok) keepInBox(in, planes, p);
    const Vec3 move = sub(p, mid);
    // The surface stage put every interface edge's midpoint within the facet distance of its
    // interface: a projection that lands much farther found another part of it.
    const double reach =
        in.facetDistance > 0 ? std::min(0.5 * length, 2 * in.facetDistance) : 0.5 * length;
    if (!ok || norm(move) > reach) {
      ++r.straightKept;
      continue;
    }
    if (norm(move) <= 1e-12 * length) {  // on the surface already (a flat interface)
      ++r.onInterfaceNodes;
      continue;
    }
    inc.around(u, v, tets);
    double t = 1;
    bool accepted = false;
    for (int h = 0; h <= params.halvings && !accepted; ++h, t *= 0.5) {
      const Vec3 q = add(mid, scale(move, t));
      accepted = std::all_of(tets.begin(), tets.end(), [&](int32_t ti) {
        const Tet10Jacobian j = tet10Jacobian(tetNodes(mesh, size_t(ti), r.nodes, key, q));
        return j.minOverStraight >= params.minJacobianFraction &&
               j.minOverMax >= params.minScaledJacobian;
      });
      if (accepted) {
        r.nodes[key] = q;
        ++(h == 0 ? r.curvedNodes : r.partlyCurvedNodes);
        if (triple) ++r.tripleLineNodes;
        if (planes) ++r.boxPlaneNodes;
        moved += t * norm(move);
        r.maxMove = std::max(r.maxMove, t * norm(move));
        ++movedCount;
      }
    }
    if (!accepted) ++r.straightKept;
  }
  r.meanMove = movedCount ? moved / double(movedCount) : 0;

  // The worst element: only tets with a curved node differ from 1.
  for (size_t t = 0; t < mesh.tets.size(); ++t) {
    const auto& T = mesh.tets[t];
    bool curved = false;
    for (const auto& ek : kTet10Edges)
      curved |= r.nodes.count(tetEdgeKey(T[size_t(ek[0])], T[size_t(ek[1])])) > 0;
    if (!curved) continue;
    const Tet10Jacobian j = tet10Jacobian(tetNodes(mesh, t, r.nodes, ~uint64_t(0), Vec3{}));
    r.worst.minOverStraight = std::min(r.worst.minOverStraight, j.minOverStraight);
    r.worst.minOverMax = std::min(r.worst.minOverMax, j.minOverMax);
  }
  return r;
}

ReportCounts reportCounts(const QuadraticCurvingResult& r) {
  return {{"quadratic_mid_edge_nodes", double(r.midEdgeNodes)},
          {"quadratic_surface_nodes", double(r.surfaceNodes)},
          {"quadratic_curved_nodes", double(r.curvedNodes)},
          {"quadratic_partly_curved_nodes", double(r.partlyCurvedNodes)},
          {"quadratic_straight_kept", double(r.straightKept)},
          {"quadratic_on_interface_nodes", double(r.onInterfaceNodes)},
          {"quadratic_triple_line_nodes", double(r.tripleLineNodes)},
          {"quadratic_box_plane_nodes", double(r.boxPlaneNodes)},
          {"quadratic_mean_move_mm", r.meanMove},
          {"quadratic_max_move_mm", r.maxMove},
          {"quadratic_min_jacobian_fraction", r.worst.minOverStraight},
          {"quadratic_worst_scaled_jacobian", r.worst.minOverMax}};
}

}  // namespace femesher
