// SPDX-License-Identifier: GPL-3.0-or-later
// The built-in phantom: materials, geometry, junctions (checked with summarizeLabelMap), round trip.
#include <femesher/Phantom.h>
#include <femesher/io/LabelMapIO.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <set>
#include <string>

using namespace femesher;

namespace {

const LabelStatistics* findStats(const LabelMapSummary& s, int32_t id) {
  for (const auto& l : s.labels)
    if (l.id == id) return &l;
  return nullptr;
}

bool touches(const LabelMapSummary& s, int32_t a, int32_t b) {
  return std::find(s.touchingPairs.begin(), s.touchingPairs.end(), std::make_pair(std::min(a, b), std::max(a, b))) !=
         s.touchingPairs.end();
}

}  // namespace

TEST(Phantom, GeometryAndMaterialTable) {
  const LabelVolume v = makePhantom();
  EXPECT_EQ(v.dims, (std::array<int, 3>{64, 64, 96}));
  EXPECT_EQ(v.spacing, (Vec3{1, 1, 1}));
  EXPECT_NE(v.origin, (Vec3{0, 0, 0}));
  EXPECT_EQ(v.direction, (Mat3{1, 0, 0, 0, 1, 0, 0, 0, 1}));
  ASSERT_EQ(v.labels.size(), v.voxelCount());
  const std::vector<std::string> names = {"cortical bone", "trabecular bone", "marrow", "cartilage", "implant"};
  ASSERT_EQ(v.materials.size(), names.size());
  std::set<std::array<double, 3>> colours;
  for (size_t m = 0; m < names.size(); ++m) {
    EXPECT_EQ(v.materials[m].id, int32_t(m + 1));
    EXPECT_EQ(v.materials[m].name, names[m]);
    colours.insert(v.materials[m].color);
  }
  EXPECT_EQ(colours.size(), names.size()) << "material colours must be distinct";
}

TEST(Phantom, LabelsJunctionsAndMargin) {
  const LabelVolume v = makePhantom();
  const LabelMapSummary s = summarizeLabelMap(v);
  ASSERT_NE(findStats(s, 0), nullptr);
  EXPECT_EQ(findStats(s, 0)->components, 1) << "one connected background around the femur";
  for (int32_t id = 1; id <= 5; ++id) {
    const LabelStatistics* st = findStats(s, id);
    ASSERT_NE(st, nullptr) << "label " << id;
    EXPECT_GE(st->voxels, id == 4 ? 500u : 1000u) << "label " << id;
    EXPECT_EQ(st->components, 1) << "label " << id;
    for (int a = 0; a < 3; ++a) {  // background margin of at least 2 voxels
      EXPECT_GE(st->bboxMin[a], 2) << "label " << id;
      EXPECT_LE(st->bboxMax[a], v.dims[a] - 3) << "label " << id;
    }
  }
  // The implant stem sits in the canal and meets marrow, trabecular and cortical bone.
  EXPECT_TRUE(touches(s, 5, 3));
  EXPECT_TRUE(touches(s, 5, 2));
  EXPECT_TRUE(touches(s, 5, 1));
  EXPECT_TRUE(touches(s, 4, 1)) << "cartilage cap on the cortical shell";
  EXPECT_GE(s.tripleCells, 100u);
  EXPECT_GE(s.quadrupleCells, 1u) << "a point where 4 materials meet";
  // At least one quadruple cell made of the four materials cortical, trabecular, marrow, implant.
  size_t quadBone = 0;
  for (int k = 0; k + 1 < v.dims[2]; ++k)
    for (int j = 0; j + 1 < v.dims[1]; ++j)
      for (int i = 0; i + 1 < v.dims[0]; ++i) {
        std::set<int32_t> c;
        for (int q = 0; q < 8; ++q) c.insert(v.at(i + (q & 1), j + ((q >> 1) & 1), k + ((q >> 2) & 1)));
        quadBone += c == std::set<int32_t>{1, 2, 3, 5};
      }
  EXPECT_GE(quadBone, 1u);
}

TEST(Phantom, DeterministicAndScalable) {
  const LabelVolume a = makePhantom(), b = makePhantom();
  EXPECT_EQ(a.labels, b.labels);
  PhantomOptions fine;
  fine.voxelSize = 0.5;
  const LabelVolume f = makePhantom(fine);
  EXPECT_EQ(f.dims, (std::array<int, 3>{128, 128, 192}));
  EXPECT_EQ(f.spacing, (Vec3{0.5, 0.5, 0.5}));
  const LabelMapSummary sa = summarizeLabelMap(a), sf = summarizeLabelMap(f);
  for (int32_t id = 1; id <= 5; ++id) {  // same physical volumes within 15 %
    const double va = findStats(sa, id)->volumeMm3, vf = findStats(sf, id)->volumeMm3;
    EXPECT_NEAR(vf / va, 1.0, 0.15) << "label " << id;
  }
  EXPECT_GE(sf.quadrupleCells, 1u);
}

TEST(Phantom, WritesAndReadsBack) {
  const LabelVolume v = makePhantom();
  const std::string path = std::string(FEMESHER_TEST_TMP_DIR) + "/phantom_roundtrip.nrrd";
  std::filesystem::create_directories(FEMESHER_TEST_TMP_DIR);
  ASSERT_TRUE(writeLabelMap(v, path).isOk());
  auto r = readLabelMap(path);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_EQ(r->labels, v.labels);
  EXPECT_EQ(r->dims, v.dims);
  EXPECT_EQ(r->origin, v.origin);
  EXPECT_EQ(r->spacing, v.spacing);
  ASSERT_EQ(r->materials.size(), v.materials.size());
  for (size_t m = 0; m < v.materials.size(); ++m) {
    EXPECT_EQ(r->materials[m].id, v.materials[m].id);
    EXPECT_EQ(r->materials[m].name, v.materials[m].name);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(r->materials[m].color[c], v.materials[m].color[c], 1e-5);
  }
}
