// SPDX-License-Identifier: GPL-3.0-or-later
// 10-node tetrahedra from a linear tet mesh: one shared mid-edge node per unique edge.
#include <femesher/Status.h>
#include <femesher/io/QuadraticTets.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace femesher {

uint64_t tetEdgeKey(int32_t a, int32_t b) {
  const uint32_t lo = uint32_t(std::min(a, b)), hi = uint32_t(std::max(a, b));
  return (uint64_t(lo) << 32) | hi;
}

const std::array<std::array<double, 3>, 11> kTet10CheckPoints{{{{0, 0, 0}},
                                                               {{1, 0, 0}},
                                                               {{0, 1, 0}},
                                                               {{0, 0, 1}},
                                                               {{0.5, 0, 0}},
                                                               {{0.5, 0.5, 0}},
                                                               {{0, 0.5, 0}},
                                                               {{0, 0, 0.5}},
                                                               {{0.5, 0, 0.5}},
                                                               {{0, 0.5, 0.5}},
                                                               {{0.25, 0.25, 0.25}}}};

double tet10JacobianDeterminant(const std::array<Vec3, 10>& x, double r, double s, double t) {
  const double u = 1 - r - s - t;
  // Derivatives of N0 = u(2u-1), N1 = r(2r-1), N2 = s(2s-1), N3 = t(2t-1), N4 = 4ru, N5 = 4rs,
  // N6 = 4su, N7 = 4tu, N8 = 4rt, N9 = 4st by r, s and t.
  const double dr[10] = {1 - 4 * u, 4 * r - 1, 0, 0, 4 * (u - r), 4 * s, -4 * s, -4 * t, 4 * t, 0};
  const double ds[10] = {1 - 4 * u, 0, 4 * s - 1, 0, -4 * r, 4 * r, 4 * (u - s), -4 * t, 0, 4 * t};
  const double dt[10] = {1 - 4 * u, 0, 0, 4 * t - 1, -4 * r, 0, -4 * s, 4 * (u - t), 4 * r, 4 * s};
  double J[3][3] = {};
  for (size_t a = 0; a < 10; ++a)
    for (size_t c = 0; c < 3; ++c) {
      J[c][0] += dr[a] * x[a][c];
      J[c][1] += ds[a] * x[a][c];
      J[c][2] += dt[a] * x[a][c];
    }
  return J[0][0] * (J[1][1] * J[2][2] - J[1][2] * J[2][1]) -
         J[0][1] * (J[1][0] * J[2][2] - J[1][2] * J[2][0]) +
         J[0][2] * (J[1][0] * J[2][1] - J[1][1] * J[2][0]);
}

Tet10Jacobian tet10Jacobian(const std::array<Vec3, 10>& x) {
  const double inf = std::numeric_limits<double>::infinity();
  Vec3 e[3];
  for (size_t k = 0; k < 3; ++k)
    for (size_t c = 0; c < 3; ++c) e[k][c] = x[k + 1][c] - x[0][c];
  const double straight = e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) -
                          e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
                          e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
  if (!(straight > 0)) return {-inf, -inf};
  double lo = inf, hi = -inf;
  for (const auto& p : kTet10CheckPoints) {
    const double d = tet10JacobianDeterminant(x, p[0], p[1], p[2]);
    lo = std::min(lo, d);
    hi = std::max(hi, d);
  }
  return {lo / straight, hi > 0 ? lo / hi : -inf};
}

Tet10Jacobian worstTet10Jacobian(const std::vector<Vec3>& points,
                                 const std::vector<std::array<int32_t, 10>>& tets) {
  Tet10Jacobian worst;
  std::array<Vec3, 10> x;
  for (const auto& t : tets) {
    for (size_t k = 0; k < 10; ++k) x[k] = points[size_t(t[k])];
    const Tet10Jacobian j = tet10Jacobian(x);
    worst.minOverStraight = std::min(worst.minOverStraight, j.minOverStraight);
    worst.minOverMax = std::min(worst.minOverMax, j.minOverMax);
  }
  return worst;
}

int32_t QuadraticTetMesh::midNode(int32_t a, int32_t b) const {
  const auto it = edgeNodes.find(tetEdgeKey(a, b));
  if (it == edgeNodes.end())
    throw Error(ErrorCode::Internal, "Quadratic mesh: vertices " + std::to_string(a) + " and " +
                                         std::to_string(b) + " are not joined by a tet edge.");
  return it->second;
}

QuadraticTetMesh quadraticTets(const TetMesh& m, const MidEdgePositions* curved) {
  QuadraticTetMesh q;
  q.cornerCount = m.points.size();
  q.points = m.points;
  q.points.reserve(m.points.size() + m.tets.size() * 2);
  q.edgeNodes.reserve(m.tets.size() * 2);
  q.tets.reserve(m.tets.size());
  size_t used = 0;
  for (const auto& t : m.tets) {
    std::array<int32_t, 10> e{};
    for (int k = 0; k < 4; ++k) e[size_t(k)] = t[size_t(k)];
    for (size_t k = 0; k < kTet10Edges.size(); ++k) {
      const int32_t a = t[size_t(kTet10Edges[k][0])], b = t[size_t(kTet10Edges[k][1])];
      const auto [it, added] = q.edgeNodes.emplace(tetEdgeKey(a, b), int32_t(q.points.size()));
      if (added) {
        const auto c = curved ? curved->find(it->first) : MidEdgePositions::const_iterator{};
        if (curved && c != curved->end()) {
          q.points.push_back(c->second);
          ++used;
        } else {
          const Vec3 &pa = m.points[size_t(a)], &pb = m.points[size_t(b)];
          q.points.push_back(
              {{0.5 * (pa[0] + pb[0]), 0.5 * (pa[1] + pb[1]), 0.5 * (pa[2] + pb[2])}});
        }
      }
      e[4 + k] = it->second;
    }
    q.tets.push_back(e);
  }
  if (curved && used != curved->size())
    throw Error(ErrorCode::Internal, "Quadratic mesh: " + std::to_string(curved->size() - used) +
                                         " curved mid-edge nodes belong to edges the mesh does "
                                         "not have (export a mesh with its own run's nodes).");
  return q;
}

}  // namespace femesher
