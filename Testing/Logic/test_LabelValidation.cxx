// SPDX-License-Identifier: GPL-3.0-or-later
// The label-map checks every label-map source shares (io/LabelValidation.h), called directly on
// buffers and volumes built in memory: voxel types and their conversion, geometry, the label
// count limits, distinct labels and the default material table.
#include <femesher/io/LabelValidation.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

using namespace femesher;

namespace {

LabelVolume volumeOf(std::array<int, 3> dims, std::vector<int32_t> labels) {
  LabelVolume v;
  v.dims = dims;
  v.labels = std::move(labels);
  return v;
}

template <class T>
Result<std::vector<int32_t>> convert(const std::vector<T>& values) {
  return labelsFromVoxels(values.data(), voxelTypeOf<T>(), values.size(), "in.nrrd");
}

void expectError(const Status& s, ErrorCode code, const std::string& what) {
  EXPECT_EQ(s.code(), code) << what << ": " << s.message();
  EXPECT_EQ(s.message().rfind("'in.nrrd'", 0), 0u) << what << ": " << s.message();
}

}  // namespace

TEST(LabelValidation, VoxelTypeOfEveryArithmeticType) {
  EXPECT_EQ(voxelTypeOf<uint8_t>(), VoxelType::UInt8);
  EXPECT_EQ(voxelTypeOf<int8_t>(), VoxelType::Int8);
  EXPECT_EQ(voxelTypeOf<uint16_t>(), VoxelType::UInt16);
  EXPECT_EQ(voxelTypeOf<int16_t>(), VoxelType::Int16);
  EXPECT_EQ(voxelTypeOf<uint32_t>(), VoxelType::UInt32);
  EXPECT_EQ(voxelTypeOf<int32_t>(), VoxelType::Int32);
  EXPECT_EQ(voxelTypeOf<uint64_t>(), VoxelType::UInt64);
  EXPECT_EQ(voxelTypeOf<int64_t>(), VoxelType::Int64);
  EXPECT_EQ(voxelTypeOf<float>(), VoxelType::Float32);
  EXPECT_EQ(voxelTypeOf<double>(), VoxelType::Float64);
  EXPECT_EQ(voxelTypeOf<long long>(), VoxelType::Int64);
  EXPECT_EQ(voxelTypeOf<unsigned long>(),
            sizeof(long) == 8 ? VoxelType::UInt64 : VoxelType::UInt32);
}

TEST(LabelValidation, IntegerVoxelsWithinInt32AreLabels) {
  EXPECT_EQ(convert<uint8_t>({0, 7, 255}).value(), (std::vector<int32_t>{0, 7, 255}));
  EXPECT_EQ(convert<int8_t>({-128, 0, 127}).value(), (std::vector<int32_t>{-128, 0, 127}));
  EXPECT_EQ(convert<uint16_t>({65535}).value(), (std::vector<int32_t>{65535}));
  EXPECT_EQ(convert<uint32_t>({2147483647u}).value(), (std::vector<int32_t>{2147483647}));
  EXPECT_EQ(convert<int64_t>({-2147483648LL, 2147483647LL}).value(),
            (std::vector<int32_t>{std::numeric_limits<int32_t>::min(), 2147483647}));
  EXPECT_EQ(convert<uint64_t>({3}).value(), (std::vector<int32_t>{3}));
  EXPECT_TRUE(convert<uint8_t>({}).value().empty());
}

TEST(LabelValidation, OutOfRangeIntegersAreNotALabelMap) {
  expectError(convert<uint32_t>({1, 2147483648u}).status(), ErrorCode::NotALabelMap, "uint32 2^31");
  expectError(convert<int64_t>({-2147483649LL}).status(), ErrorCode::NotALabelMap, "int64 below");
  expectError(convert<uint64_t>({uint64_t(1) << 40}).status(), ErrorCode::NotALabelMap,
              "uint64 2^40");
  EXPECT_NE(convert<int64_t>({int64_t(1) << 33}).status().message().find("32-bit"),
            std::string::npos);
}

TEST(LabelValidation, FloatVoxelsMustAllBeIntegers) {
  EXPECT_EQ(convert<float>({0.f, 3.f, -2.f}).value(), (std::vector<int32_t>{0, 3, -2}));
  EXPECT_EQ(convert<double>({2147483647.0, -2147483648.0}).value(),
            (std::vector<int32_t>{2147483647, std::numeric_limits<int32_t>::min()}));
  const auto ct = convert<float>({0.f, 1.f, 2.5f});
  expectError(ct.status(), ErrorCode::NotALabelMap, "2.5");
  EXPECT_NE(ct.status().message().find("CT/intensity"), std::string::npos);
  expectError(convert<double>({std::nan("")}).status(), ErrorCode::NotALabelMap, "NaN");
  expectError(convert<double>({std::numeric_limits<double>::infinity()}).status(),
              ErrorCode::NotALabelMap, "infinity");
  expectError(convert<double>({1e10}).status(), ErrorCode::NotALabelMap, "1e10");
}

TEST(LabelValidation, GeometryNeedsPositiveSpacingIndependentAxesAndVoxels) {
  LabelVolume v = volumeOf({2, 2, 2}, std::vector<int32_t>(8, 1));
  EXPECT_TRUE(validateLabelGeometry(v, "in.nrrd").isOk());
  // Oblique and left-handed is fine.
  const double c = std::cos(0.3), s = std::sin(0.3);
  v.direction = {c, -s, 0, s, c, 0, 0, 0, -1};
  v.spacing = {0.7, 0.36458, 1.9};
  EXPECT_TRUE(validateLabelGeometry(v, "in.nrrd").isOk());
  LabelVolume bad = v;
  bad.spacing[1] = 0;
  expectError(validateLabelGeometry(bad, "in.nrrd"), ErrorCode::CorruptFile, "zero spacing");
  bad.spacing[1] = std::nan("");
  expectError(validateLabelGeometry(bad, "in.nrrd"), ErrorCode::CorruptFile, "NaN spacing");
  bad = v;
  bad.direction = {1, 0, 1, 0, 1, 0, 1, 0, 1};  // first and third axes equal
  expectError(validateLabelGeometry(bad, "in.nrrd"), ErrorCode::CorruptFile,
              "degenerate direction");
  bad = v;
  bad.dims = {4, 0, 2};
  expectError(validateLabelGeometry(bad, "in.nrrd"), ErrorCode::EmptyLabelMap, "no voxels");
}

TEST(LabelValidation, GeometryNamesTheFieldAndValueOfAnAbsurdHeader) {
  LabelVolume v = volumeOf({2, 2, 2}, std::vector<int32_t>(8, 1));
  auto message = [](const Status& s) { return s.message(); };
  auto has = [](const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
  };
  LabelVolume bad = v;
  bad.spacing[2] = -0.5;
  std::string m = message(validateLabelGeometry(bad, "in.nrrd"));
  EXPECT_TRUE(has(m, "spacing along axis k is -0.5 mm") && has(m, "femesher info")) << m;
  bad = v;
  bad.spacing[0] = std::numeric_limits<double>::infinity();
  m = message(validateLabelGeometry(bad, "in.nrrd"));
  EXPECT_TRUE(has(m, "spacing along axis i is inf mm") && has(m, "finite")) << m;
  bad = v;
  bad.direction[4] = std::nan("");  // NaN makes the determinant NaN, which must not pass
  expectError(validateLabelGeometry(bad, "in.nrrd"), ErrorCode::CorruptFile, "NaN direction");
  bad = v;
  bad.direction = {1, 0, 0, 0, 1, 0, 0, 0, 0};
  expectError(validateLabelGeometry(bad, "in.nrrd"), ErrorCode::CorruptFile, "singular");
  bad = v;
  bad.origin[1] = std::nan("");
  m = message(validateLabelGeometry(bad, "in.nrrd"));
  EXPECT_TRUE(has(m, "origin is nan mm")) << m;
  bad = v;
  bad.origin = {1e300, 0, 0};
  m = message(validateLabelGeometry(bad, "in.nrrd"));
  EXPECT_EQ(validateLabelGeometry(bad, "in.nrrd").code(), ErrorCode::CorruptFile) << m;
  EXPECT_TRUE(has(m, "(1e+300, 0, 0)") && has(m, "precision")) << m;
  bad.origin = {0, -2e12, 0};  // beyond 1e12 mm even though 1 mm voxels would still be exact
  expectError(validateLabelGeometry(bad, "in.nrrd"), ErrorCode::CorruptFile, "origin 2e12");
  // 1e9 mm is exact to 1e-6 of a 1 mm voxel (ulp 1.2e-7 mm), not of a 0.001 mm voxel.
  bad.origin = {1e9, 0, 0};
  EXPECT_TRUE(validateLabelGeometry(bad, "in.nrrd").isOk());
  bad.spacing = {0.001, 0.001, 0.001};
  expectError(validateLabelGeometry(bad, "in.nrrd"), ErrorCode::CorruptFile, "origin 1e9");
  bad.origin = {1e5, -3e4, 250};  // a scanner origin far from 0 is fine
  EXPECT_TRUE(validateLabelGeometry(bad, "in.nrrd").isOk());
}

TEST(LabelValidation, VolumeReturnsItsLabelsWithoutBackground) {
  const LabelVolume v = volumeOf({2, 2, 2}, {0, 5, 5, -3, 0, 70000, 5, 0});
  const auto present = validateLabelVolume(v, "in.nrrd");
  ASSERT_TRUE(present.isOk()) << present.status().message();
  EXPECT_EQ(present.value(), (std::vector<int32_t>{-3, 5, 70000}));
  // No background at all: every label counts.
  const auto full = validateLabelVolume(volumeOf({2, 1, 1}, {4, 2}), "in.nrrd");
  ASSERT_TRUE(full.isOk());
  EXPECT_EQ(full.value(), (std::vector<int32_t>{2, 4}));
}

TEST(LabelValidation, VolumeErrors) {
  expectError(
      validateLabelVolume(volumeOf({2, 2, 2}, std::vector<int32_t>(8, 0)), "in.nrrd").status(),
      ErrorCode::EmptyLabelMap, "only background");
  expectError(validateLabelVolume(volumeOf({2, 2, 2}, {1, 2, 3}), "in.nrrd").status(),
              ErrorCode::InvalidArgument, "3 labels for 8 voxels");
  LabelVolume zeroSpacing = volumeOf({1, 1, 1}, {1});
  zeroSpacing.spacing[0] = 0;
  expectError(validateLabelVolume(zeroSpacing, "in.nrrd").status(), ErrorCode::CorruptFile,
              "geometry is checked too");
}

TEST(LabelValidation, AtMost65535LabelsBesidesBackground) {
  std::vector<int32_t> labels(65536);
  for (size_t i = 0; i < labels.size(); ++i) labels[i] = int32_t(i);  // 0 and 1..65535
  const auto ok = validateLabelVolume(volumeOf({256, 256, 1}, labels), "in.nrrd");
  ASSERT_TRUE(ok.isOk()) << ok.status().message();
  EXPECT_EQ(ok.value().size(), kMaxLabels);
  labels[0] = 65536;  // 1..65536: one too many
  expectError(validateLabelVolume(volumeOf({256, 256, 1}, labels), "in.nrrd").status(),
              ErrorCode::TooManyLabels, "65,536 labels");
  // Labels spread over the whole int32 range (counted with a hash set) are limited the same way.
  for (size_t i = 0; i < labels.size(); ++i) labels[i] = int32_t(i) * 32768 - (1 << 30) + 1;
  expectError(validateLabelVolume(volumeOf({256, 256, 1}, labels), "in.nrrd").status(),
              ErrorCode::TooManyLabels, "spread labels");
}

TEST(LabelValidation, DistinctLabelsSortedForSmallAndHugeRanges) {
  EXPECT_EQ(distinctLabels({3, 1, 3, -2, 1}), (std::vector<int32_t>{-2, 1, 3}));
  EXPECT_TRUE(distinctLabels({}).empty());
  const int32_t lo = std::numeric_limits<int32_t>::min(), hi = std::numeric_limits<int32_t>::max();
  EXPECT_EQ(distinctLabels({hi, 0, lo, hi, 0}), (std::vector<int32_t>{lo, 0, hi}));
  // With a limit, counting a huge range may stop once more than `limit` values are found.
  std::vector<int32_t> spread;
  for (int32_t i = 0; i < 1000; ++i) spread.push_back(i * 2000000 - 1000000000);
  const auto limited = distinctLabels(spread, 10);
  EXPECT_GT(limited.size(), 10u);
  EXPECT_TRUE(std::is_sorted(limited.begin(), limited.end()));
  EXPECT_EQ(distinctLabels(spread).size(), 1000u);
}

TEST(LabelValidation, DefaultMaterialsNameAndColourEveryId) {
  const auto table = defaultMaterials({-1, 4, 12});
  ASSERT_EQ(table.size(), 3u);
  EXPECT_EQ(table[0].id, -1);
  EXPECT_EQ(table[0].name, "label -1");
  EXPECT_EQ(table[2].name, "label 12");
  EXPECT_EQ(table[1].color, defaultLabelColor(4));
  EXPECT_TRUE(defaultMaterials({}).empty());
}
