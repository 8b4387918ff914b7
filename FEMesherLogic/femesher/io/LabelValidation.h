// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file LabelValidation.h
/// What makes a volume a label map FEMesher can mesh, checked the same way wherever a label map
/// comes from: a file (`readLabelMap`), a VTK image (`labelVolumeFromVtkImage`, used by the 3D
/// Slicer module), or a volume built in memory.
///
/// Every error message starts with the quoted `source` (a path or a node name) and says what to
/// do about the problem.

#include <femesher/Status.h>
#include <femesher/Types.h>

#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

namespace femesher {

/// The most distinct labels, background (0) not counted, that a label map may hold.
constexpr size_t kMaxLabels = 65535;

/// The numeric types voxel values may come in (native byte order).
enum class VoxelType { UInt8, Int8, UInt16, Int16, UInt32, Int32, UInt64, Int64, Float32, Float64 };

/// The VoxelType of the arithmetic type T (e.g. `unsigned long` -> UInt64 on LP64 systems).
template <class T>
constexpr VoxelType voxelTypeOf() {
  static_assert(std::is_arithmetic_v<T> && sizeof(T) <= 8, "voxel values are numbers");
  if constexpr (std::is_floating_point_v<T>) {
    static_assert(sizeof(T) == 4 || sizeof(T) == 8, "float or double");
    return sizeof(T) == 4 ? VoxelType::Float32 : VoxelType::Float64;
  } else if constexpr (std::is_signed_v<T>) {
    return sizeof(T) == 1   ? VoxelType::Int8
           : sizeof(T) == 2 ? VoxelType::Int16
           : sizeof(T) == 4 ? VoxelType::Int32
                            : VoxelType::Int64;
  } else {
    return sizeof(T) == 1   ? VoxelType::UInt8
           : sizeof(T) == 2 ? VoxelType::UInt16
           : sizeof(T) == 4 ? VoxelType::UInt32
                            : VoxelType::UInt64;
  }
}

/// Voxel values -> int32 labels: `values` points at `count` values of `type`.
/// Integer values must lie within int32; floating-point values must all be integers within int32
/// (NaN and infinities are not).
/// Errors: NotALabelMap, for a non-integer value (the volume is a CT/intensity image, not labels)
/// or a value outside the 32-bit range.
Result<std::vector<int32_t>> labelsFromVoxels(const void* values, VoxelType type, size_t count,
                                              const std::string& source);

/// The largest |origin| coordinate (mm) a label map may have: 1e12 mm.
constexpr double kMaxCoordinate = 1e12;

/// Whether coordinates up to `largest` mm (a double) are exact to 1e-6 of a voxel of `spacing` mm.
inline bool coordinatesExact(double largest, double spacing) {
  return largest * std::numeric_limits<double>::epsilon() <= 1e-6 * spacing;
}

/// The geometry of a label map, checked before its voxels are read: every spacing finite and
/// > 0 mm, a finite direction matrix whose axes are independent (|det| >= 1e-6), a finite origin
/// within kMaxCoordinate of 0 from which every voxel position is a double exact to 1e-6 of the
/// smallest spacing, else CorruptFile naming the field and its value (see labelio::badGeometry);
/// at least one voxel, else EmptyLabelMap.
Status validateLabelGeometry(const LabelVolume& volume, const std::string& source);

/// A whole label map: `validateLabelGeometry`, one label per voxel (InvalidArgument otherwise),
/// at most kMaxLabels distinct labels besides background (TooManyLabels: an intensity image
/// stored as integers) and at least one (EmptyLabelMap: only background).
/// `volume.materials` is not looked at. Returns the distinct labels other than 0, ascending:
/// the ids the material table must hold (see `defaultMaterials`).
Result<std::vector<int32_t>> validateLabelVolume(const LabelVolume& volume,
                                                 const std::string& source);

/// The distinct values of `labels`, ascending. Once more than `limit` distinct values are found
/// counting may stop: the result then holds more than `limit` values, but maybe not all.
std::vector<int32_t> distinctLabels(const std::vector<int32_t>& labels,
                                    size_t limit = std::numeric_limits<size_t>::max());

/// A material table with one material per id, in the order given: named "label N" and coloured
/// defaultLabelColor(N).
std::vector<Material> defaultMaterials(const std::vector<int32_t>& ids);

}  // namespace femesher
