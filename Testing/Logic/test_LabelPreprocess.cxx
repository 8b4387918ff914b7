// SPDX-License-Identifier: GPL-3.0-or-later
// Stage 1 (LabelPreprocess) on its own: crop and pad, label compaction, min_voxels merging into
// the neighbouring label, label maps without background, errors and cancel.
#include <femesher/RunContext.h>
#include <femesher/Status.h>
#include <femesher/stages/LabelPreprocess.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>

#include "MeshInvariants.h"
#include "TestShapes.h"

using namespace femesher;
using namespace femesher::testing;

namespace {

size_t countLabel(const LabelVolume& v, int32_t l) {
  return size_t(std::count(v.labels.begin(), v.labels.end(), l));
}

/// Local voxel (i, j, k) of `pv` holds the compact id of the input voxel it covers, and 0 where
/// it covers no input voxel (padding); returns the number of voxels that do not.
size_t mismatchesWithInput(const PreprocessedVolume& pv, const LabelVolume& in) {
  std::map<int32_t, uint16_t> compact;
  for (size_t c = 0; c < pv.userLabel.size(); ++c) compact[pv.userLabel[c]] = uint16_t(c);
  size_t bad = 0;
  for (int k = 0; k < pv.dims[2]; ++k)
    for (int j = 0; j < pv.dims[1]; ++j)
      for (int i = 0; i < pv.dims[0]; ++i) {
        const int x = i + pv.offset[0], y = j + pv.offset[1], z = k + pv.offset[2];
        const uint16_t want = in.inside(x, y, z) ? compact.at(in.at(x, y, z)) : 0;
        bad += pv.at(i, j, k) != want;
      }
  return bad;
}

/// A 30 x 26 x 22 volume (spacing 0.7 x 0.4 x 0.5 mm) whose labels 1000, 7 and 42 fill the box
/// of voxels [5, 19] x [6, 17] x [3, 14] (three slabs along x); background elsewhere.
LabelVolume slabsInABox() {
  LabelVolume v = test::makeVolume({30, 26, 22}, {0.7, 0.4, 0.5}, [](double x, double y, double z) {
    const double i = x + 14.5, j = y + 12.5, k = z + 10.5;  // voxel indices
    if (i < 5 || i > 19 || j < 6 || j > 17 || k < 3 || k > 14) return 0;
    return i < 10 ? 1000 : (i < 15 ? 7 : 42);
  });
  v.materials = {{42, "tendon", {0.1, 0.2, 0.3}}};
  return v;
}

}  // namespace

TEST(LabelPreprocess, CropsPadsCompactsAndDropsTinyLabels) {
  LabelVolume v = test::ballsInShell(30);
  v.labels[v.index(15, 15, 15)] = 77;  // one stray voxel inside a ball
  RunContext ctx;
  LabelPreprocessParameters p;
  p.minVoxels = 5;
  const PreprocessedVolume pv = preprocessLabels(v, p, ctx);
  ASSERT_EQ(pv.droppedLabels, std::vector<int32_t>{77});
  ASSERT_EQ(pv.materialCount(), 3);
  EXPECT_EQ(pv.userLabel, (std::vector<int32_t>{0, 1, 2, 3}));
  ASSERT_EQ(ctx.warnings().size(), 1u);
  EXPECT_NE(ctx.warnings()[0].find("77"), std::string::npos);
  // The stray voxel joined its neighbours (ball 1 or 2), so no voxel is lost from the balls.
  EXPECT_EQ(pv.voxelCounts[1] + pv.voxelCounts[2], countLabel(v, 1) + countLabel(v, 2) + 1);
  // Margin of background all around.
  for (int a = 0; a < 3; ++a) EXPECT_GE(pv.offset[a], -3);
  EXPECT_EQ(pv.at(0, 0, 0), 0);
  EXPECT_EQ(pv.at(pv.dims[0] - 1, pv.dims[1] - 1, pv.dims[2] - 1), 0);
}

TEST(LabelPreprocess, EmptyMapIsAClearError) {
  LabelVolume v;
  v.dims = {4, 4, 4};
  v.labels.assign(64, 0);
  RunContext ctx;
  try {
    preprocessLabels(v, {}, ctx);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::EmptyLabelMap);
  }
}

// The working grid is the labelled box plus the margin on every side; every voxel of the input
// keeps its place (local + offset = input index) and label; the padding is background.
TEST(LabelPreprocess, CropAndPadKeepEveryVoxelInPlace) {
  const LabelVolume v = slabsInABox();
  for (const int margin : {4, 1}) {
    RunContext ctx;
    LabelPreprocessParameters p;
    p.minVoxels = 1;
    p.margin = margin;
    const PreprocessedVolume pv = preprocessLabels(v, p, ctx);
    const int m = std::max(2, margin);  // the margin is at least 2
    EXPECT_EQ(pv.offset, (std::array<int, 3>{{5 - m, 6 - m, 3 - m}})) << "margin " << margin;
    EXPECT_EQ(pv.dims, (std::array<int, 3>{{15 + 2 * m, 12 + 2 * m, 12 + 2 * m}}));
    EXPECT_EQ(pv.inputDims, v.dims);
    EXPECT_EQ(pv.spacing, v.spacing);
    ASSERT_EQ(pv.labels.size(), size_t(pv.dims[0]) * pv.dims[1] * pv.dims[2]);
    EXPECT_EQ(mismatchesWithInput(pv, v), 0u);
    // Canonical frame: local voxel (0,0,0) sits at the input index `offset`.
    const Vec3 c = pv.localToCanonical({0, 0, 0});
    for (int a = 0; a < 3; ++a) EXPECT_DOUBLE_EQ(c[a], pv.offset[a] * v.spacing[a]);
    EXPECT_TRUE(ctx.warnings().empty());
  }
}

// User ids, in increasing order, become 1..N; the material table follows (names and colours
// from the input table, defaults otherwise) and the voxel counts are per compact id.
TEST(LabelPreprocess, UserLabelsAreCompactedInIncreasingOrder) {
  const LabelVolume v = slabsInABox();
  RunContext ctx;
  LabelPreprocessParameters p;
  p.minVoxels = 1;
  const PreprocessedVolume pv = preprocessLabels(v, p, ctx);
  ASSERT_EQ(pv.userLabel, (std::vector<int32_t>{0, 7, 42, 1000}));
  ASSERT_EQ(pv.materials.size(), 4u);
  EXPECT_EQ(pv.materials[0].name, "background");
  EXPECT_EQ(pv.materials[1].name, "label 7");
  EXPECT_EQ(pv.materials[1].color, defaultLabelColor(7));
  EXPECT_EQ(pv.materials[2].name, "tendon");
  EXPECT_EQ(pv.materials[2].color, (std::array<double, 3>{{0.1, 0.2, 0.3}}));
  EXPECT_EQ(pv.materials[3].id, 1000);
  ASSERT_EQ(pv.voxelCounts.size(), 4u);
  for (size_t c = 1; c < 4; ++c) EXPECT_EQ(pv.voxelCounts[c], countLabel(v, pv.userLabel[c])) << c;
  EXPECT_EQ(pv.voxelCounts[0] + pv.voxelCounts[1] + pv.voxelCounts[2] + pv.voxelCounts[3],
            pv.labels.size());
  EXPECT_EQ(pv.materialCount(), 3);
  EXPECT_TRUE(pv.droppedLabels.empty());
}

// A label with fewer than min_voxels voxels is dropped (one warning naming it); each of its
// voxels takes the most common label among its kept 6-neighbours (ties: the smaller compact id),
// layer by layer from the outside of a dropped blob. A label with exactly min_voxels stays.
TEST(LabelPreprocess, TinyLabelsJoinTheirMostCommonNeighbour) {
  // Material 1 below z = 0, material 2 above (centred coordinates), in a 20^3 box of background.
  LabelVolume v = test::makeVolume(20, [](double x, double y, double z) {
    if (std::max({std::fabs(x), std::fabs(y), std::fabs(z)}) > 8) return 0;
    return z < 0 ? 1 : 2;
  });
  v.materials = {{9, "speck", {1, 0, 0}}};
  auto set = [&](int i, int j, int k, int32_t l) { v.labels[v.index(i, j, k)] = l; };
  set(6, 6, 9, 9);     // in the last layer of 1: five neighbours of 1, one of 2 -> 1
  set(12, 12, 10, 8);  // in the first layer of 2: five of 2, one of 1 -> 2
  // A voxel of 6 whose neighbours are three of 1 and three of 2: the tie goes to 1.
  set(10, 5, 9, 6);
  using Voxels = std::vector<std::array<int, 3>>;
  for (const auto& q : Voxels{{9, 5, 9}, {10, 4, 9}, {10, 5, 8}}) set(q[0], q[1], q[2], 1);
  for (const auto& q : Voxels{{11, 5, 9}, {10, 6, 9}, {10, 5, 10}}) set(q[0], q[1], q[2], 2);
  // A 3x3x3 blob of 5 inside material 1: its centre has no kept neighbour in the first round.
  for (int k = 3; k < 6; ++k)
    for (int j = 8; j < 11; ++j)
      for (int i = 8; i < 11; ++i) set(i, j, k, 5);
  // A 7 x 4 patch of 4 inside material 2: exactly min_voxels = 28 in the first run.
  for (int j = 13; j < 17; ++j)
    for (int i = 5; i < 12; ++i) set(i, j, 14, 4);

  for (const int64_t minVoxels : {28, 29}) {
    RunContext ctx;
    LabelPreprocessParameters p;
    p.minVoxels = minVoxels;
    const PreprocessedVolume pv = preprocessLabels(v, p, ctx);
    const bool fourKept = minVoxels == 28;
    EXPECT_EQ(pv.droppedLabels, fourKept ? (std::vector<int32_t>{5, 6, 8, 9})
                                         : (std::vector<int32_t>{4, 5, 6, 8, 9}));
    ASSERT_EQ(ctx.warnings().size(), pv.droppedLabels.size());
    bool namedSpeck = false;
    for (const auto& w : ctx.warnings())
      namedSpeck |= w.find("Label 9 (speck)") != std::string::npos;
    EXPECT_TRUE(namedSpeck);
    auto at = [&](int i, int j, int k) {
      return pv.userLabel[pv.at(i - pv.offset[0], j - pv.offset[1], k - pv.offset[2])];
    };
    EXPECT_EQ(at(6, 6, 9), 1);
    EXPECT_EQ(at(12, 12, 10), 2);
    EXPECT_EQ(at(10, 5, 9), 1);
    for (int k = 3; k < 6; ++k)
      for (int j = 8; j < 11; ++j)
        for (int i = 8; i < 11; ++i) EXPECT_EQ(at(i, j, k), 1) << i << " " << j << " " << k;
    for (int j = 13; j < 17; ++j)
      for (int i = 5; i < 12; ++i) EXPECT_EQ(at(i, j, 14), fourKept ? 4 : 2);
    // Nothing is lost: every input voxel is counted once.
    size_t total = 0;
    for (size_t c = 1; c < pv.voxelCounts.size(); ++c) total += pv.voxelCounts[c];
    EXPECT_EQ(total, v.voxelCount() - countLabel(v, 0));
  }
}

// Without any 0 every voxel is a material and the box is the outer boundary: nothing is cropped,
// the margin is the only background ("outside").
TEST(LabelPreprocess, LabelMapWithoutBackgroundIsPaddedWithOutside) {
  const LabelVolume v = test::ballsInShellWithoutBackground(12);
  ASSERT_TRUE(v.hasNoBackground());
  RunContext ctx;
  LabelPreprocessParameters p;
  p.minVoxels = 1;
  p.margin = 3;
  const PreprocessedVolume pv = preprocessLabels(v, p, ctx);
  EXPECT_EQ(pv.offset, (std::array<int, 3>{{-3, -3, -3}}));
  EXPECT_EQ(pv.dims, (std::array<int, 3>{{18, 18, 18}}));
  EXPECT_EQ(pv.userLabel, (std::vector<int32_t>{0, 1, 2, 3, 4}));
  EXPECT_EQ(pv.materials[0].name, "outside");
  EXPECT_EQ(pv.voxelCounts[0], size_t(18 * 18 * 18 - 12 * 12 * 12));
  EXPECT_EQ(mismatchesWithInput(pv, v), 0u);
}

TEST(LabelPreprocess, NothingLeftAfterMinVoxelsAndNoVoxelsAreErrors) {
  LabelVolume v = test::makeVolume(8, [](double x, double y, double z) {
    return std::fabs(x) < 1 && std::fabs(y) < 1 && std::fabs(z) < 1 ? 3 : 0;  // 2^3 voxels
  });
  RunContext ctx;
  LabelPreprocessParameters p;
  p.minVoxels = 9;
  const std::string message =
      expectError(ErrorCode::EmptyLabelMap, [&] { preprocessLabels(v, p, ctx); });
  EXPECT_NE(message.find("min_voxels = 9"), std::string::npos) << message;
  p.minVoxels = 8;
  EXPECT_EQ(preprocessLabels(v, p, ctx).voxelCounts.at(1), 8u);
  v.labels.pop_back();  // labels no longer match dims
  expectError(ErrorCode::InvalidArgument, [&] { preprocessLabels(v, p, ctx); });
}

TEST(LabelPreprocess, CancelStopsTheStage) {
  RunContext ctx;
  ctx.cancel();
  expectError(ErrorCode::Canceled, [&] { preprocessLabels(test::ballsInShell(12), {}, ctx); });
}

// An excluded material merged into its neighbours: its voxels go to the most common kept
// neighbour (here the middle slab 7 gives its voxels to 1000 and 42, split down the middle), and
// a warning names the materials that received them.
TEST(LabelPreprocess, ExcludedMaterialMergesIntoItsNeighbours) {
  const LabelVolume v = slabsInABox();
  RunContext ctx;
  LabelPreprocessParameters p;
  p.excluded[7] = Exclusion::MergeIntoNeighbour;
  const PreprocessedVolume pv = preprocessLabels(v, p, ctx);
  EXPECT_EQ(pv.userLabel, (std::vector<int32_t>{0, 42, 1000}));
  EXPECT_EQ(pv.excludedLabels, std::vector<int32_t>{7});
  EXPECT_TRUE(pv.droppedLabels.empty());
  // Every voxel of 7 now belongs to 1000 or 42: the labelled voxels are as many as before.
  EXPECT_EQ(pv.voxelCounts[1] + pv.voxelCounts[2],
            countLabel(v, 1000) + countLabel(v, 7) + countLabel(v, 42));
  EXPECT_GT(pv.voxelCounts[1], countLabel(v, 42));
  EXPECT_GT(pv.voxelCounts[2], countLabel(v, 1000));
  bool named = false;
  for (const auto& w : ctx.warnings())
    named |= w.find("Label 7") != std::string::npos && w.find("label 1000") != std::string::npos &&
             w.find("tendon (label 42)") != std::string::npos;
  EXPECT_TRUE(named) << "the warning must name where the voxels went";
}

// The user's names replace the map's names (and "label N") in the material table and in the
// warnings; labels without a user name keep theirs.
TEST(LabelPreprocess, UserNamesNameTheMaterials) {
  const LabelVolume v = slabsInABox();  // 42 is "tendon" in the map, 7 and 1000 have no name
  RunContext ctx;
  LabelPreprocessParameters p;
  p.names[7] = "meniscus";
  p.names[42] = "patellar tendon";
  p.excluded[1000] = Exclusion::MergeIntoNeighbour;
  const PreprocessedVolume pv = preprocessLabels(v, p, ctx);
  ASSERT_EQ(pv.userLabel, (std::vector<int32_t>{0, 7, 42}));
  EXPECT_EQ(pv.materials[1].name, "meniscus");
  EXPECT_EQ(pv.materials[2].name, "patellar tendon");
  EXPECT_EQ(pv.materials[2].color, (std::array<double, 3>{0.1, 0.2, 0.3}));  // the map's colour stays
  bool named = false;
  for (const auto& w : ctx.warnings()) named |= w.find("meniscus (label 7)") != std::string::npos;
  EXPECT_TRUE(named) << "the merge warning names where the voxels went by the user's name";
  p.names.clear();
  p.excluded.clear();
  RunContext ctx2;
  const PreprocessedVolume plain = preprocessLabels(v, p, ctx2);
  EXPECT_EQ(plain.materials[1].name, "label 7");
  EXPECT_EQ(plain.materials[2].name, "tendon");
}

// An excluded material as background: a cut between the two other slabs; the crop ignores it.
TEST(LabelPreprocess, ExcludedMaterialAsBackgroundLeavesACut) {
  LabelVolume v = slabsInABox();
  RunContext ctx;
  LabelPreprocessParameters p;
  p.excluded[42] = Exclusion::Background;  // the last slab: the labelled box shrinks
  p.excluded[5] = Exclusion::Background;   // not in the map: a warning, nothing else
  const PreprocessedVolume pv = preprocessLabels(v, p, ctx);
  EXPECT_EQ(pv.userLabel, (std::vector<int32_t>{0, 7, 1000}));
  EXPECT_EQ(pv.excludedLabels, std::vector<int32_t>{42});
  EXPECT_EQ(pv.voxelCounts[1], countLabel(v, 7));
  EXPECT_EQ(pv.voxelCounts[2], countLabel(v, 1000));
  EXPECT_EQ(pv.dims[0], 10 + 2 * p.margin);  // x from 5 to 14 only
  size_t noSuchLabel = 0;
  for (const auto& w : ctx.warnings()) noSuchLabel += w.find("no such label") != std::string::npos;
  EXPECT_EQ(noSuchLabel, 1u);
  // Everything excluded: a clear error naming the exclusion.
  p.excluded[7] = Exclusion::Background;
  p.excluded[1000] = Exclusion::MergeIntoNeighbour;
  RunContext ctx2;
  try {
    preprocessLabels(v, p, ctx2);
    FAIL() << "meshed a label map whose every material is excluded";
  } catch (const Error& e) {
    EXPECT_EQ(e.status().code(), ErrorCode::EmptyLabelMap);
    EXPECT_NE(e.status().message().find("excluded"), std::string::npos);
  }
}
