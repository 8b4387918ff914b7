// SPDX-License-Identifier: GPL-3.0-or-later
// Label map reading/writing and statistics: every label map of FEMESHER_DATA_DIR against the
// numbers of its README, generated bad inputs (one per error code), Slicer .seg.nrrd layers, and
// round trips through NRRD, NIfTI and MetaImage with oblique, left-handed, anisotropic geometry.
#include <femesher/io/LabelMapIO.h>

#include <gtest/gtest.h>
#include <itkImage.h>
#include <itkImageFileReader.h>
#include <itkImageFileWriter.h>
#include <itkVectorImage.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace femesher;

namespace {

struct LabelRow {
  int32_t id;
  size_t voxels;
  int components;
};
struct DataCase {
  std::string file;
  std::array<int, 3> dims;
  Vec3 spacing;
  std::vector<LabelRow> labels;
  size_t pairs, triple, quad;
};

// Generated from the tables of FEMESHER_DATA_DIR/README.md.
const std::vector<DataCase> kDataCases = {
    {"420.nrrd", {2, 2, 2}, {100, 100, 100}, {{0, 2, 1}, {2, 2, 1}, {4, 4, 1}}, 3, 1, 0},
    {"40420.nrrd", {2, 2, 2}, {100, 100, 100}, {{0, 3, 2}, {2, 2, 1}, {4, 3, 1}}, 3, 1, 0},
    {"12323.nrrd", {2, 2, 2}, {100, 100, 100}, {{0, 3, 1}, {1, 1, 1}, {2, 2, 1}, {3, 2, 1}}, 5, 1, 1},
    {"20012323.nrrd", {2, 2, 2}, {100, 100, 100}, {{0, 2, 2}, {1, 1, 1}, {2, 3, 1}, {3, 2, 1}}, 5, 1, 1},
    {"mickey.nrrd", {63, 63, 63}, {1, 1, 1}, {{1, 232028, 1}, {2, 16348, 1}, {3, 822, 1}, {4, 822, 1}, {5, 27, 1}}, 6, 116, 0},
    {"spheres_argmax.nrrd", {28, 28, 28}, {1, 1, 1}, {{1, 7463, 1}, {2, 2924, 1}, {3, 5714, 1}, {4, 5851, 1}}, 6, 122, 1},
    {"colin27_v3.nrrd", {181, 217, 181}, {1, 1, 1}, {{0, 3068647, 19}, {1, 1457090, 773}, {2, 498234, 1112}, {3, 308195, 2573}, {4, 990129, 705}, {5, 660550, 503}, {6, 126292, 1271}}, 16, 83231, 2063},
    {"digimouse.nrrd", {190, 496, 104}, {0.2, 0.2, 0.2}, {{0, 7002524, 1}, {1, 2093709, 795}, {2, 147684, 39}, {3, 696, 2}, {4, 5734, 1}, {5, 3839, 1}, {6, 2313, 1}, {7, 17090, 1}, {8, 3228, 1}, {9, 27846, 1}, {10, 19833, 150}, {11, 13413, 2}, {12, 3829, 2}, {13, 23724, 1}, {14, 18625, 2}, {15, 28193, 1}, {16, 17394, 1}, {17, 5506, 1}, {18, 250998, 3}, {19, 61922, 2}, {20, 724, 2}, {21, 52136, 1}}, 58, 18546, 412},
    {"frogtissue.nrrd", {500, 470, 136}, {1, 1, 1.5}, {{0, 30803043, 1174}, {1, 35279, 194}, {2, 19172, 1}, {3, 38129, 1}, {4, 37146, 10}, {5, 16085, 6}, {6, 37030, 2}, {7, 27807, 3}, {8, 39181, 3}, {9, 51297, 2}, {10, 204672, 27}, {11, 47626, 7}, {12, 24263, 105}, {13, 440722, 289}, {14, 3891, 4}, {15, 133880, 28}, {16, 252, 52}, {17, 38, 21}, {20, 29, 18}, {21, 4, 4}, {23, 6, 5}, {24, 239, 26}, {25, 121, 65}, {26, 16, 10}, {27, 32, 2}, {29, 40, 5}}, 96, 29155, 1065},
    {"example_seg.nii.gz", {122, 101, 30}, {3, 3, 3}, {{0, 259435, 203}, {1, 9452, 1}, {2, 3947, 1}, {3, 3676, 1}, {4, 1333, 1}, {5, 38634, 1}, {6, 4675, 1}, {7, 644, 5}, {8, 152, 2}, {9, 184, 1}, {10, 259, 1}, {11, 1312, 1}, {13, 1, 1}, {14, 2735, 2}, {18, 1020, 4}, {19, 1110, 2}, {20, 12993, 2}, {30, 1868, 1}, {31, 2139, 1}, {32, 1783, 1}, {33, 70, 1}, {52, 997, 1}, {63, 1368, 1}, {64, 901, 3}, {79, 492, 1}, {86, 7050, 1}, {87, 6635, 1}, {88, 410, 1}, {89, 360, 1}, {98, 103, 1}, {99, 171, 1}, {100, 213, 1}, {101, 210, 2}, {102, 234, 1}, {103, 132, 3}, {110, 64, 1}, {111, 147, 1}, {112, 170, 1}, {113, 195, 1}, {114, 203, 1}, {115, 83, 2}, {117, 2100, 8}}, 100, 3726, 12},
    {"example_seg_dicom.nii.gz", {512, 512, 20}, {0.9765625, 0.9765625, 2}, {{0, 4503460, 23}, {1, 130634, 1}, {5, 366708, 1}, {6, 74102, 1}, {7, 1327, 1}, {8, 1254, 1}, {20, 10340, 1}, {32, 23576, 2}, {33, 9930, 10}, {52, 11723, 1}, {63, 4772, 2}, {64, 3015, 2}, {69, 9108, 1}, {70, 10424, 1}, {79, 4911, 1}, {86, 16338, 1}, {87, 21605, 1}, {97, 708, 2}, {98, 2085, 2}, {99, 2196, 1}, {100, 2043, 1}, {101, 2337, 1}, {102, 1860, 1}, {103, 123, 1}, {109, 432, 2}, {110, 2730, 1}, {111, 2163, 1}, {112, 2750, 1}, {113, 2418, 1}, {114, 2079, 1}, {115, 288, 1}, {117, 15441, 2}}, 48, 2346, 15},
    {"9135902_00m_WB01.nii.gz", {160, 384, 384}, {0.7, 0.36458, 0.36458}, {{0, 19484866, 108}, {1, 2323147, 13}, {2, 141196, 8}, {3, 1219588, 3}, {4, 57975, 7}, {5, 303416, 12}, {6, 44296, 14}, {7, 1180, 4}, {8, 399, 1}, {9, 16897, 5}}, 23, 8747, 56},
};

bool inCI() {
  const char* ci = std::getenv("CI");
  return ci && std::string(ci) == "true";
}

std::string dataFile(const std::string& name) { return std::string(FEMESHER_DATA_DIR) + "/" + name; }

std::string tmpFile(const std::string& name) {
  const fs::path dir = fs::path(FEMESHER_TEST_TMP_DIR) / "labelmapio";
  fs::create_directories(dir);
  return (dir / name).string();
}

/// Missing real data: a failure in CI, a skip elsewhere.
#define REQUIRE_DATA(path)                                                        \
  do {                                                                            \
    if (!fs::exists(path)) {                                                      \
      if (inCI()) FAIL() << "missing test data file " << (path);                  \
      GTEST_SKIP() << "missing test data file " << (path);                        \
    }                                                                             \
  } while (0)

void writeBytes(const std::string& path, const std::string& header, const void* data, size_t bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << header;
  out.write(static_cast<const char*>(data), std::streamsize(bytes));
}

/// Asserts the error code and that the message names the file.
void expectError(const std::string& path, ErrorCode code) {
  auto r = readLabelMap(path);
  ASSERT_FALSE(r.isOk()) << path << " was accepted";
  EXPECT_EQ(r.status().code(), code) << r.status().message();
  EXPECT_NE(r.status().message().find(path), std::string::npos) << r.status().message();
}

LabelVolume smallVolume(std::array<int, 3> dims) {
  LabelVolume v;
  v.dims = dims;
  v.labels.assign(v.voxelCount(), 0);
  return v;
}

/// Oblique, left-handed direction (a rotation about an oblique axis, then one axis flipped).
Mat3 obliqueLeftHanded() {
  const double a = 0.3, b = -0.7;
  const double ca = std::cos(a), sa = std::sin(a), cb = std::cos(b), sb = std::sin(b);
  // Rz(a) * Rx(b), then negate the second column.
  Mat3 rz{ca, -sa, 0, sa, ca, 0, 0, 0, 1}, rx{1, 0, 0, 0, cb, -sb, 0, sb, cb}, m{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 3; ++k) m[size_t(3 * r + c)] += rz[size_t(3 * r + k)] * rx[size_t(3 * k + c)];
  for (int r = 0; r < 3; ++r) m[size_t(3 * r + 1)] = -m[size_t(3 * r + 1)];
  return m;
}

/// A 3-material test volume with oblique left-handed geometry and anisotropic spacing.
LabelVolume geometryVolume(int32_t a, int32_t b, int32_t c) {
  LabelVolume v = smallVolume({13, 9, 7});
  v.spacing = {0.7, 0.36458333333333331, 1.9};
  v.origin = {-24.003, 51.7996, -57.13971};
  v.direction = obliqueLeftHanded();
  for (int k = 0; k < 7; ++k)
    for (int j = 0; j < 9; ++j)
      for (int i = 0; i < 13; ++i)
        v.labels[v.index(i, j, k)] = (i + j + k) % 5 == 0 ? 0 : (i < 5 ? a : (j < 4 ? b : c));
  return v;
}

const LabelStatistics* findStats(const LabelMapSummary& s, int32_t id) {
  for (const auto& l : s.labels)
    if (l.id == id) return &l;
  return nullptr;
}

/// Minimal NRRD header for hand-written inputs (raw encoding, little endian).
std::string nrrdHeader(const std::string& type, const std::string& sizes, int dimension,
                       const std::string& extra = "") {
  return "NRRD0004\ntype: " + type + "\ndimension: " + std::to_string(dimension) + "\nsizes: " + sizes +
         "\nendian: little\nencoding: raw\n" + extra + "\n";
}

class LabelMapIORealData : public ::testing::TestWithParam<DataCase> {};

}  // namespace

TEST_P(LabelMapIORealData, MatchesReadme) {
  const DataCase& c = GetParam();
  const std::string path = dataFile(c.file);
  REQUIRE_DATA(path);
  auto r = readLabelMap(path);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  const LabelVolume& v = r.value();
  EXPECT_EQ(v.dims, c.dims);
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(v.spacing[a], c.spacing[a], 1e-5) << "axis " << a;
  EXPECT_NEAR(std::fabs(v.directionDeterminant()), 1.0, 1e-6);
  EXPECT_EQ(v.sourcePath, path);
  // Material table: every non-zero label, sorted, default names and colours.
  std::vector<int32_t> expectedIds;
  for (const auto& row : c.labels)
    if (row.id != 0) expectedIds.push_back(row.id);
  ASSERT_EQ(v.materials.size(), expectedIds.size());
  for (size_t m = 0; m < expectedIds.size(); ++m) {
    EXPECT_EQ(v.materials[m].id, expectedIds[m]);
    EXPECT_EQ(v.materials[m].name, "label " + std::to_string(expectedIds[m]));
    EXPECT_EQ(v.materials[m].color, defaultLabelColor(expectedIds[m]));
  }
  // Statistics.
  const LabelMapSummary s = summarizeLabelMap(v);
  ASSERT_EQ(s.labels.size(), c.labels.size());
  const double voxelVolume = v.spacing[0] * v.spacing[1] * v.spacing[2];
  for (size_t l = 0; l < c.labels.size(); ++l) {
    EXPECT_EQ(s.labels[l].id, c.labels[l].id);
    EXPECT_EQ(s.labels[l].voxels, c.labels[l].voxels) << "label " << c.labels[l].id;
    EXPECT_EQ(s.labels[l].components, c.labels[l].components) << "label " << c.labels[l].id;
    EXPECT_NEAR(s.labels[l].volumeMm3, double(c.labels[l].voxels) * voxelVolume, 1e-6 * s.labels[l].volumeMm3);
    for (int a = 0; a < 3; ++a) {
      EXPECT_LE(s.labels[l].bboxMin[a], s.labels[l].bboxMax[a]);
      EXPECT_GE(s.labels[l].bboxMin[a], 0);
      EXPECT_LT(s.labels[l].bboxMax[a], v.dims[a]);
    }
  }
  EXPECT_EQ(s.touchingPairs.size(), c.pairs);
  EXPECT_EQ(s.tripleCells, c.triple);
  EXPECT_EQ(s.quadrupleCells, c.quad);
}

INSTANTIATE_TEST_SUITE_P(LabelMapIO, LabelMapIORealData, ::testing::ValuesIn(kDataCases),
                         [](const ::testing::TestParamInfo<DataCase>& info) {
                           std::string n = info.param.file;
                           for (auto& ch : n)
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           return n;
                         });

TEST(LabelMapIO, KneeIsObliqueWithOriginAndAnisotropicSpacing) {
  const std::string path = dataFile("9135902_00m_WB01.nii.gz");
  REQUIRE_DATA(path);
  auto r = readLabelMap(path);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  const LabelVolume& v = r.value();
  const Mat3 expected{-0.978, 0.208, 0, -0.208, -0.978, 0, 0, 0, 1};
  for (int e = 0; e < 9; ++e) EXPECT_NEAR(v.direction[size_t(e)], expected[size_t(e)], 1e-3) << "element " << e;
  EXPECT_NEAR(v.origin[0], -24.00, 0.005);
  EXPECT_NEAR(v.origin[1], 51.80, 0.005);
  EXPECT_NEAR(v.origin[2], -57.14, 0.005);
  EXPECT_NEAR(v.spacing[0], 0.7, 1e-5);
  EXPECT_NEAR(v.spacing[1], 0.36458, 1e-5);
  EXPECT_NEAR(v.spacing[2], 0.36458, 1e-5);
  EXPECT_NEAR(v.directionDeterminant(), 1.0, 1e-4);
  // The same corner through the LabelVolume mapping and by hand.
  const Vec3 p = v.indexToPhysical({159, 383, 383});
  for (int r2 = 0; r2 < 3; ++r2) {
    double x = v.origin[size_t(r2)];
    for (int c = 0; c < 3; ++c)
      x += v.direction[size_t(3 * r2 + c)] * v.spacing[size_t(c)] * double(std::array<int, 3>{159, 383, 383}[size_t(c)]);
    EXPECT_NEAR(p[size_t(r2)], x, 1e-9);
  }
}

TEST(LabelMapIO, TotalSegmentatorNiftiGeometry) {
  const std::string path = dataFile("example_seg.nii.gz");
  REQUIRE_DATA(path);
  auto r = readLabelMap(path);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  // RAS axes in the file -> LPS: x and y flipped.
  EXPECT_NEAR(r->direction[0], -1, 1e-6);
  EXPECT_NEAR(r->direction[4], -1, 1e-6);
  EXPECT_NEAR(r->direction[8], 1, 1e-6);
  EXPECT_NEAR(r->origin[0], 177.96, 0.005);
  EXPECT_NEAR(r->origin[1], -11.32, 0.005);
  EXPECT_NEAR(r->origin[2], 94.30, 0.005);
}

TEST(LabelMapIO, FrogMetaImageWithLyingHeaderIsCorrupt) {
  const std::string path = dataFile("orig/frogtissue.mhd");
  REQUIRE_DATA(path);
  REQUIRE_DATA(dataFile("orig/frogtissue.zraw"));
  expectError(path, ErrorCode::CorruptFile);
  const std::string msg = readLabelMap(path).status().message();
  EXPECT_NE(msg.find("CompressedDataSize"), std::string::npos) << msg;
  EXPECT_NE(msg.find("262087"), std::string::npos) << msg;
}

TEST(LabelMapIO, CleaverIndicatorFunctionIsNotALabelMap) {
  const std::string path = dataFile("spheres1.nrrd");
  REQUIRE_DATA(path);
  expectError(path, ErrorCode::NotALabelMap);
}

// --- generated bad inputs ----------------------------------------------------------------------

TEST(LabelMapIO, MissingFile) {
  expectError(tmpFile("does_not_exist.nrrd"), ErrorCode::FileNotFound);
  EXPECT_EQ(readLabelMap("").status().code(), ErrorCode::FileNotFound);
}

TEST(LabelMapIO, FolderEmptyFileAndTextFileAreUnreadable) {
  const std::string dir = tmpFile("a_folder.nrrd");
  fs::create_directories(dir);
  expectError(dir, ErrorCode::UnreadableFile);
  const std::string empty = tmpFile("empty.nrrd");
  writeBytes(empty, "", nullptr, 0);
  expectError(empty, ErrorCode::UnreadableFile);
  const std::string text = tmpFile("notes.nrrd");
  writeBytes(text, "These are my notes about the knee segmentation.\nNothing to see here.\n", nullptr, 0);
  expectError(text, ErrorCode::UnreadableFile);
  const std::string unknown = tmpFile("volume.xyz");
  writeBytes(unknown, "12345", nullptr, 0);
  expectError(unknown, ErrorCode::UnreadableFile);
}

TEST(LabelMapIO, FloatImageWithNonIntegerValuesIsNotALabelMap) {
  LabelVolume g = smallVolume({6, 5, 4});
  std::vector<float> values(g.voxelCount(), 0.f);
  for (size_t i = 0; i < values.size(); ++i) values[i] = float(i) * 0.37f - 3.f;  // a CT-like ramp
  const std::string path = tmpFile("ct_like.nrrd");
  ASSERT_TRUE(writeScalarVolume(g, values, path).isOk());
  expectError(path, ErrorCode::NotALabelMap);
  EXPECT_NE(readLabelMap(path).status().message().find("CT/intensity"), std::string::npos);
}

TEST(LabelMapIO, FloatImageWithIntegerValuesIsAccepted) {
  LabelVolume g = smallVolume({6, 5, 4});
  std::vector<float> values(g.voxelCount(), 0.f);
  for (size_t i = 0; i < values.size(); ++i) values[i] = float(i % 3) * 7.f - 7.f;  // -7, 0, 7
  const std::string path = tmpFile("float_labels.nii.gz");
  ASSERT_TRUE(writeScalarVolume(g, values, path).isOk());
  auto r = readLabelMap(path);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  for (size_t i = 0; i < values.size(); ++i) ASSERT_EQ(r->labels[i], int32_t(values[i]));
  ASSERT_EQ(r->materials.size(), 2u);
  EXPECT_EQ(r->materials[0].id, -7);
  EXPECT_EQ(r->materials[1].id, 7);
}

TEST(LabelMapIO, AllZeroIsEmpty) {
  const LabelVolume v = smallVolume({8, 8, 8});
  const std::string path = tmpFile("all_zero.nrrd");
  ASSERT_TRUE(writeLabelMap(v, path).isOk());
  expectError(path, ErrorCode::EmptyLabelMap);
}

TEST(LabelMapIO, TwoDimensionalImageIsNotALabelMap) {
  const std::string path = tmpFile("slice.nrrd");
  std::vector<uint8_t> data(16 * 12, 0);
  for (size_t i = 0; i < data.size(); ++i) data[i] = uint8_t(i % 3);
  writeBytes(path, nrrdHeader("uint8", "16 12", 2), data.data(), data.size());
  expectError(path, ErrorCode::NotALabelMap);
  EXPECT_NE(readLabelMap(path).status().message().find("3-D"), std::string::npos);
}

TEST(LabelMapIO, VectorImageIsNotALabelMap) {
  const std::string path = tmpFile("rgb.nrrd");
  std::vector<uint8_t> data(3 * 5 * 4 * 3, 1);
  writeBytes(path, nrrdHeader("uint8", "3 5 4 3", 4, "kinds: RGB-color domain domain domain\n"), data.data(),
             data.size());
  expectError(path, ErrorCode::NotALabelMap);
}

TEST(LabelMapIO, FourDimensionalImageWithSingletonAxisIsRead) {
  const std::string path = tmpFile("singleton4d.nrrd");
  std::vector<uint16_t> data(5 * 4 * 3, 0);
  data[7] = 300;
  data[20] = 2;
  writeBytes(path, nrrdHeader("uint16", "5 4 3 1", 4), data.data(), data.size() * 2);
  auto r = readLabelMap(path);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_EQ(r->dims, (std::array<int, 3>{5, 4, 3}));
  EXPECT_EQ(r->labels[7], 300);
  ASSERT_EQ(r->materials.size(), 2u);
  // A real time series is refused.
  const std::string series = tmpFile("series4d.nrrd");
  std::vector<uint16_t> two(5 * 4 * 3 * 2, 1);
  writeBytes(series, nrrdHeader("uint16", "5 4 3 2", 4), two.data(), two.size() * 2);
  expectError(series, ErrorCode::NotALabelMap);
}

TEST(LabelMapIO, TruncatedCompressedNrrdIsCorrupt) {
  LabelVolume v = smallVolume({40, 40, 40});
  uint32_t state = 12345;  // pseudo-random labels so that gzip cannot shrink the data much
  for (auto& x : v.labels) {
    state = state * 1664525u + 1013904223u;
    x = int32_t(state >> 28);
  }
  const std::string path = tmpFile("truncated.nrrd");
  ASSERT_TRUE(writeLabelMap(v, path).isOk());
  ASSERT_TRUE(readLabelMap(path).isOk());
  const auto size = fs::file_size(path);
  fs::resize_file(path, size / 2);
  expectError(path, ErrorCode::CorruptFile);
}

TEST(LabelMapIO, TruncatedRawNrrdIsCorrupt) {
  const std::string path = tmpFile("truncated_raw.nrrd");
  std::vector<uint8_t> data(10 * 10 * 10, 1);
  writeBytes(path, nrrdHeader("uint8", "10 10 10", 3), data.data(), data.size() - 100);
  expectError(path, ErrorCode::CorruptFile);
}

TEST(LabelMapIO, TruncatedNiftiIsCorrupt) {
  // ITK reads all three silently (zero-filled): FEMesher must not.
  LabelVolume v = smallVolume({40, 40, 40});
  for (size_t i = 0; i < v.labels.size(); ++i) v.labels[i] = int32_t((i * 2654435761u) >> 29);
  const std::string path = tmpFile("truncated.nii");
  ASSERT_TRUE(writeLabelMap(v, path).isOk());
  ASSERT_TRUE(readLabelMap(path).isOk());
  fs::resize_file(path, fs::file_size(path) - 5000);
  expectError(path, ErrorCode::CorruptFile);
  // A .nii.gz whose gzip stream is cut.
  const std::string gz = tmpFile("truncated_stream.nii.gz");
  ASSERT_TRUE(writeLabelMap(v, gz).isOk());
  ASSERT_TRUE(readLabelMap(gz).isOk());
  fs::resize_file(gz, fs::file_size(gz) * 2 / 3);
  expectError(gz, ErrorCode::CorruptFile);
  // A complete gzip stream of a short .nii.
  std::ifstream in(path, std::ios::binary);
  const std::string shortNii((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string gzShort = tmpFile("short_data.nii.gz");
  gzFile f = gzopen(gzShort.c_str(), "wb");
  ASSERT_NE(f, nullptr);
  gzwrite(f, shortNii.data(), unsigned(shortNii.size()));
  gzclose(f);
  expectError(gzShort, ErrorCode::CorruptFile);
}

TEST(LabelMapIO, MetaImageWithShortRawDataIsCorrupt) {
  const std::string path = tmpFile("short.mhd");
  std::ofstream(path) << "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
                         "CompressedData = False\nElementSpacing = 1 1 1\nDimSize = 10 10 10\n"
                         "ElementType = MET_USHORT\nElementDataFile = short.raw\n";
  std::vector<uint16_t> data(10 * 10 * 10 - 50, 3);
  writeBytes(tmpFile("short.raw"), "", data.data(), data.size() * 2);
  expectError(path, ErrorCode::CorruptFile);
  // Missing data file.
  const std::string orphan = tmpFile("orphan.mhd");
  std::ofstream(orphan) << "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_UCHAR\n"
                           "ElementDataFile = orphan_missing.raw\n";
  expectError(orphan, ErrorCode::CorruptFile);
}

TEST(LabelMapIO, MetaImageWithLyingCompressedSizeIsCorrupt) {
  // A valid compressed .mhd, then its header edited to understate the data (like the frog file).
  LabelVolume v = geometryVolume(1, 2, 3);
  const std::string path = tmpFile("lying.mhd");
  ASSERT_TRUE(writeLabelMap(v, path).isOk());
  ASSERT_TRUE(readLabelMap(path).isOk());
  std::ifstream in(path);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto pos = text.find("CompressedDataSize = ");
  ASSERT_NE(pos, std::string::npos);
  const auto end = text.find('\n', pos);
  const long declared = std::stol(text.substr(pos + 21, end - pos - 21));
  text = text.substr(0, pos) + "CompressedDataSize = " + std::to_string(declared - 7) + text.substr(end);
  std::ofstream(path, std::ios::trunc) << text;
  expectError(path, ErrorCode::CorruptFile);
}

TEST(LabelMapIO, MoreThan65535LabelsIsTooMany) {
  LabelVolume v = smallVolume({50, 50, 30});
  for (size_t i = 0; i < v.labels.size(); ++i) v.labels[i] = int32_t(i % 70000) + 1;
  const std::string path = tmpFile("too_many.nrrd");
  ASSERT_TRUE(writeLabelMap(v, path).isOk());
  expectError(path, ErrorCode::TooManyLabels);
  // Exactly 65,535 labels plus background is fine.
  for (size_t i = 0; i < v.labels.size(); ++i) v.labels[i] = int32_t(i % 65536);
  const std::string ok = tmpFile("max_labels.nrrd");
  ASSERT_TRUE(writeLabelMap(v, ok).isOk());
  auto r = readLabelMap(ok);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_EQ(r->materials.size(), 65535u);
}

TEST(LabelMapIO, Int64LabelsOutsideInt32AreNotALabelMap) {
  using Image = itk::Image<long long, 3>;
  auto image = Image::New();
  Image::SizeType size;
  size.Fill(4);
  image->SetRegions(size);
  image->Allocate();
  image->FillBuffer(3);
  const std::string ok = tmpFile("int64_ok.nrrd");
  auto writer = itk::ImageFileWriter<Image>::New();
  writer->SetInput(image);
  writer->SetFileName(ok);
  writer->Update();
  auto r = readLabelMap(ok);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_EQ(r->labels[5], 3);
  image->GetBufferPointer()[9] = 5000000000LL;
  const std::string bad = tmpFile("int64_bad.nrrd");
  writer->SetFileName(bad);
  writer->Modified();
  writer->Update();
  expectError(bad, ErrorCode::NotALabelMap);
}

namespace {

template <class T>
std::vector<int32_t> writeNativeAndRead(const std::vector<T>& values, const std::string& name) {
  using Image = itk::Image<T, 3>;
  auto image = Image::New();
  typename Image::SizeType size;
  size[0] = 5;
  size[1] = 3;
  size[2] = 2;
  image->SetRegions(size);
  image->Allocate();
  std::copy(values.begin(), values.end(), image->GetBufferPointer());
  auto writer = itk::ImageFileWriter<Image>::New();
  writer->SetInput(image);
  writer->SetFileName(tmpFile(name));
  writer->Update();
  auto r = readLabelMap(tmpFile(name));
  EXPECT_TRUE(r.isOk()) << r.status().message();
  return r.isOk() ? r->labels : std::vector<int32_t>{};
}

template <class T>
void checkNative(const std::string& name) {
  std::vector<T> values(30);
  for (size_t i = 0; i < values.size(); ++i)
    values[i] = T(std::is_signed_v<T> ? (int(i % 7) - 3) * 9 : int(i % 7) * 30);
  const std::vector<int32_t> labels = writeNativeAndRead(values, name);
  ASSERT_EQ(labels.size(), values.size()) << name;
  for (size_t i = 0; i < values.size(); ++i) EXPECT_EQ(labels[i], int32_t(values[i])) << name;
}

}  // namespace

TEST(LabelMapIO, EveryIntegerPixelType) {
  checkNative<uint8_t>("u8.nrrd");
  checkNative<int8_t>("s8.nrrd");
  checkNative<uint16_t>("u16.mha");
  checkNative<int16_t>("s16.nii.gz");
  checkNative<uint32_t>("u32.nrrd");
  checkNative<int32_t>("s32.nii");
  checkNative<uint64_t>("u64.nrrd");
  checkNative<int64_t>("s64.mha");
  checkNative<double>("f64.nrrd");
}

// --- Slicer segmentations -------------------------------------------------------------------------

namespace {

std::string segmentKeys(int n, const std::string& name, const std::string& color, int labelValue, int layer) {
  const std::string k = "Segment" + std::to_string(n) + "_";
  return k + "Color:=" + color + "\n" + k + "ID:=Segment_" + std::to_string(n + 1) + "\n" + k +
         "LabelValue:=" + std::to_string(labelValue) + "\n" + k + "Layer:=" + std::to_string(layer) + "\n" + k +
         "Name:=" + name + "\n";
}

const std::string kSegGeometry =
    "space: left-posterior-superior\nspace origin: (10.5,-20.25,30)\n";

/// A 2-layer .seg.nrrd (8x6x5, layer axis first, Slicer's "list" kind). Layer 0 has "femur"
/// (value 1) and "tibia" (value 2); layer 1 has "cartilage" (value 1). `overlap` voxels of
/// cartilage are also femur.
std::string writeTwoLayerSeg(const std::string& name, int overlap, bool uniqueValues) {
  const int nx = 8, ny = 6, nz = 5;
  std::vector<uint8_t> data(size_t(2 * nx * ny * nz), 0);
  auto at = [&](int layer, int i, int j, int k) -> uint8_t& {
    return data[size_t(layer) + 2 * (size_t(i) + size_t(nx) * (size_t(j) + size_t(ny) * size_t(k)))];
  };
  const uint8_t cartilageValue = uniqueValues ? 3 : 1;
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        if (i < 3) at(0, i, j, k) = 1;
        else if (i > 5) at(0, i, j, k) = 2;
        else at(1, i, j, k) = cartilageValue;
      }
  int made = 0;
  for (int k = 0; k < nz && made < overlap; ++k)
    for (int j = 0; j < ny && made < overlap; ++j, ++made) at(1, 2, j, k) = cartilageValue;
  const std::string header =
      "NRRD0004\ntype: unsigned char\ndimension: 4\nsizes: 2 8 6 5\n" + kSegGeometry +
      "space directions: none (0,1.5,0) (-1,0,0) (0,0,2)\nkinds: list domain domain domain\nendian: little\n"
      "encoding: raw\n" +
      segmentKeys(0, "femur", "0.9 0.8 0.7", 1, 0) + segmentKeys(1, "tibia", "0.1 0.2 0.3", 2, 0) +
      segmentKeys(2, "cartilage", "0.2 0.6 1", cartilageValue, 1) + "\n";
  const std::string path = tmpFile(name);
  writeBytes(path, header, data.data(), data.size());
  return path;
}

}  // namespace

TEST(LabelMapIO, SegNrrdSingleLayerNamesColoursAndLabelValues) {
  const int nx = 7, ny = 5, nz = 4;
  std::vector<uint8_t> data(size_t(nx * ny * nz), 0);
  for (size_t i = 0; i < data.size(); ++i) data[i] = uint8_t(i % 4 == 1 ? 1 : (i % 4 == 2 ? 5 : 0));
  const std::string header = "NRRD0004\ntype: unsigned char\ndimension: 3\nsizes: 7 5 4\n" + kSegGeometry +
                             "space directions: (0.5,0,0) (0,0.75,0) (0,0,1.25)\nkinds: domain domain domain\n"
                             "endian: little\nencoding: raw\n" +
                             segmentKeys(0, "femoral bone", "0.945098 0.839216 0.568627", 1, 0) +
                             segmentKeys(1, "implant screw", "0.2 0.3 1", 5, 0) + "\n";
  const std::string path = tmpFile("single_layer.seg.nrrd");
  writeBytes(path, header, data.data(), data.size());
  auto r = readLabelMap(path);
  ASSERT_TRUE(r.isOk()) << r.status().message();
  EXPECT_EQ(r->dims, (std::array<int, 3>{7, 5, 4}));
  EXPECT_EQ(r->spacing, (Vec3{0.5, 0.75, 1.25}));
  EXPECT_EQ(r->origin, (Vec3{10.5, -20.25, 30}));
  ASSERT_EQ(r->materials.size(), 2u);
  EXPECT_EQ(r->materials[0].id, 1);
  EXPECT_EQ(r->materials[0].name, "femoral bone");
  EXPECT_NEAR(r->materials[0].color[0], 0.945098, 1e-9);
  EXPECT_NEAR(r->materials[0].color[2], 0.568627, 1e-9);
  EXPECT_EQ(r->materials[1].id, 5);
  EXPECT_EQ(r->materials[1].name, "implant screw");
  EXPECT_EQ(r->materials[1].color, (std::array<double, 3>{0.2, 0.3, 1}));
  for (size_t i = 0; i < data.size(); ++i) ASSERT_EQ(r->labels[i], int32_t(data[i]));
}

TEST(LabelMapIO, SegNrrdTwoLayersWithoutOverlapAreMerged) {
  for (bool unique : {false, true}) {
    const std::string path = writeTwoLayerSeg(unique ? "layers_unique.seg.nrrd" : "layers.seg.nrrd", 0, unique);
    auto r = readLabelMap(path);
    ASSERT_TRUE(r.isOk()) << r.status().message();
    EXPECT_EQ(r->dims, (std::array<int, 3>{8, 6, 5}));
    EXPECT_EQ(r->spacing, (Vec3{1.5, 1, 2}));
    EXPECT_EQ(r->origin, (Vec3{10.5, -20.25, 30}));
    EXPECT_EQ(r->direction, (Mat3{0, -1, 0, 1, 0, 0, 0, 0, 1}));  // columns = axis directions
    ASSERT_EQ(r->materials.size(), 3u);
    // Layer 1 reuses LabelValue 1: segments are numbered in header order; else LabelValues are kept.
    const int32_t cartilage = unique ? 3 : 3;
    EXPECT_EQ(r->materials[0].name, "femur");
    EXPECT_EQ(r->materials[1].name, "tibia");
    EXPECT_EQ(r->materials[2].name, "cartilage");
    EXPECT_EQ(r->materials[2].id, cartilage);
    EXPECT_EQ(r->materials[2].color, (std::array<double, 3>{0.2, 0.6, 1}));
    EXPECT_EQ(r->at(0, 0, 0), 1);
    EXPECT_EQ(r->at(7, 5, 4), 2);
    EXPECT_EQ(r->at(4, 2, 2), cartilage);
    const LabelMapSummary s = summarizeLabelMap(r.value());
    EXPECT_EQ(findStats(s, cartilage)->voxels, size_t(3 * 6 * 5));
  }
}

TEST(LabelMapIO, SegNrrdOverlappingLayersAreRefused) {
  const std::string path = writeTwoLayerSeg("overlap.seg.nrrd", 7, false);
  expectError(path, ErrorCode::OverlappingSegments);
  const std::string msg = readLabelMap(path).status().message();
  EXPECT_NE(msg.find("'femur' and 'cartilage' overlap in 7 voxels"), std::string::npos) << msg;
  EXPECT_NE(msg.find("Logical operators"), std::string::npos) << msg;
}

TEST(LabelMapIO, SegNrrdDuplicateLabelValuesInOneLayerAreRefused) {
  // Two segments with LabelValue 1 in layer 0: every voxel of value 1 would belong to both.
  std::vector<uint8_t> data(size_t(4 * 4 * 4), 0);
  for (size_t i = 0; i < data.size(); ++i) data[i] = uint8_t(i % 3 == 0 ? 1 : (i % 3 == 1 ? 2 : 0));
  const std::string header = "NRRD0004\ntype: unsigned char\ndimension: 3\nsizes: 4 4 4\n" + kSegGeometry +
                             "space directions: (1,0,0) (0,1,0) (0,0,1)\nkinds: domain domain domain\n"
                             "endian: little\nencoding: raw\n" +
                             segmentKeys(0, "femur", "1 0 0", 1, 0) + segmentKeys(1, "tibia", "0 1 0", 2, 0) +
                             segmentKeys(2, "patella", "0 0 1", 1, 0) + "\n";
  const std::string path = tmpFile("duplicate_value.seg.nrrd");
  writeBytes(path, header, data.data(), data.size());
  expectError(path, ErrorCode::OverlappingSegments);
  const std::string msg = readLabelMap(path).status().message();
  EXPECT_NE(msg.find("'femur' (ID Segment_1) and 'patella' (ID Segment_3) both have LabelValue 1 in layer 0"),
            std::string::npos)
      << msg;
  EXPECT_NE(msg.find("re-export"), std::string::npos) << msg;
}

// --- writing -------------------------------------------------------------------------------------

class LabelMapIORoundTrip : public ::testing::TestWithParam<std::string> {};

TEST_P(LabelMapIORoundTrip, LabelsAndGeometry) {
  const std::string ext = GetParam();
  const bool nifti = ext.rfind(".nii", 0) == 0;
  // uint8, uint16 and int32 (negative) label ranges.
  for (const auto& ids : {std::array<int32_t, 3>{1, 2, 200}, std::array<int32_t, 3>{3, 4000, 65535},
                          std::array<int32_t, 3>{-5, 7, 100000}}) {
    LabelVolume v = geometryVolume(ids[0], ids[1], ids[2]);
    v.materials = {{ids[0], "first", {0.1, 0.2, 0.3}}, {ids[1], "second", {0.4, 0.5, 0.6}},
                   {ids[2], "third", {0.7, 0.8, 0.9}}};
    std::sort(v.materials.begin(), v.materials.end(), [](auto& a, auto& b) { return a.id < b.id; });
    const std::string path = tmpFile("roundtrip_" + std::to_string(ids[2]) + ext);
    ASSERT_TRUE(writeLabelMap(v, path).isOk());
    // No temporary file of this write is left behind (ctest -j runs the other formats'
    // round trips in the same directory at the same time: only this file's prefix counts).
    const std::string name = fs::path(path).filename().string();
    const std::string mine = "." + name.substr(0, name.size() - ext.size()) + ".tmp";
    for (const auto& e : fs::directory_iterator(fs::path(path).parent_path())) {
      const std::string f = e.path().filename().string();
      const bool sameWrite = f.rfind(mine, 0) == 0 && f.size() >= ext.size() &&
                             f.compare(f.size() - ext.size(), ext.size(), ext) == 0;
      EXPECT_FALSE(sameWrite) << e.path();
    }
    auto r = readLabelMap(path);
    ASSERT_TRUE(r.isOk()) << r.status().message();
    EXPECT_EQ(r->labels, v.labels);
    EXPECT_EQ(r->dims, v.dims);
    // NIfTI stores geometry in float32; NRRD and MetaImage keep doubles (spacing*direction is
    // stored as one vector, so the last bit may change when it is split again).
    const double tol = nifti ? 2e-5 : 1e-14;
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(r->spacing[a], v.spacing[a], tol * 10);
      EXPECT_NEAR(r->origin[a], v.origin[a], tol * 100);
    }
    for (int e = 0; e < 9; ++e) EXPECT_NEAR(r->direction[size_t(e)], v.direction[size_t(e)], tol);
    EXPECT_NEAR(r->directionDeterminant(), -1.0, 1e-5);
    ASSERT_EQ(r->materials.size(), 3u);
    for (size_t m = 0; m < 3; ++m) EXPECT_EQ(r->materials[m].id, v.materials[m].id);
    if (!nifti) {  // NRRD and MetaImage keep FEMesher's material table
      for (size_t m = 0; m < 3; ++m) {
        EXPECT_EQ(r->materials[m].name, v.materials[m].name);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(r->materials[m].color[c], v.materials[m].color[c], 1e-6);
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(LabelMapIO, LabelMapIORoundTrip, ::testing::Values(".nrrd", ".nhdr", ".nii.gz", ".nii", ".mha", ".mhd"),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           std::string n = info.param.substr(1);
                           for (auto& ch : n)
                             if (ch == '.') ch = '_';
                           return n;
                         });

TEST(LabelMapIO, NrrdIsGzipAndSmallestType) {
  LabelVolume v = geometryVolume(1, 2, 3);
  const std::string path = tmpFile("types_u8.nrrd");
  ASSERT_TRUE(writeLabelMap(v, path).isOk());
  std::ifstream in(path, std::ios::binary);
  std::string header, line;
  while (std::getline(in, line) && !line.empty()) header += line + "\n";
  EXPECT_NE(header.find("encoding: gzip"), std::string::npos) << header;
  EXPECT_NE(header.find("type: unsigned char"), std::string::npos) << header;
  v = geometryVolume(1, 2, 300);
  ASSERT_TRUE(writeLabelMap(v, tmpFile("types_u16.nrrd")).isOk());
  auto io = itk::ImageIOFactory::CreateImageIO(tmpFile("types_u16.nrrd").c_str(), itk::ImageIOFactory::IOFileModeEnum::ReadMode);
  ASSERT_TRUE(io);
  io->SetFileName(tmpFile("types_u16.nrrd"));
  io->ReadImageInformation();
  EXPECT_EQ(io->GetComponentType(), itk::IOComponentEnum::USHORT);
  v = geometryVolume(-1, 2, 3);
  ASSERT_TRUE(writeLabelMap(v, tmpFile("types_s32.nrrd")).isOk());
  io->SetFileName(tmpFile("types_s32.nrrd"));
  io->ReadImageInformation();
  EXPECT_EQ(io->GetComponentType(), itk::IOComponentEnum::INT);
}

TEST(LabelMapIO, ScalarVolumeKeepsValuesAndGeometry) {
  const LabelVolume g = geometryVolume(1, 2, 3);
  std::vector<float> values(g.voxelCount());
  for (size_t i = 0; i < values.size(); ++i) values[i] = 0.25f + float(i) * 0.013f;
  for (const std::string ext : {".nrrd", ".nii.gz"}) {
    const std::string path = tmpFile("sizing" + ext);
    ASSERT_TRUE(writeScalarVolume(g, values, path).isOk());
    using Image = itk::Image<float, 3>;
    auto reader = itk::ImageFileReader<Image>::New();
    reader->SetFileName(path);
    reader->Update();
    Image::Pointer image = reader->GetOutput();
    auto io = reader->GetImageIO();
    EXPECT_EQ(io->GetComponentType(), itk::IOComponentEnum::FLOAT);
    const float* buf = image->GetBufferPointer();
    for (size_t i = 0; i < values.size(); ++i) ASSERT_EQ(buf[i], values[i]);
    const double tol = ext == ".nrrd" ? 1e-14 : 2e-5;
    for (unsigned a = 0; a < 3; ++a) {
      EXPECT_NEAR(image->GetSpacing()[a], g.spacing[a], tol);
      EXPECT_NEAR(image->GetOrigin()[a], g.origin[a], tol * 100);
      for (unsigned r = 0; r < 3; ++r) EXPECT_NEAR(image->GetDirection()[r][a], g.direction[3 * r + a], tol);
    }
  }
  EXPECT_EQ(writeScalarVolume(g, std::vector<float>(3), tmpFile("wrong.nrrd")).code(), ErrorCode::InvalidArgument);
}

TEST(LabelMapIO, FailedWritesLeaveNoFile) {
  const LabelVolume v = geometryVolume(1, 2, 3);
  const std::string noFolder = tmpFile("no_such_folder") + "/x.nrrd";
  EXPECT_EQ(writeLabelMap(v, noFolder).code(), ErrorCode::WriteFailed);
  EXPECT_FALSE(fs::exists(noFolder));
  const std::string badExt = tmpFile("labels.unknownformat");
  EXPECT_EQ(writeLabelMap(v, badExt).code(), ErrorCode::InvalidArgument);
  EXPECT_FALSE(fs::exists(badExt));
  LabelVolume empty;
  EXPECT_EQ(writeLabelMap(empty, tmpFile("empty_out.nrrd")).code(), ErrorCode::InvalidArgument);
}

// --- statistics on generated volumes ---------------------------------------------------------------

TEST(LabelMapIO, SummaryOfGeneratedVolume) {
  // Background with: label 1 = two separate 2x2x2 cubes, label 2 = an L-shaped bar touching one of
  // them, label -3 = a single voxel; and one 2x2x2 cell with four labels.
  LabelVolume v = smallVolume({10, 8, 6});
  v.spacing = {0.5, 2, 3};
  auto set = [&](int i, int j, int k, int32_t l) { v.labels[v.index(i, j, k)] = l; };
  for (int k = 1; k < 3; ++k)
    for (int j = 1; j < 3; ++j)
      for (int i = 1; i < 3; ++i) {
        set(i, j, k, 1);
        set(i + 6, j + 4, k + 2, 1);
      }
  for (int i = 3; i < 7; ++i) set(i, 1, 1, 2);  // touches the first cube at (3,1,1)
  set(6, 2, 1, 2);                              // the L
  set(6, 3, 1, 2);
  set(5, 3, 1, -3);  // cell (5..6, 2..3, 1..2) holds 0, 2, -3 ...
  set(5, 2, 2, 4);   // ... and 4 (touching only 0): a quadruple cell
  const LabelMapSummary s = summarizeLabelMap(v);
  ASSERT_EQ(s.labels.size(), 5u);
  EXPECT_EQ(s.labels[0].id, 0);  // background first, then ascending ids
  EXPECT_EQ(s.labels[1].id, -3);
  EXPECT_EQ(s.labels[2].id, 1);
  EXPECT_EQ(s.labels[0].name, "background");
  EXPECT_EQ(s.labels[2].name, "label 1");
  const LabelStatistics* one = findStats(s, 1);
  EXPECT_EQ(one->voxels, 16u);
  EXPECT_EQ(one->components, 2);
  EXPECT_DOUBLE_EQ(one->volumeMm3, 16 * 3.0);
  EXPECT_EQ(one->bboxMin, (std::array<int, 3>{1, 1, 1}));
  EXPECT_EQ(one->bboxMax, (std::array<int, 3>{8, 6, 4}));
  const LabelStatistics* two = findStats(s, 2);
  EXPECT_EQ(two->voxels, 6u);
  EXPECT_EQ(two->components, 1);
  EXPECT_EQ(two->bboxMax, (std::array<int, 3>{6, 3, 1}));
  EXPECT_EQ(findStats(s, -3)->components, 1);
  EXPECT_EQ(findStats(s, 0)->components, 1);
  const std::vector<std::pair<int32_t, int32_t>> pairs = {{-3, 0}, {-3, 2}, {0, 1}, {0, 2}, {0, 4},
                                                          {1, 2}};
  EXPECT_EQ(s.touchingPairs, pairs);
  EXPECT_GE(s.quadrupleCells, 1u);
  EXPECT_GE(s.tripleCells, s.quadrupleCells);
  // Brute-force cell counts.
  size_t triple = 0, quad = 0;
  for (int k = 0; k + 1 < 6; ++k)
    for (int j = 0; j + 1 < 8; ++j)
      for (int i = 0; i + 1 < 10; ++i) {
        std::set<int32_t> c;
        for (int q = 0; q < 8; ++q) c.insert(v.at(i + (q & 1), j + ((q >> 1) & 1), k + ((q >> 2) & 1)));
        triple += c.size() >= 3;
        quad += c.size() >= 4;
      }
  EXPECT_EQ(s.tripleCells, triple);
  EXPECT_EQ(s.quadrupleCells, quad);
}

TEST(LabelMapIO, SummaryComponentsOfSpiral) {
  // A single winding path (many runs that only join through other rows and slices) is one
  // component; a checkerboard of one label has every voxel alone.
  LabelVolume v = smallVolume({9, 9, 3});
  for (int j = 0; j < 9; j += 2)
    for (int i = 0; i < 9; ++i) v.labels[v.index(i, j, 1)] = 1;
  for (int j = 1; j < 9; j += 2) v.labels[v.index((j / 2) % 2 == 0 ? 8 : 0, j, 1)] = 1;
  for (int j = 0; j < 9; ++j)
    for (int i = 0; i < 9; ++i)
      if ((i + j) % 2 == 0) v.labels[v.index(i, j, 0)] = 2;
  const LabelMapSummary s = summarizeLabelMap(v);
  EXPECT_EQ(findStats(s, 1)->components, 1);
  EXPECT_EQ(findStats(s, 2)->components, 41);
}
