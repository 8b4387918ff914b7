// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/io/LabelMapFiles.h>
#include <femesher/io/LabelValidation.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <unordered_set>

namespace femesher {

namespace {

/// Label ranges up to this size are counted with a flat histogram, larger ones with a hash set.
constexpr int64_t kFlatRange = int64_t(1) << 24;

using labelio::quoted;

enum class Conversion { Ok, NonInteger, OutOfRange };

/// Native buffer -> int32, in one loop per type.
template <class T>
Conversion convertBuffer(const void* data, size_t n, std::vector<int32_t>& out) {
  const T* p = static_cast<const T*>(data);
  out.resize(n);
  int32_t* o = out.data();
  if constexpr (std::is_floating_point_v<T>) {
    for (size_t i = 0; i < n; ++i) {
      const T v = p[i];
      if (!(v == std::floor(v))) return Conversion::NonInteger;  // also NaN and infinities
      if (v > T(2147483647.0) || v < T(-2147483648.0)) return Conversion::OutOfRange;
      o[i] = int32_t(v);
    }
  } else if constexpr (sizeof(T) < 4 || (sizeof(T) == 4 && std::is_signed_v<T>)) {
    for (size_t i = 0; i < n; ++i) o[i] = int32_t(p[i]);
  } else {
    bool bad = false;
    for (size_t i = 0; i < n; ++i) {
      const T v = p[i];
      if constexpr (std::is_signed_v<T>)
        bad |= v < T(std::numeric_limits<int32_t>::min()) ||
               v > T(std::numeric_limits<int32_t>::max());
      else
        bad |= v > T(std::numeric_limits<int32_t>::max());
      o[i] = int32_t(v);
    }
    if (bad) return Conversion::OutOfRange;
  }
  return Conversion::Ok;
}

template <class T>
Result<std::vector<int32_t>> convert(const void* values, size_t count, const std::string& source) {
  std::vector<int32_t> labels;
  const Conversion c = convertBuffer<T>(values, count, labels);
  if (c == Conversion::NonInteger)
    return Result<std::vector<int32_t>>(
        ErrorCode::NotALabelMap,
        quoted(source) +
            " holds non-integer values: it looks like a CT/intensity image, not labels. "
            "Segment it first (e.g. in 3D Slicer's Segment Editor) and export the "
            "segmentation as a label map.");
  if (c == Conversion::OutOfRange)
    return Result<std::vector<int32_t>>(
        ErrorCode::NotALabelMap,
        quoted(source) +
            " holds values outside the 32-bit integer range, which cannot be labels. "
            "Check that this is a label map; renumber the labels if it is.");
  return labels;
}

}  // namespace

Result<std::vector<int32_t>> labelsFromVoxels(const void* values, VoxelType type, size_t count,
                                              const std::string& source) {
  switch (type) {
    case VoxelType::UInt8:
      return convert<uint8_t>(values, count, source);
    case VoxelType::Int8:
      return convert<int8_t>(values, count, source);
    case VoxelType::UInt16:
      return convert<uint16_t>(values, count, source);
    case VoxelType::Int16:
      return convert<int16_t>(values, count, source);
    case VoxelType::UInt32:
      return convert<uint32_t>(values, count, source);
    case VoxelType::Int32:
      return convert<int32_t>(values, count, source);
    case VoxelType::UInt64:
      return convert<uint64_t>(values, count, source);
    case VoxelType::Int64:
      return convert<int64_t>(values, count, source);
    case VoxelType::Float32:
      return convert<float>(values, count, source);
    case VoxelType::Float64:
      return convert<double>(values, count, source);
  }
  return Result<std::vector<int32_t>>(ErrorCode::Internal, "labelsFromVoxels: unknown voxel type");
}

Status validateLabelGeometry(const LabelVolume& v, const std::string& source) {
  using labelio::badGeometry;
  using labelio::number;
  static const char* axisName[3] = {"i", "j", "k"};
  for (int a = 0; a < 3; ++a)
    if (!(v.spacing[a] > 0) || !std::isfinite(v.spacing[a]))
      return badGeometry(source, std::string("spacing along axis ") + axisName[a],
                         number(v.spacing[a]) + " mm",
                         std::isfinite(v.spacing[a]) ? "a voxel size must be greater than 0"
                                                     : "a voxel size must be a finite number");
  for (int k = 0; k < 9; ++k)
    if (!std::isfinite(v.direction[k]))
      return badGeometry(source,
                         "direction matrix entry (row " + std::to_string(k / 3) + ", column " +
                             std::to_string(k % 3) + ")",
                         number(v.direction[k]), "its entries must be finite numbers");
  const double det = v.directionDeterminant();
  if (!(std::fabs(det) >= 1e-6))
    return badGeometry(source, "direction matrix's determinant", number(det),
                       "its axes are not independent, so voxels have no volume");
  for (int r = 0; r < 3; ++r)
    if (!std::isfinite(v.origin[r]))
      return badGeometry(source, "origin", number(v.origin[r]) + " mm",
                         "a position must be a finite number");
  // Coordinates are doubles: every voxel position must be representable to 1e-6 of the smallest
  // voxel (the mesh's vertices would otherwise collapse onto a few points).
  const double minSpacing = std::min({v.spacing[0], v.spacing[1], v.spacing[2]});
  double largest = 0;
  for (int corner = 0; corner < 8; ++corner)
    for (int r = 0; r < 3; ++r) {
      double x = v.origin[r];
      for (int a = 0; a < 3; ++a)
        if (corner & (1 << a))
          x += v.direction[3 * r + a] * v.spacing[a] * std::max(0, v.dims[a] - 1);
      largest = std::max(largest, std::fabs(x));
    }
  const double maxOrigin = std::max({std::fabs(v.origin[0]), std::fabs(v.origin[1]),
                                     std::fabs(v.origin[2])});
  if (maxOrigin > kMaxCoordinate || !coordinatesExact(largest, minSpacing))
    return badGeometry(source, "origin",
                       "(" + number(v.origin[0]) + ", " + number(v.origin[1]) + ", " +
                           number(v.origin[2]) + ") mm",
                       "so far from 0 that voxel positions (up to " + number(largest) +
                           " mm) lose their precision for voxels of " + number(minSpacing) +
                           " mm; the origin must lie within " + number(kMaxCoordinate) + " mm");
  if (v.voxelCount() == 0) return {ErrorCode::EmptyLabelMap, quoted(source) + " has no voxels."};
  return Status::ok();
}

Result<std::vector<int32_t>> validateLabelVolume(const LabelVolume& v, const std::string& source) {
  using R = Result<std::vector<int32_t>>;
  if (Status s = validateLabelGeometry(v, source); !s) return s;
  if (v.labels.size() != v.voxelCount())
    return R(ErrorCode::InvalidArgument, quoted(source) + " holds " +
                                             std::to_string(v.labels.size()) + " labels for " +
                                             std::to_string(v.voxelCount()) + " voxels.");
  std::vector<int32_t> present = distinctLabels(v.labels, kMaxLabels + 1);
  present.erase(std::remove(present.begin(), present.end(), 0), present.end());
  if (present.size() > kMaxLabels)
    return R(ErrorCode::TooManyLabels,
             quoted(source) +
                 " has more than 65,535 distinct labels: it is probably an intensity image "
                 "stored as integers, not a segmentation. Segment it first, or merge labels.");
  if (present.empty())
    return R(ErrorCode::EmptyLabelMap,
             quoted(source) +
                 " holds only background (0): there is nothing to mesh. Check that you "
                 "picked the segmentation and that it is not empty.");
  return present;
}

std::vector<int32_t> distinctLabels(const std::vector<int32_t>& labels, size_t limit) {
  std::vector<int32_t> out;
  if (labels.empty()) return out;
  const auto [mnIt, mxIt] = std::minmax_element(labels.begin(), labels.end());
  const int64_t mn = *mnIt, mx = *mxIt;
  if (mx - mn < kFlatRange) {
    std::vector<uint8_t> seen(size_t(mx - mn + 1), 0);
    for (int32_t x : labels) seen[size_t(int64_t(x) - mn)] = 1;
    for (size_t i = 0; i < seen.size(); ++i)
      if (seen[i]) out.push_back(int32_t(int64_t(i) + mn));
    return out;
  }
  std::unordered_set<int32_t> seen;
  int32_t last = labels[0];
  seen.insert(last);
  for (int32_t x : labels) {
    if (x == last) continue;
    last = x;
    seen.insert(x);
    if (seen.size() > limit) break;
  }
  out.assign(seen.begin(), seen.end());
  std::sort(out.begin(), out.end());
  return out;
}

/// Merge the layers of a .seg.nrrd (layer index fastest in `values`) into one label per voxel.
/// Material ids are the segments' LabelValues when these are unique across layers, otherwise the

std::vector<Material> defaultMaterials(const std::vector<int32_t>& ids) {
  std::vector<Material> table;
  table.reserve(ids.size());
  for (int32_t id : ids)
    table.push_back({id, "label " + std::to_string(id), defaultLabelColor(id)});
  return table;
}

}  // namespace femesher
