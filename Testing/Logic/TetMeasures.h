// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Measures of a bare tet mesh (points, tets, one label per tet) for the Optimize tests.
#include <femesher/VecMath.h>
#include <femesher/stages/Optimize.h>

#include <algorithm>
#include <array>
#include <map>
#include <vector>

namespace femesher::test {

using Tets = std::vector<std::array<int32_t, 4>>;

/// The smallest minimum dihedral angle (degrees) of the tets; -1 when one is inverted or flat.
inline double minOver(const std::vector<Vec3>& p, const Tets& t) {
  double q = 1e300;
  for (const auto& T : t) q = std::min(q, tetMinDihedral(p[T[0]], p[T[1]], p[T[2]], p[T[3]]));
  return q;
}

/// Signed volume (mm^3) per label.
inline std::map<int32_t, double> labelVolumes(const std::vector<Vec3>& p, const Tets& t,
                                              const std::vector<int32_t>& labels) {
  std::map<int32_t, double> v;
  for (size_t i = 0; i < t.size(); ++i) {
    const Vec3 &a = p[t[i][0]], &b = p[t[i][1]], &c = p[t[i][2]], &d = p[t[i][3]];
    v[labels[i]] += dot(cross(sub(b, a), sub(c, a)), sub(d, a)) / 6;
  }
  return v;
}

}  // namespace femesher::test
