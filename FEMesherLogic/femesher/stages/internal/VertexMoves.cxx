// SPDX-License-Identifier: GPL-3.0-or-later
// Vertex moves of the Optimize stage's rounds (OptimizeEditor.h): a vertex moved by its class, and
// the moves of a tet's four vertices found ahead on a copy of their stars.
#include <femesher/VecMath.h>
#include <femesher/stages/internal/OptimizeEditor.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace femesher {
namespace optimize_detail {

namespace {

/// For a vertex on constrained faces: true when all of them are outer-boundary faces of one
/// material (no interface between two materials holds v) and their vertices lie within
/// `tolerance` of one plane through v, whose unit normal goes to `normal`. Such a vertex may
/// slide in that plane: the outer boundary moves by at most `tolerance`.
bool flatPatch(const Editor& m, int32_t v, double tolerance, Vec3& normal) {
  if (tolerance <= 0) return false;
  int32_t material = -1;
  Vec3 n{0, 0, 0};
  std::vector<int32_t> ring;
  for (uint32_t t : m.around[size_t(v)])
    for (int k = 0; k < 4; ++k) {
      if (m.tets[t][size_t(k)] == v) continue;
      const auto f = m.face(t, k);
      const int64_t s = m.across(t, f[0], f[1], f[2]);
      if (s >= 0 && m.labels[size_t(s)] == m.labels[t]) continue;
      if (s >= 0 || (material >= 0 && material != m.labels[t])) return false;
      material = m.labels[t];
      // Outward normal of the face seen from t (the vertex opposite lies behind it).
      const Vec3 &A = m.pts[size_t(f[0])], &B = m.pts[size_t(f[1])], &C = m.pts[size_t(f[2])];
      Vec3 fn = cross(sub(B, A), sub(C, A));
      if (dot(fn, sub(m.pts[size_t(m.tets[t][size_t(k)])], A)) > 0)
        for (double& x : fn) x = -x;
      for (int a = 0; a < 3; ++a) n[a] += fn[a];
      ring.insert(ring.end(), f.begin(), f.end());
    }
  const double len = norm(n);
  if (ring.empty() || !(len > 0)) return false;
  for (double& x : n) x /= len;
  const Vec3& P = m.pts[size_t(v)];
  for (int32_t w : ring)
    if (std::fabs(dot(sub(m.pts[size_t(w)], P), n)) > tolerance) return false;
  normal = n;
  return true;
}

}  // namespace

bool moveVertex(Editor& m, int32_t v, const OptimizeParameters& params,
                const OptimizeInterfaces& interfaces, OptimizeResult& r) {
  bool moved = false;
  if (!m.fixedVertex(v)) {
    moved = smoothVertex(m, v, nullptr);
  } else {
    int kind = 0;
    if (params.moveInterfaces && interfaces.enabled() &&
        smoothInterfaceVertex(m, v, interfaces, kind)) {
      ++(kind == 4 ? r.junctionVertices : kind == 3 ? r.tripleLineVertices : r.interfaceVertices);
      return true;
    }
    Vec3 normal;
    if (kind == 0 && flatPatch(m, v, 1e-4 * (params.peelDistance * params.voxelSize), normal)) {
      MoveConstraint inPlane;
      inPlane.tangent = [normal](const Vec3& d) {
        const double x = dot(d, normal);
        return Vec3{d[0] - x * normal[0], d[1] - x * normal[1], d[2] - x * normal[2]};
      };
      moved = smoothVertex(m, v, &inPlane);
    }
  }
  r.smoothedVertices += moved;
  return moved;
}

void findTetMoves(const Editor& m, uint32_t t, const OptimizeParameters& params,
                  const OptimizeInterfaces& interfaces, TetMoves& out) {
  // One copy per thread, its memory kept from tet to tet.
  struct Copy {
    std::vector<Vec3> pts;
    std::vector<std::array<int32_t, 4>> tets;
    std::vector<int32_t> labels, vertexOf, localOf;  // localOf: per mesh vertex, -1 if not copied
    // Copied tet of a mesh tet: open addressing on the mesh tet's id (slots hold copied tet + 1).
    std::vector<std::pair<uint32_t, uint32_t>> slots;
    Editor editor{pts, tets, labels};
  };
  thread_local Copy c;
  c.pts.clear();
  c.tets.clear();
  c.labels.clear();
  c.vertexOf.clear();
  if (c.localOf.size() < m.pts.size()) c.localOf.resize(m.pts.size(), -1);
  auto vertex = [&](int32_t w) {
    int32_t& l = c.localOf[size_t(w)];
    if (l < 0) {
      l = int32_t(c.vertexOf.size());
      c.vertexOf.push_back(w);
      c.pts.push_back(m.pts[size_t(w)]);
    }
    return l;
  };
  const auto T = m.tets[t];
  size_t starTets = 0;
  for (int32_t v : T) starTets += m.around[size_t(v)].size();
  size_t mask = 255;
  while (mask + 1 < 2 * starTets) mask = 2 * mask + 1;
  c.slots.assign(mask + 1, {0, 0});
  auto slotOf = [&](uint32_t s) {
    size_t h = (size_t(s) * 0x9E3779B1u) & mask;
    while (c.slots[h].second != 0 && c.slots[h].first != s) h = (h + 1) & mask;
    return h;
  };
  for (int32_t v : T) vertex(v);
  for (int32_t v : T)
    for (uint32_t s : m.around[size_t(v)]) {
      auto& slot = c.slots[slotOf(s)];
      if (slot.second != 0) continue;
      slot = {s, uint32_t(c.tets.size()) + 1};
      std::array<int32_t, 4> L;
      for (int k = 0; k < 4; ++k) L[size_t(k)] = vertex(m.tets[s][size_t(k)]);
      c.tets.push_back(L);
      c.labels.push_back(m.labels[s]);
    }
  Editor& local = c.editor;
  const size_t nv = c.vertexOf.size();
  local.alive.assign(c.tets.size(), 1);
  if (local.around.size() < nv) local.around.resize(nv);
  local.fixedState.resize(nv);
  local.stamped.assign(nv, 0);
  for (size_t lw = 0; lw < nv; ++lw) {
    auto& star = local.around[lw];
    star.clear();
    for (uint32_t s : m.around[size_t(c.vertexOf[lw])]) {
      const auto& slot = c.slots[slotOf(s)];
      if (slot.second != 0) star.push_back(slot.second - 1);
    }
    local.fixedState[lw] = m.fixedState[size_t(c.vertexOf[lw])];
  }
  for (int32_t w : c.vertexOf) c.localOf[size_t(w)] = -1;
  local.perLabel = m.perLabel;
  local.startVolume = m.startVolume;
  local.movedVolume = m.movedVolume;
  local.peeledVolume = m.peeledVolume;
  local.hullAscent = m.hullAscent;
  local.junctionStart.clear();
  for (int i = 0; i < 4; ++i) {
    const auto it = m.junctionStart.find(T[size_t(i)]);
    if (it != m.junctionStart.end()) local.junctionStart.emplace(i, it->second);
  }
  out.log.clear();
  local.budgetLog = &out.log;
  out.counts = OptimizeResult();
  for (int i = 0; i < 4; ++i) {  // the four vertices are local vertices 0..3
    out.moved[size_t(i)] = moveVertex(local, i, params, interfaces, out.counts);
    out.to[size_t(i)] = local.pts[size_t(i)];
  }
  for (int i = 0; i < 4; ++i) {
    const auto it = local.junctionStart.find(i);
    out.junctionStarted[size_t(i)] =
        it != local.junctionStart.end() && !m.junctionStart.count(T[size_t(i)]);
    if (out.junctionStarted[size_t(i)]) out.junctionStart[size_t(i)] = it->second;
    out.fixedState[size_t(i)] = local.fixedState[size_t(i)];
  }
  out.made = true;
}

bool tetMovesHold(const Editor& m, uint32_t t, const TetMoves& found) {
  if (!found.made) return false;
  for (int32_t v : m.tets[t]) {
    if (!m.untouched(v)) return false;
    for (uint32_t s : m.around[size_t(v)])
      for (int32_t w : m.tets[s])
        if (!m.untouched(w)) return false;
  }
  return m.budgetsAgree(found.log);
}

bool applyTetMoves(Editor& m, uint32_t t, const TetMoves& found, OptimizeResult& r,
                   std::vector<uint32_t>& fresh) {
  const auto T = m.tets[t];
  bool changed = false;
  for (int i = 0; i < 4; ++i) {
    const int32_t v = T[size_t(i)];
    if (found.junctionStarted[size_t(i)]) m.junctionStart.emplace(v, found.junctionStart[size_t(i)]);
    // The stars did not change since: what was found of them on the copy holds.
    if (m.fixedState[size_t(v)] < 0) m.fixedState[size_t(v)] = found.fixedState[size_t(i)];
    if (m.pts[size_t(v)] != found.to[size_t(i)]) {
      m.pts[size_t(v)] = found.to[size_t(i)];
      m.touch(v);
    }
    if (found.moved[size_t(i)]) {
      changed = true;
      for (uint32_t s : m.around[size_t(v)]) fresh.push_back(s);
    }
  }
  m.replayBookings(found.log);
  r.smoothedVertices += found.counts.smoothedVertices;
  r.interfaceVertices += found.counts.interfaceVertices;
  r.tripleLineVertices += found.counts.tripleLineVertices;
  r.junctionVertices += found.counts.junctionVertices;
  return changed;
}

}  // namespace optimize_detail
}  // namespace femesher
