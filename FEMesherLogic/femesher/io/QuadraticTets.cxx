// SPDX-License-Identifier: GPL-3.0-or-later
// 10-node tetrahedra from a linear tet mesh: one shared mid-edge node per unique edge.
#include <femesher/Status.h>
#include <femesher/io/QuadraticTets.h>

#include <algorithm>
#include <string>

namespace femesher {

namespace {

uint64_t edgeKey(int32_t a, int32_t b) {
  const uint32_t lo = uint32_t(std::min(a, b)), hi = uint32_t(std::max(a, b));
  return (uint64_t(lo) << 32) | hi;
}

}  // namespace

int32_t QuadraticTetMesh::midNode(int32_t a, int32_t b) const {
  const auto it = edgeNodes.find(edgeKey(a, b));
  if (it == edgeNodes.end())
    throw Error(ErrorCode::Internal, "Quadratic mesh: vertices " + std::to_string(a) + " and " +
                                         std::to_string(b) + " are not joined by a tet edge.");
  return it->second;
}

QuadraticTetMesh quadraticTets(const TetMesh& m) {
  QuadraticTetMesh q;
  q.cornerCount = m.points.size();
  q.points = m.points;
  q.points.reserve(m.points.size() + m.tets.size() * 2);
  q.edgeNodes.reserve(m.tets.size() * 2);
  q.tets.reserve(m.tets.size());
  for (const auto& t : m.tets) {
    std::array<int32_t, 10> e{};
    for (int k = 0; k < 4; ++k) e[size_t(k)] = t[size_t(k)];
    for (size_t k = 0; k < kTet10Edges.size(); ++k) {
      const int32_t a = t[size_t(kTet10Edges[k][0])], b = t[size_t(kTet10Edges[k][1])];
      const auto [it, added] = q.edgeNodes.emplace(edgeKey(a, b), int32_t(q.points.size()));
      if (added) {
        const Vec3 &pa = m.points[size_t(a)], &pb = m.points[size_t(b)];
        q.points.push_back({{0.5 * (pa[0] + pb[0]), 0.5 * (pa[1] + pb[1]), 0.5 * (pa[2] + pb[2])}});
      }
      e[4 + k] = it->second;
    }
    q.tets.push_back(e);
  }
  return q;
}

}  // namespace femesher
