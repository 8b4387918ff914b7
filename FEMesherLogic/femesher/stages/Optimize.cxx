// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/Status.h>
#include <femesher/VecMath.h>
#include <femesher/stages/Optimize.h>
#include <femesher/stages/internal/OptimizeEditor.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

namespace femesher {

namespace optimize_detail {

/// Edge removal: re-triangulates the ring of edge (u, v) of tet t when that raises the ring's
/// worst tet. Returns true when applied.
bool removeEdge(Editor& m, uint32_t t, int32_t u, int32_t v, std::vector<uint32_t>& fresh) {
  std::vector<uint32_t> ring;
  m.tetsOnEdge(u, v, ring);
  const size_t n = ring.size();
  if (n < 3 || n > 7) return false;
  const int32_t label = m.labels[t];
  double oldMin = 1e300;
  // Link polygon: per ring tet the edge (p, q) with vol(u, v, p, q) > 0, chained p -> q.
  std::vector<std::pair<int32_t, int32_t>> links;
  for (uint32_t s : ring) {
    if (m.labels[s] != label) return false;
    oldMin = std::min(oldMin, m.quality(s));
    int32_t pq[2], k = 0;
    for (int32_t w : m.tets[s])
      if (w != u && w != v) pq[k++] = w;
    const Vec3 &U = m.pts[size_t(u)], &V = m.pts[size_t(v)], &P = m.pts[size_t(pq[0])],
               &Q = m.pts[size_t(pq[1])];
    const double vol = dot(cross(sub(P, U), sub(Q, U)), sub(V, U));
    links.push_back(vol > 0 ? std::make_pair(pq[0], pq[1]) : std::make_pair(pq[1], pq[0]));
  }
  std::vector<int32_t> w;
  w.push_back(links[0].first);
  for (size_t i = 0; i < n; ++i) {
    const int32_t cur = w.back();
    int32_t next = -1;
    for (const auto& l : links)
      if (l.first == cur) {
        if (next >= 0) return false;  // not a simple cycle
        next = l.second;
      }
    if (next < 0) return false;  // open ring: the edge is on the boundary
    if (i + 1 < n) {
      if (std::find(w.begin(), w.end(), next) != w.end()) return false;
      w.push_back(next);
    } else if (next != w[0]) {
      return false;
    }
  }
  // Best triangulation of the polygon w[0..n-1]: triangle (i, k, j) gives tets (w_i, w_k, w_j, v)
  // and (w_i, w_j, w_k, u).
  double best[7][7];
  int split[7][7];
  // A diagonal that is an edge of the mesh already runs outside the ring: never use it.
  bool existing[7][7] = {};
  for (size_t i = 0; i < n; ++i)
    for (size_t j = i + 2; j < n; ++j) {
      if (i == 0 && j == n - 1) continue;
      for (uint32_t r : m.around[size_t(w[i])])
        if (m.has(r, w[j])) existing[i][j] = true;
    }
  // A ring of three becomes the two tets on triangle (w0, w1, w2), whose edges are all in the
  // mesh already: the triangle itself must not be (a thin rod's surface can hold it; the new tets
  // would make it a triangle of three or four tets).
  if (n == 3)
    for (uint32_t r : m.around[size_t(w[0])])
      if (m.has(r, w[1]) && m.has(r, w[2])) return false;
  auto triangleQuality = [&](size_t i, size_t k, size_t j) {
    if (existing[i][k] || existing[k][j] || existing[i][j]) return -1.0;
    const double a = m.quality({w[i], w[k], w[j], v});
    if (a <= 0) return -1.0;
    return std::min(a, m.quality({w[i], w[j], w[k], u}));
  };
  for (size_t len = 1; len < n; ++len)
    for (size_t i = 0; i + len < n; ++i) {
      const size_t j = i + len;
      if (len == 1) {
        best[i][j] = 1e300;
        continue;
      }
      best[i][j] = -1;
      split[i][j] = -1;
      for (size_t k = i + 1; k < j; ++k) {
        const double q = std::min({best[i][k], best[k][j], triangleQuality(i, k, j)});
        if (q > best[i][j]) {
          best[i][j] = q;
          split[i][j] = int(k);
        }
      }
    }
  if (best[0][n - 1] <= oldMin + kEps) return false;
  for (uint32_t s : ring) m.kill(s);
  std::vector<std::pair<size_t, size_t>> stack{{0, n - 1}};
  while (!stack.empty()) {
    const auto [i, j] = stack.back();
    stack.pop_back();
    if (j < i + 2) continue;
    const size_t k = size_t(split[i][j]);
    fresh.push_back(m.add({w[i], w[k], w[j], v}, label));
    fresh.push_back(m.add({w[i], w[j], w[k], u}, label));
    stack.push_back({i, k});
    stack.push_back({k, j});
  }
  return true;
}

/// 2-to-3 flip across face k of t (the face opposite T[k]) when both tets are of one material.
bool flipFace(Editor& m, uint32_t t, int k, std::vector<uint32_t>& fresh) {
  auto f = m.face(t, k);
  const int64_t s = m.across(t, f[0], f[1], f[2]);
  if (s < 0 || m.labels[size_t(s)] != m.labels[t]) return false;
  const int32_t d = m.tets[t][size_t(k)];
  int32_t e = -1;
  for (int32_t x : m.tets[size_t(s)])
    if (x != f[0] && x != f[1] && x != f[2]) e = x;
  for (uint32_t r : m.around[size_t(d)])
    if (m.has(r, e)) return false;  // edge d-e exists already
  // Orient (a, b, c) so that d is on its positive side.
  const Vec3 &A = m.pts[size_t(f[0])], &B = m.pts[size_t(f[1])], &C = m.pts[size_t(f[2])],
             &D = m.pts[size_t(d)];
  if (dot(cross(sub(B, A), sub(C, A)), sub(D, A)) < 0) std::swap(f[1], f[2]);
  const double oldMin = std::min(m.quality(t), m.quality(uint32_t(s)));
  const std::array<std::array<int32_t, 4>, 3> nt = {{{e, d, f[0], f[1]},
                                                      {e, d, f[1], f[2]},
                                                      {e, d, f[2], f[0]}}};
  double newMin = 1e300;
  for (const auto& T : nt) newMin = std::min(newMin, m.quality(T));
  if (newMin <= oldMin + kEps) return false;
  const int32_t label = m.labels[t];
  m.kill(t);
  m.kill(uint32_t(s));
  for (const auto& T : nt) fresh.push_back(m.add(T, label));
  return true;
}

bool sphereShell(const std::vector<std::pair<std::array<int32_t, 4>, int>>& shell) {
  std::vector<std::pair<int32_t, int32_t>> edges;
  std::vector<int32_t> vertices;
  for (const auto& [T, k] : shell) {
    std::array<int32_t, 3> f;
    int n = 0;
    for (int i = 0; i < 4; ++i)
      if (i != k) f[size_t(n++)] = T[size_t(i)];
    for (int i = 0; i < 3; ++i) {
      vertices.push_back(f[size_t(i)]);
      const int32_t a = f[size_t(i)], b = f[size_t((i + 1) % 3)];
      edges.emplace_back(std::min(a, b), std::max(a, b));
    }
  }
  std::sort(edges.begin(), edges.end());
  for (size_t i = 0; i < edges.size(); i += 2)
    if (i + 1 >= edges.size() || edges[i] != edges[i + 1] ||
        (i + 2 < edges.size() && edges[i + 2] == edges[i]))
      return false;
  std::sort(vertices.begin(), vertices.end());
  const long V = long(std::unique(vertices.begin(), vertices.end()) - vertices.begin());
  const long E = long(edges.size() / 2), F = long(shell.size());
  return V - E + F == 2;
}

}  // namespace optimize_detail

namespace {

using namespace optimize_detail;

/// Chunks of the scans over every tet (fixed, so that what they find comes in tet order).
constexpr int kScanChunks = 64;

/// How many times the improvement runs a round that may insert vertices (see improve).
constexpr int kInsertingRounds = 4;
/// Inserting rounds over the tets still below the target after the interior is coarsened.
constexpr int kRescueRounds = 4;
/// Those rounds run again while they raise the worst tet below the target or lower their number,
/// at most this many times (OptimizeShapes' thin rod 5.5 -> 11.3 and one-voxel plate
/// 11.1 -> 14.9 degrees from once to up to eight times).
constexpr int kRescueTimes = 8;

/// Tets of a round that get the connectivity operations before those of them nothing helped get
/// their vertex moves (see improve), and the chunks in which the moves are found ahead. Small, so
/// that a tet's moves wait for at most 15 others: over batches of 1 (each tet's moves at once),
/// 16, 64 and 256 tets the thin plate's and rod's worst angles over eight seeds (the figures
/// OptimizeShapesOverEightSeeds checks) swing by up to 3.6 degrees per seed either way with no
/// trend (16: means 13.73 and 11.57 degrees against 13.73 and 11.25 at 1); colin27's Optimize
/// 24.6 s at 1, 20.4 s at 16 (2 threads).
constexpr size_t kMoveBatch = 16;
constexpr int kMoveChunks = 16;

/// Longest edge (in facet distances) the inserting rounds may collapse when the interface
/// triangles left stay within the facet distance.
constexpr double kLongCollapse = 8;

/// How far (share of the facet distance) the last-resort move may take a vertex off its interface.
constexpr double kOffInterfaceShare = 0.95;

/// Vertex insertion: a new vertex inside tet t replaces t and the tets of its material across
/// unconstrained faces, `rings` steps deep (the cavity), by tets joining it to the cavity's faces,
/// then moves to where the worst of them is best (smoothVertex). Kept only when that worst tet
/// beats the cavity's worst and no more of them are below `target` than before; otherwise the
/// cavity's tets come back (the unused point is dropped at the end). Constrained faces stay as
/// they are, so interfaces and the outer boundary do not change.
bool insertVertex(Editor& m, uint32_t t, double target, int rings, std::vector<uint32_t>& fresh) {
  const int32_t label = m.labels[t];
  // The faces held by one tet of `tets` only (the rest are held by two of them), as the tet and
  // the slot opposite: the boundary of their union.
  auto boundaryOf = [&m](const std::vector<uint32_t>& tets) {
    std::vector<std::pair<std::array<int32_t, 3>, std::pair<uint32_t, int>>> faces;
    for (uint32_t s : tets)
      for (int k = 0; k < 4; ++k) {
        auto f = m.face(s, k);
        std::sort(f.begin(), f.end());
        faces.push_back({f, {s, k}});
      }
    std::sort(faces.begin(), faces.end());
    std::vector<std::pair<std::array<int32_t, 4>, int>> shell;
    for (size_t i = 0; i < faces.size();) {
      size_t j = i + 1;
      while (j < faces.size() && faces[j].first == faces[i].first) ++j;
      if (j == i + 1) shell.push_back({m.tets[faces[i].second.first], faces[i].second.second});
      i = j;
    }
    return shell;
  };
  // `rings` steps across unconstrained faces; should that cavity not be a ball (it touched itself
  // along an edge or at a vertex, as around a thin rod), the same steps again taking only the
  // tets that keep it a ball.
  std::vector<uint32_t> cavity;
  for (const bool keepBall : {false, true}) {
    cavity.assign(1, t);
    size_t from = 0;
    for (int ring = 0; ring < rings; ++ring) {
      const size_t to = cavity.size();
      for (size_t i = from; i < to; ++i)
        for (int k = 0; k < 4; ++k) {
          const auto f = m.face(cavity[i], k);
          const int64_t s = m.across(cavity[i], f[0], f[1], f[2]);
          if (s < 0 || m.labels[size_t(s)] != label ||
              std::find(cavity.begin(), cavity.end(), uint32_t(s)) != cavity.end())
            continue;
          cavity.push_back(uint32_t(s));
          if (keepBall && !sphereShell(boundaryOf(cavity))) cavity.pop_back();
        }
      from = to;
    }
    if (keepBall || sphereShell(boundaryOf(cavity))) break;
  }
  if (cavity.size() < 2) return false;
  double oldMin = 1e300;
  size_t oldBelow = 0;
  for (uint32_t s : cavity) {
    oldMin = std::min(oldMin, m.quality(s));
    oldBelow += m.quality(s) < target;
  }
  // The cavity's faces: a face of a cavity tet whose other side is not in the cavity. Replacing
  // the opposite vertex by the new one keeps the orientation.
  std::vector<std::pair<std::array<int32_t, 4>, int>> shell;  // (tet with the slot to fill, slot)
  for (uint32_t s : cavity)
    for (int k = 0; k < 4; ++k) {
      const auto f = m.face(s, k);
      const int64_t o = m.across(s, f[0], f[1], f[2]);
      if (o >= 0 && std::find(cavity.begin(), cavity.end(), uint32_t(o)) != cavity.end()) continue;
      shell.push_back({m.tets[s], k});
    }
  Vec3 c{0, 0, 0};
  for (int32_t w : m.tets[t])
    for (int a = 0; a < 3; ++a) c[a] += m.pts[size_t(w)][a] / 4;
  const int32_t v = m.addPoint(c);
  for (uint32_t s : cavity) m.kill(s);
  std::vector<uint32_t> made;
  for (auto [T, k] : shell) {
    T[size_t(k)] = v;
    made.push_back(m.add(T, label));
  }
  smoothVertex(m, v, nullptr);
  double newMin = 1e300;
  size_t newBelow = 0;
  for (uint32_t s : m.around[size_t(v)]) {
    newMin = std::min(newMin, m.quality(s));
    newBelow += m.quality(s) < target;
  }
  if (!(newMin > oldMin + kEps) || newBelow > oldBelow) {
    for (uint32_t s : made) m.kill(s);
    for (uint32_t s : cavity) m.revive(s);
    return false;
  }
  fresh.insert(fresh.end(), made.begin(), made.end());
  return true;
}

/// True when edge (u, v) lies inside one material: its ring of tets (`ring`) is closed and of
/// one material, so no interface or outer face holds the edge.
bool innerEdge(const Editor& m, int32_t u, int32_t v, const std::vector<uint32_t>& ring) {
  std::vector<int32_t> link;
  for (uint32_t s : ring) {
    if (m.labels[s] != m.labels[ring[0]]) return false;
    for (int32_t w : m.tets[s])
      if (w != u && w != v) link.push_back(w);
  }
  std::sort(link.begin(), link.end());
  for (size_t i = 0; i < link.size(); i += 2)
    if (i + 1 >= link.size() || link[i] != link[i + 1] || (i + 2 < link.size() && link[i + 2] == link[i]))
      return false;
  return !link.empty();
}

/// Edge split: the longest edge of tet t that helps is split at its midpoint w, together with
/// every tet around it whatever their material (so the mesh stays conformal), and w then moves
/// by its class like any vertex (moveVertex: along its interface or triple line, within its flat
/// outer patch, or freely inside one material). Interface triangles on the edge are halved in
/// their own plane, so no interface moves before w does, and w's move keeps its own rules. Without
/// interfaces to move along (or moveInterfaces off), only edges inside one material are split. Kept
/// only when the worst of the new tets beats the worst tet around the edge; otherwise the old
/// tets come back (the unused point is dropped at the end). True when applied.
bool splitEdge(Editor& m, uint32_t t, const OptimizeParameters& params,
               const OptimizeInterfaces& interfaces, std::vector<uint32_t>& fresh) {
  const auto T = m.tets[t];
  std::array<std::pair<double, std::pair<int32_t, int32_t>>, 6> edges;
  int n = 0;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j)
      edges[size_t(n++)] = {-norm(sub(m.pts[size_t(T[size_t(i)])], m.pts[size_t(T[size_t(j)])])),
                            {T[size_t(i)], T[size_t(j)]}};
  std::sort(edges.begin(), edges.end());
  std::vector<uint32_t> ring, made;
  const bool surfaces = params.moveInterfaces && interfaces.enabled();
  for (const auto& [negLength, uv] : edges) {
    const auto [u, v] = uv;
    m.tetsOnEdge(u, v, ring);
    if (!surfaces && !innerEdge(m, u, v, ring)) continue;  // interfaces and boundary stay as they are
    double oldMin = 1e300;
    for (uint32_t s : ring) oldMin = std::min(oldMin, m.quality(s));
    const Vec3 &U = m.pts[size_t(u)], &V = m.pts[size_t(v)];
    const int32_t w = m.addPoint({(U[0] + V[0]) / 2, (U[1] + V[1]) / 2, (U[2] + V[2]) / 2});
    made.clear();
    for (uint32_t s : ring) {
      m.kill(s);
      for (int32_t end : {u, v}) {
        auto half = m.tets[s];
        for (int32_t& x : half)
          if (x == end) x = w;
        made.push_back(m.add(half, m.labels[s]));
      }
    }
    const std::vector<double> movedBefore = m.movedVolume;
    OptimizeResult scratch;
    moveVertex(m, w, params, interfaces, scratch);
    double newMin = 1e300;
    for (uint32_t s : m.around[size_t(w)]) newMin = std::min(newMin, m.quality(s));
    if (newMin > oldMin + kEps) {
      fresh.insert(fresh.end(), made.begin(), made.end());
      return true;
    }
    for (uint32_t s : made) m.kill(s);
    for (uint32_t s : ring) m.revive(s);
    m.movedVolume = movedBefore;
    m.junctionStart.erase(w);
  }
  return false;
}

}  // namespace

double tetMaxDihedralCos(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const Vec3 ab = sub(b, a), ac = sub(c, a), ad = sub(d, a);
  const double vol = dot(cross(ab, ac), ad);
  if (!(vol > 0)) return 2;
  // Outward face normals (unnormalised): opposite a, b, c, d.
  const Vec3 bc = sub(c, b), bd = sub(d, b);
  Vec3 n[4] = {cross(bd, bc), cross(ac, ad), cross(ad, ab), cross(ab, ac)};
  double len[4];
  for (int i = 0; i < 4; ++i) {
    len[i] = norm(n[i]);
    if (!(len[i] > 0)) return 2;
  }
  // Dihedral angle at the edge shared by faces i and j: pi - angle(n_i, n_j).
  double maxCos = -1;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j)
      maxCos = std::max(maxCos, -dot(n[i], n[j]) / (len[i] * len[j]));
  return std::clamp(maxCos, -1.0, 1.0);
}

double cosToDegrees(double maxCos) { return maxCos > 1 ? -1 : std::acos(maxCos) * kRadToDeg; }

namespace {

/// "Smallest dihedral angle below `degrees`" decided from tetMaxDihedralCos's value, with the
/// acos taken only near the threshold: a cosine clearly below the threshold's is an angle clearly
/// above it (the margin dwarfs acos's rounding). A flat or inverted tet counts as 0 degrees.
struct BelowAngle {
  double degrees, clearCos;
  explicit BelowAngle(double d) : degrees(d), clearCos(std::cos(d / kRadToDeg) - 1e-9) {}
  bool operator()(double c) const {
    return !(c < clearCos) && std::max(0.0, cosToDegrees(c)) < degrees;
  }
};

}  // namespace

double tetMinDihedral(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  return cosToDegrees(tetMaxDihedralCos(a, b, c, d));
}

namespace {

void improve(std::vector<Vec3>& points, std::vector<std::array<int32_t, 4>>& tets,
             std::vector<int32_t>& labels, const OptimizeParameters& params,
             const OptimizeInterfaces& interfaces, RunContext& ctx, OptimizeResult& r) {
  Editor m(points, tets, labels);
  std::vector<uint32_t> queue, fresh;
  const BelowAngle belowTarget(params.targetMinDihedral);
  auto bad = [&](uint32_t t) { return belowTarget(m.qualityCos(m.tets[t])); };
  // The alive tets below the target, in order (found in parallel, in fixed chunks).
  auto everyBadTet = [&] {
    queue = parallelCollect<uint32_t>(
        tets.size(), ctx.threads(), kScanChunks,
        [&](size_t begin, size_t end, std::vector<uint32_t>& found) {
          for (size_t t = begin; t < end; ++t)
            if (m.alive[t] && bad(uint32_t(t))) found.push_back(uint32_t(t));
        });
  };
  everyBadTet();
  // Rounds: up to `passes` regular ones (until nothing changes), then, with insertVertices,
  // kInsertingRounds times a round that may also insert vertices (and split edges) over every tet
  // still below the target followed by a regular one over what it changed. Insertion comes last
  // so that it only works where nothing else helps; each later time round reaches the tets the
  // one before made or could not help (four rounds: example_seg_dicom's worst tet 10.6 -> 11.8
  // -> 12.8 degrees from two to three to four, colin27's Optimize 20.7 -> 22.1 s).
  enum class Round { Regular, Inserting, Final, Done };
  const int totalRounds = params.passes + 2 * (params.insertVertices ? kInsertingRounds : 0);
  auto worstOf = [&](const std::vector<uint32_t>& ts) {
    double w = 180;
    for (uint32_t t : ts) w = std::min(w, m.quality(t));
    return w;
  };
  bool inserting = false;  // the round may insert vertices
  // The operations that change the connectivity around tet t (see runRounds); their new tets go
  // to `fresh`. True when one was applied.
  auto reconnect = [&](uint32_t t) {
    bool changed = false;
    // Peeling costs volume: a tet at or above the warning angle tries the flips first.
    const bool flattest =
        params.minDihedralWarning <= 0 || m.quality(t) < params.minDihedralWarning;
    auto tryPeel = [&] {
      if (!changed && peel(m, t, params, flattest ? 1.0 : 0.75, interfaces, fresh)) {
        ++r.peeledTets;
        changed = true;
      }
    };
    if (flattest) tryPeel();
    if (!changed) {  // the best of the six edge removals is not searched: first that helps
      const auto T = m.tets[t];
      for (int i = 0; i < 4 && !changed; ++i)
        for (int j = i + 1; j < 4 && !changed; ++j)
          if (removeEdge(m, t, T[size_t(i)], T[size_t(j)], fresh)) {
            ++r.edgeRemovals;
            changed = true;
          }
    }
    for (int k = 0; k < 4 && !changed; ++k)
      if (flipFace(m, t, k, fresh)) {
        ++r.faceFlips;
        changed = true;
      }
    if (!flattest) tryPeel();
    if (!changed && params.moveInterfaces && interfaces.enabled() &&
        flipInterfaceEdge(m, t, interfaces, fresh)) {
      ++r.interfaceFlips;
      changed = true;
    }
    if (!changed && params.moveInterfaces && interfaces.enabled() &&
        relabelFlatTet(m, t, interfaces, params.peelDistance * params.voxelSize, fresh)) {
      ++r.relabelledTets;
      changed = true;
    }
    if (!changed && params.collapseEdges &&
        collapseEdge(m, t,
                     interfaces.enabled() ? interfaces.facetDistance : 0.1 * params.voxelSize,
                     interfaces, false, fresh)) {
      ++r.collapsedEdges;
      changed = true;
    }
    return changed;
  };
  // The operations of the inserting rounds for a tet nothing else helped; their new tets go to
  // `fresh`. True when one was applied.
  auto addVertices = [&](uint32_t t) {
    if (insertVertex(m, t, params.targetMinDihedral, 1, fresh) ||
        insertVertex(m, t, params.targetMinDihedral, 2, fresh) ||
        insertVertex(m, t, params.targetMinDihedral, 3, fresh)) {
      ++r.insertedVertices;
      return true;
    }
    if (params.splitEdges && splitEdge(m, t, params, interfaces, fresh)) {
      ++r.splitEdges;
      return true;
    }
    // Any edge of the tet may go when every interface triangle then left around its kept end
    // lies within the facet distance.
    if (params.collapseEdges && params.moveInterfaces && interfaces.enabled() &&
        collapseEdge(m, t, kLongCollapse * interfaces.facetDistance, interfaces, true, fresh)) {
      ++r.collapsedEdges;
      return true;
    }
    // Last resort for a tet whose vertices lie on interfaces: one of them may leave its
    // interface by up to 0.95 × the facet distance.
    if (params.moveInterfaces && interfaces.enabled())
      for (int32_t v : m.tets[t]) {
        int kind = 0;
        if (smoothInterfaceVertex(m, v, interfaces, kind,
                                  kOffInterfaceShare * interfaces.facetDistance)) {
          ++r.offInterfaceMoves;
          for (uint32_t s : m.around[size_t(v)]) fresh.push_back(s);
          return true;
        }
      }
    return false;
  };
  const bool speculate = resolveThreads(ctx.threads()) > 1;
  std::vector<uint32_t> waiting;
  std::vector<TetMoves> found;
  // `regular` regular rounds (until nothing changes), then `insertingRounds` times an inserting
  // round and a final one, over `queue`.
  auto runRounds = [&](int regular, int insertingRounds) {
    Round round = Round::Regular;
    int regularLeft = regular;
    int insertingLeft = params.insertVertices ? insertingRounds : 0;
    for (int pass = 0; round != Round::Done && regularLeft > 0 && !queue.empty(); ++pass) {
      ++r.passes;
      inserting = round == Round::Inserting;
      m.hullAscent = inserting;
      std::vector<std::pair<double, uint32_t>> order;
      for (uint32_t t : queue)
        if (m.alive[t]) order.emplace_back(m.quality(t), t);
      std::sort(order.begin(), order.end());
      queue.clear();
      size_t changes = 0, done = 0;
      // The tets below the target, worst first, kMoveBatch at a time: each gets the operations
      // that change the mesh's connectivity (peeling, edge removal, flips, relabelling,
      // collapses); those none of them helped then get their vertex moves, in the same order,
      // and in the inserting rounds the operations that add vertices after that. The moves are
      // found ahead on several threads (findTetMoves, on copies of the stars) and used where
      // still valid (tetMovesHold), so the mesh does not depend on the thread count.
      for (size_t batch = 0; batch < order.size(); batch += kMoveBatch) {
        const size_t batchEnd = std::min(order.size(), batch + kMoveBatch);
        waiting.clear();
        for (size_t at = batch; at < batchEnd; ++at) {
          const uint32_t t = order[at].second;
          if ((++done & 0xFF) == 0) {
            ctx.progress(
                std::min(1.0, (double(pass) + double(done) / double(order.size())) / totalRounds));
          }
          if (!m.alive[t] || !bad(t)) continue;
          fresh.clear();
          const bool changed = reconnect(t);
          if (!changed && (params.smooth || inserting)) {
            waiting.push_back(t);
            continue;
          }
          if (changed) ++changes;
          for (uint32_t s : fresh)
            if (m.alive[s] && bad(s)) queue.push_back(s);
        }
        if (speculate && params.smooth) {
          if (found.size() < waiting.size()) found.resize(waiting.size());
          parallelFor(
              waiting.size(), ctx.threads(),
              [&](size_t lo, size_t hi, int) {
                for (size_t i = lo; i < hi; ++i) {
                  found[i].made = false;
                  if (m.alive[waiting[i]] && bad(waiting[i]))
                    findTetMoves(m, waiting[i], params, interfaces, found[i]);
                }
              },
              kMoveChunks);
        }
        ++m.stamp;  // what changes from here on, the moves found above did not see
        for (size_t i = 0; i < waiting.size(); ++i) {
          const uint32_t t = waiting[i];
          if (!m.alive[t] || !bad(t)) continue;
          fresh.clear();
          bool changed = false;
          if (params.smooth) {
            if (speculate && tetMovesHold(m, t, found[i])) {
              changed = applyTetMoves(m, t, found[i], r, fresh);
            } else {
              for (int32_t v : m.tets[t])
                if (moveVertex(m, v, params, interfaces, r)) {
                  changed = true;
                  for (uint32_t s : m.around[size_t(v)]) fresh.push_back(s);
                }
            }
            if (m.alive[t] && m.quality(t) < params.targetMinDihedral && changed) queue.push_back(t);
          }
          if (!changed && inserting) changed = addVertices(t);
          if (changed) ++changes;
          for (uint32_t s : fresh)
            if (m.alive[s] && bad(s)) queue.push_back(s);
        }
      }
      ctx.checkCancel();
      std::sort(queue.begin(), queue.end());
      queue.erase(std::unique(queue.begin(), queue.end()), queue.end());
      if (round == Round::Inserting) {
        round = Round::Final;
      } else if (round == Round::Final || --regularLeft == 0 || changes == 0) {
        regularLeft = 1;
        round = insertingLeft-- > 0 ? Round::Inserting : Round::Done;
        if (round == Round::Inserting) everyBadTet();
      }
    }
  };
  runRounds(params.passes, kInsertingRounds);
  // Coarsening comes last: it never lowers the worst tet of a star it changes, so the rounds'
  // result stands, and it cannot take away the interior vertices the rounds needed.
  r.coarsenedVertices = coarsenInterior(m, params, ctx.threads());
  // The tets the rounds could not mend get the rounds again, now in their coarsened
  // neighbourhood, while that helps (once: colin27 10.4 -> 12.0, example_seg_dicom 12.8 -> 14.5
  // degrees). Without vertex insertion they would only be more regular rounds: those stop where
  // they are.
  if (params.insertVertices) {
    for (int again = 0; again < kRescueTimes; ++again) {
      everyBadTet();
      if (queue.empty()) break;
      const double worstBefore = worstOf(queue);
      const size_t badBefore = queue.size();
      runRounds(params.passes, kRescueRounds);
      everyBadTet();
      if (queue.empty() || !(worstOf(queue) > worstBefore + kEps || queue.size() < badBefore)) break;
    }
  }
  // The last resort: a tet still below the warning angle with a face on the outer boundary goes
  // (with the specks it cuts off) even beyond the peeling budget: a flat element is worse for a
  // solver than a small material losing a speck more (a box-sized label of 133 tets whose flat
  // corner tet held 0.6 mm^3 of specks, 0.8 % of it, in a random volume).
  const BelowAngle belowWarning(params.minDihedralWarning);
  for (int again = 0; again < kRescueTimes && params.minDihedralWarning > 0; ++again) {
    auto flat = parallelCollect<std::pair<double, uint32_t>>(
        tets.size(), ctx.threads(), kScanChunks,
        [&](size_t begin, size_t end, std::vector<std::pair<double, uint32_t>>& found) {
          for (size_t t = begin; t < end; ++t)
            if (m.alive[t] && belowWarning(m.qualityCos(m.tets[t])))
              found.emplace_back(m.quality(uint32_t(t)), uint32_t(t));
        });
    std::sort(flat.begin(), flat.end());
    size_t peeled = 0;
    for (const auto& [q, t] : flat)
      if (m.alive[t] && m.quality(t) < params.minDihedralWarning &&
          peel(m, t, params, 1.0, interfaces, fresh, true))
        ++peeled;
    r.overBudgetPeels += peeled;
    r.peeledTets += peeled;
    if (peeled == 0) break;
  }
  // Every operation keeps each triangle shared by at most two tets; should one not have (a vertex
  // insertion into a cavity that touched itself did so on the thin rod until sphereShell), the
  // run stops here rather than write a mesh that is not conformal.
  const auto overShared = parallelCollect<uint32_t>(
      tets.size(), ctx.threads(), kScanChunks,
      [&](size_t begin, size_t end, std::vector<uint32_t>& found) {
        for (size_t t = begin; t < end; ++t) {
          if (!m.alive[t]) continue;
          for (int k = 0; k < 4; ++k) {
            const auto f = m.face(uint32_t(t), k);
            int holders = 0;
            for (uint32_t s : m.around[size_t(f[0])]) holders += m.has(s, f[1]) && m.has(s, f[2]);
            if (holders > 2) {
              found.push_back(uint32_t(t));
              break;
            }
          }
        }
      });
  if (!overShared.empty())
    throw Error(ErrorCode::MeshingFailed,
                "Optimize left " + std::to_string(overShared.size()) +
                    " tet(s) with a triangle shared by three or more tets: the mesh is not "
                    "conformal and is not written. For a mesh given to `femesher optimize`, "
                    "check that it was conformal; otherwise this is a bug (please report it with "
                    "the label map), and --set optimize_min_dihedral=0 skips the improvement "
                    "(the mesh then keeps TetGen's flat tets).");
  // Compact: alive tets, used points (order kept).
  std::vector<char> dead(tets.size());
  for (size_t t = 0; t < tets.size(); ++t) dead[t] = !m.alive[t];
  eraseTets(points, tets, labels, dead);
}


}  // namespace

OptimizeResult optimizeTetMesh(std::vector<Vec3>& points, std::vector<std::array<int32_t, 4>>& tets,
                               std::vector<int32_t>& labels, const OptimizeParameters& params,
                               RunContext& ctx) {
  return optimizeTetMesh(points, tets, labels, params, OptimizeInterfaces{}, ctx);
}

OptimizeResult optimizeTetMesh(std::vector<Vec3>& points, std::vector<std::array<int32_t, 4>>& tets,
                               std::vector<int32_t>& labels, const OptimizeParameters& params,
                               const OptimizeInterfaces& interfaces, RunContext& ctx) {
  OptimizeResult r;
  auto survey = [&](size_t& below, size_t& below5, double& mn) {
    below = below5 = 0;
    mn = tets.empty() ? 0 : 1e300;
    // The worst angle from the largest cosine (acos is monotone).
    const BelowAngle belowTarget(params.targetMinDihedral), below5Degrees(5);
    std::vector<double> chunkMax(kScanChunks, -1);
    std::vector<size_t> chunkBelow(kScanChunks, 0), chunkBelow5(kScanChunks, 0);
    parallelFor(
        tets.size(), ctx.threads(),
        [&](size_t begin, size_t end, int chunk) {
          for (size_t t = begin; t < end; ++t) {
            const auto& T = tets[t];
            const double c = tetMaxDihedralCos(points[size_t(T[0])], points[size_t(T[1])],
                                               points[size_t(T[2])], points[size_t(T[3])]);
            chunkMax[size_t(chunk)] = std::max(chunkMax[size_t(chunk)], c);
            chunkBelow[size_t(chunk)] += belowTarget(c);
            chunkBelow5[size_t(chunk)] += below5Degrees(c);
          }
        },
        kScanChunks);
    double cMax = -1;
    for (int c = 0; c < kScanChunks; ++c) {
      cMax = std::max(cMax, chunkMax[size_t(c)]);
      below += chunkBelow[size_t(c)];
      below5 += chunkBelow5[size_t(c)];
    }
    if (!tets.empty()) mn = std::max(0.0, cosToDegrees(cMax));
  };
  survey(r.tetsBelowTargetBefore, r.tetsBelow5Before, r.minDihedralBefore);
  const bool coarsen = params.coarsenMinDihedral > 0 && params.sizeAt;
  if (params.targetMinDihedral > 0 && (r.tetsBelowTargetBefore > 0 || coarsen)) {
    // The specks that go in the end whatever their tets (lighter than minFragmentVoxels: they go
    // without the stage too) go first, so that the rounds do not work on them. (The heavier ones
    // with a flat tet may be mended by the rounds and then stay.)
    if (params.minFragmentVoxels > 0)
      removeFragments(points, tets, labels, params.minFragmentVoxels * params.voxelVolume,
                      params.minFragmentVoxels * params.voxelVolume, 0, ctx.threads(), r);
    improve(points, tets, labels, params, interfaces, ctx, r);
  }
  if (params.minFragmentVoxels > 0)
    removeFragments(points, tets, labels, params.minFragmentVoxels * params.voxelVolume,
                    kBadFragmentFactor * params.minFragmentVoxels * params.voxelVolume,
                    params.targetMinDihedral, ctx.threads(), r);
  survey(r.tetsBelowTargetAfter, r.tetsBelow5After, r.minDihedralAfter);
  ctx.progress(1.0);
  return r;
}


ReportCounts reportCounts(const OptimizeResult& r) {
  return {{"optimize_tets_below_target_before", double(r.tetsBelowTargetBefore)},
          {"optimize_tets_below_target_after", double(r.tetsBelowTargetAfter)},
          {"optimize_tets_below_5deg_before", double(r.tetsBelow5Before)},
          {"optimize_tets_below_5deg_after", double(r.tetsBelow5After)},
          {"optimize_min_dihedral_before", r.minDihedralBefore},
          {"optimize_min_dihedral_after", r.minDihedralAfter},
          {"optimize_edge_removals", double(r.edgeRemovals)},
          {"optimize_face_flips", double(r.faceFlips)},
          {"optimize_smoothed_vertices", double(r.smoothedVertices)},
          {"optimize_interface_vertex_moves", double(r.interfaceVertices)},
          {"optimize_triple_line_vertex_moves", double(r.tripleLineVertices)},
          {"optimize_junction_vertex_moves", double(r.junctionVertices)},
          {"optimize_off_interface_moves", double(r.offInterfaceMoves)},
          {"optimize_interface_flips", double(r.interfaceFlips)},
          {"optimize_peeled_tets", double(r.peeledTets)},
          {"optimize_over_budget_peels", double(r.overBudgetPeels)},
          {"optimize_relabelled_tets", double(r.relabelledTets)},
          {"optimize_inserted_vertices", double(r.insertedVertices)},
          {"optimize_collapsed_edges", double(r.collapsedEdges)},
          {"optimize_split_edges", double(r.splitEdges)},
          {"optimize_coarsened_vertices", double(r.coarsenedVertices)},
          {"optimize_fragments_removed", double(r.fragments)},
          {"optimize_fragment_tets", double(r.fragmentTets)},
          {"optimize_fragment_volume_mm3", r.fragmentVolume},
          {"optimize_passes", double(r.passes)}};
}

}  // namespace femesher
