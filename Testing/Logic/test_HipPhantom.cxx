// SPDX-License-Identifier: GPL-3.0-or-later
// The clinical-size hip phantom: size and spacing at full and small scale, the material table, and
// on the small scale (256 x 256 x 200) the connected structure: components per label, which
// labels touch and which must not (nested shells, the cartilage gap), the 1-2 voxel subchondral
// plate and the thin cartilage; the same labels on 1 and 2 threads.
#include <femesher/HipPhantom.h>
#include <femesher/Status.h>
#include <femesher/io/LabelMapSummary.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <set>
#include <string>
#include <utility>

using namespace femesher;

namespace {

const LabelVolume& smallHip() {
  static const LabelVolume v = [] {
    HipPhantomOptions o;
    o.scale = 0.5;
    return makeHipPhantom(o);
  }();
  return v;
}

const LabelMapSummary& smallSummary() {
  static const LabelMapSummary s = summarizeLabelMap(smallHip());
  return s;
}

const LabelStatistics* findStats(const LabelMapSummary& s, int32_t id) {
  for (const auto& l : s.labels)
    if (l.id == id) return &l;
  return nullptr;
}

bool touches(int32_t a, int32_t b) {
  const auto& p = smallSummary().touchingPairs;
  return std::find(p.begin(), p.end(), std::make_pair(std::min(a, b), std::max(a, b))) != p.end();
}

/// How many voxels of `label` (off the volume's border) have a 26-neighbour with neighbourIs.
template <class Pred>
size_t count26(const LabelVolume& v, int32_t label, Pred neighbourIs) {
  size_t n = 0;
  for (int k = 1; k + 1 < v.dims[2]; ++k)
    for (int j = 1; j + 1 < v.dims[1]; ++j)
      for (int i = 1; i + 1 < v.dims[0]; ++i) {
        if (v.at(i, j, k) != label) continue;
        bool hit = false;
        for (int d = 0; d < 27 && !hit; ++d)
          hit = d != 13 && neighbourIs(v.at(i + d % 3 - 1, j + (d / 3) % 3 - 1, k + d / 9 - 1));
        n += hit;
      }
  return n;
}

}  // namespace

TEST(HipPhantom, SizeAndSpacing) {
  const LabelVolume full = hipPhantomHeader();
  EXPECT_EQ(full.dims, (std::array<int, 3>{512, 512, 400}));
  EXPECT_EQ(full.spacing, (Vec3{0.7, 0.7, 1.0}));
  EXPECT_TRUE(full.labels.empty()) << "the header computes no voxel";
  const LabelVolume& small = smallHip();
  EXPECT_EQ(small.dims, (std::array<int, 3>{256, 256, 200}));
  EXPECT_EQ(small.spacing, (Vec3{1.4, 1.4, 2.0}));
  EXPECT_EQ(small.direction, (Mat3{1, 0, 0, 0, 1, 0, 0, 0, 1}));
  ASSERT_EQ(small.labels.size(), small.voxelCount());
  // The same field of view at every scale: the centre of the volume is at x = y = 0.
  EXPECT_NEAR(small.origin[0] + (small.dims[0] - 1) * small.spacing[0] / 2, 0, 1e-9);
  EXPECT_NEAR(full.origin[0] + (full.dims[0] - 1) * full.spacing[0] / 2, 0, 1e-9);
  EXPECT_NEAR(small.origin[2] - small.spacing[2] / 2, full.origin[2] - full.spacing[2] / 2, 1e-9);
  HipPhantomOptions bad;
  bad.scale = 0;
  EXPECT_THROW(hipPhantomHeader(bad), Error);
  bad.scale = 2.5;
  EXPECT_THROW(makeHipPhantom(bad), Error);
}

TEST(HipPhantom, TenMaterialsEachWithItsComponents) {
  const LabelVolume& v = smallHip();
  const std::vector<std::string> names = {
      "pelvis cortical bone", "pelvis trabecular bone", "femur cortical bone",
      "femur trabecular bone", "marrow", "cartilage", "implant", "muscle", "fat",
      "subchondral bone plate"};
  ASSERT_EQ(v.materials.size(), names.size());
  for (size_t m = 0; m < names.size(); ++m) {
    EXPECT_EQ(v.materials[m].id, int32_t(m + 1));
    EXPECT_EQ(v.materials[m].name, names[m]);
  }
  // 6-connected components: one pelvis (a ring), a femur per side with its canal, one cartilage
  // layer and one plate (the native hip), one implant (stem, neck, ball and cup together), one
  // muscle inside one fat layer inside one background.
  const std::map<int32_t, int> components = {{0, 1}, {1, 1}, {2, 1}, {3, 2}, {4, 2}, {5, 2},
                                             {6, 1}, {7, 1}, {8, 1}, {9, 1}, {10, 1}};
  for (const auto& [id, expected] : components) {
    const LabelStatistics* st = findStats(smallSummary(), id);
    ASSERT_NE(st, nullptr) << "label " << id;
    EXPECT_EQ(st->components, expected) << "label " << id;
    EXPECT_GE(st->voxels, 1000u) << "label " << id;
  }
  EXPECT_GT(findStats(smallSummary(), 0)->voxels, v.voxelCount() / 4) << "air around the body";
}

TEST(HipPhantom, NestedShellsImplantAndCartilageGap) {
  // The implant touches the femur's three tissues (stem) and the pelvis (cup).
  for (int32_t bone : {kHipFemurCortical, kHipFemurTrabecular, kHipMarrow, kHipPelvisCortical})
    EXPECT_TRUE(touches(kHipImplant, bone)) << bone;
  // Cartilage between the plate of the femoral head and the acetabulum's cortex.
  EXPECT_TRUE(touches(kHipCartilage, kHipSubchondralPlate));
  EXPECT_TRUE(touches(kHipCartilage, kHipPelvisCortical));
  EXPECT_TRUE(touches(kHipSubchondralPlate, kHipFemurTrabecular));
  // Background touches fat only; no bone touches fat or the background; the gap keeps femur and
  // pelvis apart; the plate keeps cartilage off trabecular bone.
  for (const auto& [a, b] : smallSummary().touchingPairs) {
    if (a == 0) EXPECT_EQ(b, kHipFat) << "background touches label " << b;
    const bool boneA = (a >= 1 && a <= kHipMarrow) || a == kHipSubchondralPlate || a == kHipImplant;
    const bool boneB = (b >= 1 && b <= kHipMarrow) || b == kHipSubchondralPlate || b == kHipImplant;
    if (boneA || boneB) EXPECT_NE(std::max(a, b), kHipFat) << a << ":" << b;
    const std::set<int32_t> pair{a, b};
    const bool pelvisFemur = a >= 1 && a <= 2 && ((b >= 3 && b <= 5) || b == 10);
    EXPECT_FALSE(pelvisFemur) << "pelvis " << a << " touches femur " << b;
    EXPECT_NE(pair, (std::set<int32_t>{kHipCartilage, kHipFemurTrabecular}));
  }
}

TEST(HipPhantom, ThinPlateAndThinCartilage) {
  const LabelVolume& v = smallHip();
  const auto isCartilage = [](int32_t l) { return l == kHipCartilage; };
  // At least one voxel: no trabecular voxel of the femur has a cartilage 26-neighbour.
  EXPECT_EQ(count26(v, kHipFemurTrabecular, isCartilage), 0u);
  // At most two: every plate voxel has a 26-neighbour outside the bone.
  const auto outsideBone = [](int32_t l) { return l == kHipCartilage || l == kHipMuscle; };
  const size_t plate = findStats(smallSummary(), kHipSubchondralPlate)->voxels;
  EXPECT_EQ(count26(v, kHipSubchondralPlate, outsideBone), plate);
  // Cartilage 3 mm: every cartilage voxel has a non-cartilage 26-neighbour (no voxel inside it).
  const size_t cartilage = findStats(smallSummary(), kHipCartilage)->voxels;
  EXPECT_EQ(count26(v, kHipCartilage, [](int32_t l) { return l != kHipCartilage; }), cartilage);
}

TEST(HipPhantom, SameLabelsOnAnyThreadCount) {
  HipPhantomOptions one, two;
  one.scale = two.scale = 0.2;
  one.threads = 1;
  two.threads = 2;
  EXPECT_EQ(makeHipPhantom(one).labels, makeHipPhantom(two).labels);
}
