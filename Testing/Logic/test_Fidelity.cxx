// SPDX-License-Identifier: GPL-3.0-or-later
// Fidelity: Dice, volumes, boundary distances and missing labels against meshes built from the
// voxels themselves (each labelled voxel box split into 6 Kuhn tets, shared corners).
#include "MeshInvariants.h"
#include "TestShapes.h"

#include <femesher/RunContext.h>
#include <femesher/io/LabelMapIO.h>
#include <femesher/stages/Fidelity.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <map>
#include <set>

using namespace femesher;
using namespace femesher::testing;

namespace {

/// An all-background volume with the oblique, left-handed, anisotropic test geometry (spacing
/// 0.7 x 1.1 x 1.6 mm: x is the smallest spacing).
LabelVolume obliqueVolume(int nx, int ny, int nz) {
  return test::obliqueLeftHanded(
      test::makeVolume({nx, ny, nz}, {1, 1, 1}, [](double, double, double) { return 0; }));
}

/// Voxel-box mesh: every voxel whose label passes `keep` becomes a cube of 6 tets; the cube of
/// voxel v spans index coordinates v ± 0.5 (+ shift), with corners shared between cubes.
/// `block` > 1 meshes blocks of block³ voxels as one cube (they must be uniform).
TetMesh voxelMesh(const LabelVolume& v, const Vec3& shift = {0, 0, 0},
                  const std::set<int32_t>& drop = {}, int block = 1) {
  TetMesh m;
  const int cx = v.dims[0] / block + 1, cy = v.dims[1] / block + 1, cz = v.dims[2] / block + 1;
  std::vector<int32_t> pid(size_t(cx) * size_t(cy) * size_t(cz), -1);
  auto corner = [&](int i, int j, int k) {
    int32_t& id = pid[size_t(i) + size_t(cx) * (size_t(j) + size_t(cy) * size_t(k))];
    if (id < 0) {
      id = int32_t(m.points.size());
      m.points.push_back(v.indexToPhysical({i * block - 0.5 + shift[0], j * block - 0.5 + shift[1],
                                            k * block - 0.5 + shift[2]}));
    }
    return id;
  };
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k < v.dims[2] / block; ++k)
    for (int j = 0; j < v.dims[1] / block; ++j)
      for (int i = 0; i < v.dims[0] / block; ++i) {
        const int32_t l = v.at(i * block, j * block, k * block);
        if ((l == 0 && !v.hasNoBackground()) || drop.count(l)) continue;
        for (const auto& p : perms) {
          int c[3] = {i, j, k};
          std::array<int32_t, 4> T;
          T[0] = corner(c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) {
            ++c[p[s]];
            T[size_t(s) + 1] = corner(c[0], c[1], c[2]);
          }
          m.tets.push_back(T);
          m.tetLabels.push_back(l);
          if (m.tetVolume(m.tets.size() - 1) < 0) std::swap(m.tets.back()[2], m.tets.back()[3]);
        }
      }
  std::set<int32_t> ls(m.tetLabels.begin(), m.tetLabels.end());
  for (int32_t l : ls) m.materials.push_back({l, "label " + std::to_string(l), defaultLabelColor(l)});
  return m;
}

/// Three labels: a 4x4x4 block (3), a slab (5) touching it, a one-voxel-thick layer (9).
LabelVolume threeLabels() {
  LabelVolume v = obliqueVolume(9, 8, 7);
  for (int k = 0; k < 7; ++k)
    for (int j = 0; j < 8; ++j)
      for (int i = 0; i < 9; ++i) {
        int32_t l = 0;
        if (i >= 1 && i < 5 && j >= 1 && j < 5 && k >= 1 && k < 5) l = 3;
        else if (i >= 5 && i < 8 && j >= 0 && j < 6 && k >= 1 && k < 6) l = 5;
        else if (k == 6 && i < 6) l = 9;
        v.labels[v.index(i, j, k)] = l;
      }
  v.materials = {{3, "block", defaultLabelColor(3)}, {5, "slab", defaultLabelColor(5)},
                 {9, "layer", defaultLabelColor(9)}};
  return v;
}

const MaterialFidelity* find(const FidelityReport& r, int32_t label) {
  for (const auto& m : r.materials)
    if (m.label == label) return &m;
  return nullptr;
}

/// Expected Dice when the mesh label of voxel (i,j,k) is the label of voxel (i-1,j,k).
std::map<int32_t, double> diceOfShiftByOne(const LabelVolume& v) {
  std::map<int32_t, size_t> a, b, both;
  for (int k = 0; k < v.dims[2]; ++k)
    for (int j = 0; j < v.dims[1]; ++j)
      for (int i = 0; i < v.dims[0]; ++i) {
        const int32_t l = v.at(i, j, k), m = i > 0 ? v.at(i - 1, j, k) : 0;
        ++a[l];
        ++b[m];
        if (l == m) ++both[l];
      }
  std::map<int32_t, double> d;
  for (const auto& [l, n] : a)
    if (l != 0) d[l] = 2.0 * double(both[l]) / double(n + b[l]);
  return d;
}

/// Expected volume Dice when every voxel box moves by `frac` of a voxel along index axis `axis`:
/// a voxel keeps (1 - frac) of itself and overlaps `frac` of its + neighbour, which counts when
/// that neighbour has the same label (the moved volume is the voxel volume, unchanged).
std::map<int32_t, double> volumeDiceOfShift(const LabelVolume& v, int axis, double frac) {
  std::map<int32_t, double> n, overlap;
  for (int k = 0; k < v.dims[2]; ++k)
    for (int j = 0; j < v.dims[1]; ++j)
      for (int i = 0; i < v.dims[0]; ++i) {
        int q[3] = {i, j, k};
        ++q[axis];
        const int32_t l = v.at(i, j, k);
        n[l] += 1;
        overlap[l] += 1 - frac;
        if (v.inside(q[0], q[1], q[2]) && v.at(q[0], q[1], q[2]) == l) overlap[l] += frac;
      }
  std::map<int32_t, double> d;
  for (const auto& [l, count] : n)
    if (l != 0) d[l] = overlap[l] / count;
  return d;
}

}  // namespace

TEST(Fidelity, ExactVoxelMeshIsPerfect) {
  const LabelVolume v = threeLabels();
  ASSERT_LT(v.directionDeterminant(), 0);
  const TetMesh m = voxelMesh(v);
  femesher::testing::expectConformal(m);
  RunContext ctx;
  ctx.setThreads(2);
  const FidelityReport r = computeFidelity(v, m, ctx);
  ASSERT_EQ(r.materials.size(), 3u);
  EXPECT_TRUE(r.missingLabels.empty());
  EXPECT_NEAR(r.voxelSize, 0.7, 1e-15);
  for (const auto& f : r.materials) {
    EXPECT_EQ(f.voxels, f.meshVoxels) << f.label;
    EXPECT_NEAR(f.dice, 1.0, 1e-12) << f.label;
    EXPECT_DOUBLE_EQ(f.voxelCentreDice, 1.0) << f.label;
    EXPECT_NEAR(f.overlapVolume, f.voxelVolume, 1e-9) << f.label;
    EXPECT_NEAR(f.volumeError, 0.0, 1e-9) << f.label;
    EXPECT_NEAR(f.voxelVolume, double(f.voxels) * 0.7 * 1.1 * 1.6, 1e-9);
    EXPECT_EQ(f.tets, 6 * f.voxels);
  }
  EXPECT_EQ(find(r, 3)->name, "block");
  EXPECT_EQ(find(r, 3)->voxels, 64u);
  EXPECT_GT(r.meshToLabels.samples, 100u);
  EXPECT_GT(r.labelsToMesh.samples, 100u);
  EXPECT_FALSE(r.meshToLabels.sampled);
  EXPECT_LT(r.meshToLabels.max, 1e-6);
  EXPECT_LT(r.labelsToMesh.max, 1e-6);
  // Single-threaded gives the same result.
  RunContext one;
  one.setThreads(1);
  const FidelityReport r1 = computeFidelity(v, m, one);
  for (size_t k = 0; k < r.materials.size(); ++k)
    EXPECT_EQ(r.materials[k].meshVoxels, r1.materials[k].meshVoxels);
}

TEST(Fidelity, HalfVoxelShiftLowersDiceAndGivesHalfVoxelDistance) {
  const LabelVolume v = threeLabels();
  // Shift by half a voxel along index axis 0 (the smallest spacing): every voxel centre lies on
  // a cube face; the tie rule gives it to exactly one cube, the one of voxel (i-1, j, k).
  const TetMesh m = voxelMesh(v, {0.5, 0, 0});
  const FidelityReport r = computeFidelity(v, m, quietContext());
  const auto expected = diceOfShiftByOne(v);
  const auto volume = volumeDiceOfShift(v, 0, 0.5);
  ASSERT_EQ(r.materials.size(), 3u);
  for (const auto& f : r.materials) {
    EXPECT_NEAR(f.voxelCentreDice, expected.at(f.label), 1e-12) << f.label;
    EXPECT_NEAR(f.dice, volume.at(f.label), 1e-9) << f.label;
    EXPECT_LT(f.dice, 0.999) << f.label;
    EXPECT_GT(f.dice, f.voxelCentreDice) << f.label;  // centres lose whole voxels, volume half
    EXPECT_NEAR(f.volumeError, 0.0, 1e-9);  // shifting keeps the volume
  }
  EXPECT_NEAR(find(r, 3)->voxelCentreDice, 2.0 * 48 / 128, 1e-12);  // the block loses a layer
  EXPECT_NEAR(find(r, 3)->dice, 3.5 / 4, 1e-9);                      // ... of half a voxel
  EXPECT_NEAR(r.meshToLabels.max, 0.5, 1e-6);
  EXPECT_NEAR(r.labelsToMesh.max, 0.5, 1e-6);
  EXPECT_GT(r.meshToLabels.mean, 0.05);
  EXPECT_LT(r.meshToLabels.mean, 0.5);
  EXPECT_GT(r.labelsToMesh.mean, 0.05);
  EXPECT_LE(r.labelsToMesh.median, r.labelsToMesh.p95);
  EXPECT_LE(r.labelsToMesh.p95, r.labelsToMesh.p99);
  EXPECT_LE(r.labelsToMesh.p99, r.labelsToMesh.max);

  // A shift of a quarter voxel keeps every centre inside its own cube (voxel-centre agreement 1:
  // it cannot see the shift) while a quarter voxel of volume moves (volume Dice below 1). Along
  // index axis 0 the volume overlap is integrated exactly (the lines run along it); along axis 1
  // it is stratified across 5 lines per voxel: on these three small labels (the thinnest one
  // voxel) within 0.005 of the exact Dice. The surfaces move
  // by 0.25 voxel, or 0.25 * 1.1 / 0.7 voxels of the smallest spacing along axis 1.
  const FidelityReport q = computeFidelity(v, voxelMesh(v, {0.25, 0, 0}), quietContext());
  const auto quarter = volumeDiceOfShift(v, 0, 0.25);
  for (const auto& f : q.materials) {
    EXPECT_DOUBLE_EQ(f.voxelCentreDice, 1.0);
    EXPECT_NEAR(f.dice, quarter.at(f.label), 1e-9) << f.label;
    EXPECT_LT(f.dice, 0.99) << f.label;
  }
  EXPECT_NEAR(q.meshToLabels.max, 0.25, 1e-6);
  EXPECT_NEAR(q.labelsToMesh.max, 0.25, 1e-6);
  const FidelityReport y = computeFidelity(v, voxelMesh(v, {0, 0.25, 0}), quietContext());
  const auto quarterY = volumeDiceOfShift(v, 1, 0.25);
  for (const auto& f : y.materials) {
    EXPECT_DOUBLE_EQ(f.voxelCentreDice, 1.0);
    EXPECT_NEAR(f.dice, quarterY.at(f.label), 0.005) << f.label;
    EXPECT_LT(f.dice, 0.99) << f.label;
  }
  EXPECT_NEAR(y.meshToLabels.max, 0.25 * 1.1 / 0.7, 1e-6);
  EXPECT_NEAR(y.labelsToMesh.max, 0.25 * 1.1 / 0.7, 1e-6);
}

TEST(Fidelity, MissingLabelIsListed) {
  const LabelVolume v = threeLabels();
  const TetMesh m = voxelMesh(v, {0, 0, 0}, {9});
  const FidelityReport r = computeFidelity(v, m, quietContext());
  ASSERT_EQ(r.missingLabels.size(), 1u);
  EXPECT_EQ(r.missingLabels[0], 9);
  ASSERT_NE(find(r, 9), nullptr);
  EXPECT_EQ(find(r, 9)->tets, 0u);
  EXPECT_EQ(find(r, 9)->dice, 0.0);
  EXPECT_NEAR(find(r, 9)->volumeError, -1.0, 1e-12);
  EXPECT_NEAR(find(r, 3)->dice, 1.0, 1e-9);
  EXPECT_GT(r.labelsToMesh.max, 0.9);  // the layer's outer faces are a voxel from any mesh face
  const auto j = nlohmann::json::parse(fidelityReportToJson(r));
  EXPECT_EQ(j["missing_labels"][0], 9);
  EXPECT_EQ(j["materials"].size(), 3u);
  EXPECT_EQ(j["mesh_to_labels"]["sampled"], false);
  const std::string text = fidelityReportToText(r);
  EXPECT_NE(text.find("missing labels"), std::string::npos);
  EXPECT_NE(text.find("layer"), std::string::npos);
}

TEST(Fidelity, LabelMapWithoutBackground) {
  LabelVolume v = obliqueVolume(5, 4, 3);
  for (int k = 0; k < 3; ++k)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 5; ++i) v.labels[v.index(i, j, k)] = i < 2 ? 1 : (j < 2 ? 2 : 4);
  ASSERT_TRUE(v.hasNoBackground());
  const TetMesh m = voxelMesh(v);
  const FidelityReport r = computeFidelity(v, m, quietContext());
  ASSERT_EQ(r.materials.size(), 3u);
  for (const auto& f : r.materials) {
    EXPECT_NEAR(f.dice, 1.0, 1e-9);
    EXPECT_DOUBLE_EQ(f.voxelCentreDice, 1.0);
    EXPECT_NEAR(f.volumeError, 0, 1e-9);
  }
  EXPECT_LT(r.meshToLabels.max, 1e-6);
  EXPECT_LT(r.labelsToMesh.max, 1e-6);
  // Shifted: voxels of the first column are not covered at all and count against label 1.
  const FidelityReport s = computeFidelity(v, voxelMesh(v, {0.5, 0, 0}), quietContext());
  const auto expected = diceOfShiftByOne(v);
  const auto volume = volumeDiceOfShift(v, 0, 0.5);
  for (const auto& f : s.materials) {
    EXPECT_NEAR(f.voxelCentreDice, expected.at(f.label), 1e-12) << f.label;
    EXPECT_NEAR(f.dice, volume.at(f.label), 1e-9) << f.label;
  }
}

TEST(Fidelity, MeshFarFromLabelsUsesTheFallbackSearch) {
  // A mesh moved 20 voxels away: the ring search gives up and the kd-tree answers.
  const LabelVolume v = threeLabels();
  const FidelityReport r = computeFidelity(v, voxelMesh(v, {20, 0, 0}), quietContext());
  for (const auto& f : r.materials) EXPECT_EQ(f.dice, 0.0);
  EXPECT_GT(r.meshToLabels.mean, 5.0);
  EXPECT_GT(r.meshToLabels.max, 19.0);
  // Lower bound: every mesh point is at least 20 - 9 voxels (of x) right of the volume's box.
  EXPECT_GE(r.meshToLabels.max, r.meshToLabels.mean);
  EXPECT_GT(r.labelsToMesh.max, 19.0);
}

TEST(Fidelity, MickeyVoxelMesh) {
  const std::string path = femesher::testing::dataFile("mickey.nrrd");
  auto lv = readLabelMap(path);
  if (!lv.isOk()) {
    if (femesher::testing::inCI()) FAIL() << lv.status().message();
    GTEST_SKIP() << lv.status().message();
  }
  const LabelVolume& v = lv.value();
  const TetMesh m = voxelMesh(v);
  const FidelityReport r = computeFidelity(v, m, quietContext());
  EXPECT_FALSE(r.materials.empty());
  for (const auto& f : r.materials) {
    EXPECT_NEAR(f.dice, 1.0, 1e-9) << f.label;
    EXPECT_DOUBLE_EQ(f.voxelCentreDice, 1.0) << f.label;
    EXPECT_NEAR(f.volumeError, 0, 1e-9) << f.label;
  }
  EXPECT_TRUE(r.missingLabels.empty());
  EXPECT_LT(r.meshToLabels.max, 1e-6);
  EXPECT_LT(r.labelsToMesh.max, 1e-6);
}

TEST(Fidelity, LargeVolumeBlockMesh) {
  // 8M voxels, 750k tets (blocks of 4^3 voxels): prints the time; Dice must be exactly 1.
  LabelVolume v = obliqueVolume(200, 200, 200);
  for (int k = 0; k < 200; ++k)
    for (int j = 0; j < 200; ++j)
      for (int i = 0; i < 200; ++i) {
        const int bi = i / 4, bj = j / 4, bk = k / 4;
        const double r2 = (bi - 25.0) * (bi - 25.0) + (bj - 25.0) * (bj - 25.0) + (bk - 25.0) * (bk - 25.0);
        v.labels[v.index(i, j, k)] = r2 < 100 ? 2 : (r2 < 400 ? 1 : 0);
      }
  const TetMesh m = voxelMesh(v, {0, 0, 0}, {}, 4);
  RunContext ctx;
  ctx.setThreads(2);
  const auto t0 = std::chrono::steady_clock::now();
  const FidelityReport r = computeFidelity(v, m, ctx);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("fidelity: %zu voxels, %zu tets, %zu+%zu distance samples: %.2f s (2 threads)\n",
              v.voxelCount(), m.tets.size(), r.meshToLabels.samples, r.labelsToMesh.samples, s);
  ASSERT_EQ(r.materials.size(), 2u);
  for (const auto& f : r.materials) EXPECT_NEAR(f.dice, 1.0, 1e-9);
  EXPECT_LT(r.meshToLabels.max, 1e-6);
  EXPECT_LT(r.labelsToMesh.max, 1e-6);
}

TEST(Fidelity, RejectsInconsistentInput) {
  LabelVolume v = threeLabels();
  TetMesh m = voxelMesh(v);
  m.tetLabels.pop_back();
  EXPECT_THROW(computeFidelity(v, m, quietContext()), Error);
  m = voxelMesh(v);
  v.labels.pop_back();
  EXPECT_THROW(computeFidelity(v, m, quietContext()), Error);
}
