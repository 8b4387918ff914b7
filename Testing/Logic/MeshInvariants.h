// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Invariant checks shared by the meshing tests: conformity, orientation, labels, extent,
// material volumes, interface triangles; and the expected-error check.
#include <femesher/Status.h>
#include <femesher/RunContext.h>
#include <femesher/Types.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <unordered_map>

namespace femesher::testing {

/// Path of a real data file; in CI a missing file fails the test, elsewhere it skips.
inline std::string dataFile(const std::string& name) { return std::string(FEMESHER_DATA_DIR) + "/" + name; }
inline bool inCI() {
  const char* ci = std::getenv("CI");
  return ci && std::string(ci) == "true";
}

/// Every face shared by at most two tets; every tet positive; each interior face between two tets
/// of different labels is an interface (trivially), and no face is used by >2 tets.
inline void expectConformal(const TetMesh& m) {
  ASSERT_EQ(m.tets.size(), m.tetLabels.size());
  size_t inverted = 0;
  for (size_t t = 0; t < m.tets.size(); ++t)
    if (!(m.tetVolume(t) > 0)) ++inverted;
  EXPECT_EQ(inverted, 0u) << "inverted or flat tets";
  std::map<std::array<int32_t, 3>, int> faces;
  for (const auto& T : m.tets) {
    for (int f = 0; f < 4; ++f) {
      std::array<int32_t, 3> k{T[(f + 1) % 4], T[(f + 2) % 4], T[(f + 3) % 4]};
      std::sort(k.begin(), k.end());
      ++faces[k];
    }
  }
  size_t over = 0;
  for (const auto& kv : faces) over += kv.second > 2;
  EXPECT_EQ(over, 0u) << "faces shared by more than two tets";
  std::vector<InterfaceTriangle> tris;
  ASSERT_NO_THROW(tris = extractInterfaces(m));
  for (const auto& t : tris)
    if (t.labelB != kExteriorLabel) EXPECT_NE(t.labelA, t.labelB);
  // Point usage: every point belongs to a tet.
  std::vector<char> used(m.points.size(), 0);
  for (const auto& T : m.tets)
    for (int v : T) used[size_t(v)] = 1;
  EXPECT_EQ(size_t(std::count(used.begin(), used.end(), 0)), 0u) << "unused points";
}

/// All mesh points within `tol` voxels of the index-space bounding box of the labelled voxels.
inline void expectWithinLabelExtent(const TetMesh& m, const LabelVolume& v, double tol = 1.5) {
  // tol is measured from the outermost labelled voxel centres: 0.5 = the labels' physical extent,
  // 1.5 = one voxel beyond it.
  std::array<int, 3> lo{{v.dims[0], v.dims[1], v.dims[2]}}, hi{{-1, -1, -1}};
  const bool all = v.hasNoBackground();
  for (int k = 0; k < v.dims[2]; ++k)
    for (int j = 0; j < v.dims[1]; ++j)
      for (int i = 0; i < v.dims[0]; ++i)
        if (all || v.at(i, j, k) != 0) {
          lo = {std::min(lo[0], i), std::min(lo[1], j), std::min(lo[2], k)};
          hi = {std::max(hi[0], i), std::max(hi[1], j), std::max(hi[2], k)};
        }
  size_t outside = 0;
  double worst = 0;
  for (const auto& p : m.points) {
    const Vec3 ijk = v.physicalToIndex(p);
    for (int a = 0; a < 3; ++a) {
      const double d = std::max(lo[a] - ijk[a], ijk[a] - hi[a]);
      worst = std::max(worst, d);
      if (d > tol) ++outside;
    }
  }
  EXPECT_EQ(outside, 0u) << "points beyond the label extent; worst " << worst << " voxels";
}

/// Labels of the mesh (set).
inline std::set<int32_t> meshLabels(const TetMesh& m) {
  return std::set<int32_t>(m.tetLabels.begin(), m.tetLabels.end());
}

/// Volume of the tets of each label.
inline std::map<int32_t, double> labelVolumes(const TetMesh& m) {
  std::map<int32_t, double> vol;
  for (size_t t = 0; t < m.tets.size(); ++t) vol[m.tetLabels[t]] += m.tetVolume(t);
  return vol;
}

/// A triangle by its geometry: the label pair (smaller first; `exterior` stands for
/// kExteriorLabel) and the three vertex positions, sorted.
struct TriangleKey {
  std::pair<int32_t, int32_t> labels;
  std::array<Vec3, 3> corners;
  bool operator<(const TriangleKey& o) const {
    return std::tie(labels, corners) < std::tie(o.labels, o.corners);
  }
  bool operator==(const TriangleKey& o) const { return labels == o.labels && corners == o.corners; }
};

inline TriangleKey triangleKey(int32_t a, int32_t b, const Vec3& p, const Vec3& q, const Vec3& r) {
  TriangleKey k{{std::min(a, b), std::max(a, b)}, {{p, q, r}}};
  std::sort(k.corners.begin(), k.corners.end());
  return k;
}

/// Every interface triangle of a mesh (extractInterfaces) by its geometry, the outer boundary
/// with label `exterior`.
inline std::set<TriangleKey> interfaceTriangleKeys(const TetMesh& m, int32_t exterior) {
  std::set<TriangleKey> out;
  for (const auto& t : extractInterfaces(m))
    out.insert(triangleKey(t.labelA, t.labelB == kExteriorLabel ? exterior : t.labelB,
                           m.points[size_t(t.v[0])], m.points[size_t(t.v[1])],
                           m.points[size_t(t.v[2])]));
  return out;
}

/// Runs `fn`, expects it to throw femesher::Error with `code`; returns the error's message.
template <class Fn>
std::string expectError(ErrorCode code, Fn&& fn) {
  try {
    fn();
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), code) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "expected the error " << errorCodeName(code);
  return {};
}

/// A run context for calling a stage outside a run (no callbacks, all threads).
inline RunContext& quietContext() {
  static RunContext ctx;
  return ctx;
}

}  // namespace femesher::testing
