// SPDX-License-Identifier: GPL-3.0-or-later
// Colour tables naming labels (io/LabelTable): 3D Slicer's .ctbl and .csv, ITK-SNAP's label
// description, the errors of malformed files, and naming the real knee's materials.
#include "MeshInvariants.h"

#include <femesher/io/LabelMapIO.h>
#include <femesher/io/LabelTable.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <string>

namespace fs = std::filesystem;
using namespace femesher;

namespace {

std::string writeFile(const std::string& name, const std::string& text) {
  const fs::path d = fs::path(FEMESHER_TEST_TMP_DIR) / "LabelTable";
  fs::create_directories(d);
  const std::string path = (d / name).string();
  std::ofstream(path) << text;
  return path;
}

std::map<int32_t, std::string> names(const std::vector<LabelTableEntry>& t) {
  std::map<int32_t, std::string> m;
  for (const auto& e : t) m[e.label] = e.name;
  return m;
}

}  // namespace

TEST(LabelTable, ReadsSlicerColorTableFile) {
  const auto path = writeFile("a.ctbl",
                              "# Color table file /tmp/a.ctbl\n# 4 values\n0 Background 0 0 0 0\n"
                              "1 artery 216 101 79 255\n\n  2 bone 241 214 145 255\r\n"
                              "3 connective_tissue 111 184 210 255\n");
  auto t = readLabelTable(path);
  ASSERT_TRUE(t.isOk()) << t.status().message();
  EXPECT_EQ(names(t.value()),
            (std::map<int32_t, std::string>{
                {0, "Background"}, {1, "artery"}, {2, "bone"}, {3, "connective_tissue"}}));
  EXPECT_TRUE(t->at(2).hasColor);
  EXPECT_NEAR(t->at(2).color[0], 241.0 / 255, 1e-12);
  EXPECT_EQ(t->at(2).line, 6);
}

TEST(LabelTable, ReadsSlicerCsvAndItkSnapLabelDescriptions) {
  auto csv = readLabelTable(writeFile(
      "b.csv",
      "LabelValue,Name,Color_R,Color_G,Color_B,Color_A\n1,\"bone, cortical\",241,214,145,255\n"
      "2,,0,0,0,255\n7,cartilage,111,184,210,255\n"));
  ASSERT_TRUE(csv.isOk()) << csv.status().message();
  EXPECT_EQ(names(csv.value()),
            (std::map<int32_t, std::string>{{1, "bone, cortical"}, {7, "cartilage"}}));
  auto snap = readLabelTable(writeFile(
      "c.label",
      "################################################\n# ITK-SnAP Label Description File\n"
      "# IDX   -R-  -G-  -B-  -A--  VIS MSH  LABEL\n"
      "    0     0    0    0        0  0  0    \"Clear Label\"\n"
      "    1   255    0    0        1  1  1    \"Femoral cartilage\"\n"
      "   12    0  255    0     0.5  1  1    \"Tibia (bone)\"\n"));
  ASSERT_TRUE(snap.isOk()) << snap.status().message();
  EXPECT_EQ(names(snap.value()),
            (std::map<int32_t, std::string>{
                {0, "Clear Label"}, {1, "Femoral cartilage"}, {12, "Tibia (bone)"}}));
  EXPECT_NEAR(snap->at(2).color[1], 1.0, 1e-12);
}

TEST(LabelTable, MalformedTablesAreClearErrors) {
  struct Case {
    const char* text;
    ErrorCode code;
    const char* says;
  };
  const Case cases[] = {
      {"1 bone 1 2 3 255\nbone 2 1 2 3 255\n", ErrorCode::CorruptFile,
       "line 2: 'bone' is not an integer label"},
      {"1\n", ErrorCode::CorruptFile, "line 1: the label has no name"},
      {"1 bone 1 2 300 255\n", ErrorCode::CorruptFile, "0 to 255"},
      {"1 bone 1 2 3 255\n1 marrow 1 2 3 255\n", ErrorCode::CorruptFile,
       "label 1 is given again (first on line 1)"},
      {"  1  255 0 0  1 1 1  \"unterminated\n", ErrorCode::CorruptFile, "closing quote"},
      {"# only comments\n\n", ErrorCode::UnreadableFile, "names no label"},
  };
  int n = 0;
  for (const auto& c : cases) {
    const auto path = writeFile("bad" + std::to_string(++n) + ".txt", c.text);
    auto t = readLabelTable(path);
    ASSERT_FALSE(t.isOk()) << c.text;
    EXPECT_EQ(t.status().code(), c.code) << c.text;
    EXPECT_NE(t.status().message().find(c.says), std::string::npos) << t.status().message();
    EXPECT_NE(t.status().message().find(path), std::string::npos) << t.status().message();
  }
  EXPECT_EQ(readLabelTable(writeFile("x", "") + ".missing").status().code(),
            ErrorCode::FileNotFound);
}

TEST(LabelTable, NamesTheRealKneesMaterials) {
  const std::string knee = femesher::testing::dataFile("9135902_00m_WB01.nii.gz");
  if (!fs::exists(knee)) {
    if (femesher::testing::inCI()) FAIL() << "missing " << knee;
    GTEST_SKIP() << "missing " << knee;
  }
  auto v = readLabelMap(knee);
  ASSERT_TRUE(v.isOk()) << v.status().message();
  EXPECT_EQ(v->materials.size(), 9u);
  const auto path = writeFile(
      "knee.ctbl",
      "# Color table file knee.ctbl\n0 Background 0 0 0 0\n1 femoral_bone 241 214 145 255\n"
      "2 femoral_cartilage 111 184 210 255\n3 tibial_bone 230 220 70 255\n"
      "4 tibial_cartilage 90 160 210 255\n5 patellar_bone 250 200 150 255\n"
      "6 patellar_cartilage 100 140 220 255\n7 femoral_bone_lesion 200 40 40 255\n"
      "8 tibial_bone_lesion 200 80 40 255\n9 patellar_bone_lesion 200 40 80 255\n"
      "42 not_in_the_knee 1 2 3 255\n");
  auto t = readLabelTable(path);
  ASSERT_TRUE(t.isOk()) << t.status().message();
  LabelVolume named = v.value();
  ASSERT_TRUE(applyLabelTable(named, t.value(), path).isOk());
  std::map<int32_t, std::string> got;
  for (const auto& m : named.materials) got[m.id] = m.name;
  EXPECT_EQ(got.at(2), "femoral_cartilage");
  EXPECT_EQ(got.at(9), "patellar_bone_lesion");
  EXPECT_EQ(got.size(), 9u);  // label 42 of the table is ignored
  EXPECT_NEAR(named.materials[6].color[0], 200.0 / 255, 1e-12);
  // A table for another map names none of the knee's labels: an error listing both.
  const auto other = writeFile("other.ctbl", "40 liver 1 2 3 255\n41 spleen 1 2 3 255\n");
  LabelVolume unnamed = v.value();
  const Status s = applyLabelTable(unnamed, readLabelTable(other).value(), other);
  EXPECT_EQ(s.code(), ErrorCode::InvalidArgument);
  for (const char* part : {"names none of the labels", "40, 41", "1, 2, 3, 4, 5, 6, 7, 8, 9"})
    EXPECT_NE(s.message().find(part), std::string::npos) << s.message();
}
