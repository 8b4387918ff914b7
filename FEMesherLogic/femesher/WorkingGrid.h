// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file WorkingGrid.h
/// The grid every stage after LabelPreprocess works on: the input's voxels cropped to the labelled
/// box plus a margin, and the conversions between the four frames a run uses:
///
/// | frame     | unit  | origin                               | who uses it                       |
/// |-----------|-------|--------------------------------------|-----------------------------------|
/// | local     | voxel | working-grid voxel (0,0,0)           | indicator functions, particles    |
/// | grid mm   | mm    | working-grid voxel (0,0,0)           | sizing field, medial axis         |
/// | canonical | mm    | input voxel (0,0,0), axes = voxel axes | Delaunay, TetGen, Optimize      |
/// | physical  | mm    | LPS (ITK/Slicer), input origin + direction | written meshes, previews    |
///
/// canonical = (local + offset) * spacing; grid mm = local * spacing; physical =
/// LabelVolume::canonicalToPhysical(canonical). All conversions are exact in the sense that they
/// are the same arithmetic wherever they are done: use these and never re-derive them.

#include <femesher/Types.h>

#include <array>

namespace femesher {

struct WorkingGrid {
  std::array<int, 3> dims{{0, 0, 0}};
  Vec3 spacing{{1, 1, 1}};  ///< mm, the input's
  /// Index of local voxel (0,0,0) in the input grid (may be negative: padding).
  std::array<int, 3> offset{{0, 0, 0}};
  /// Dims of the input grid (0 = unknown). The meshed domain is the input's box: voxel centres
  /// 0..inputDims-1 plus half a voxel, i.e. local [-offset - 0.5, inputDims - offset - 0.5].
  std::array<int, 3> inputDims{{0, 0, 0}};

  size_t voxelCount() const { return size_t(dims[0]) * size_t(dims[1]) * size_t(dims[2]); }
  size_t index(int i, int j, int k) const {
    return size_t(i) + size_t(dims[0]) * (size_t(j) + size_t(dims[1]) * size_t(k));
  }
  /// The smallest spacing: the "voxel" of parameters given in voxels (facet distance, ...).
  double minSpacing() const;
  /// Local (continuous) voxel index -> canonical frame of the input (mm).
  Vec3 localToCanonical(const Vec3& l) const {
    return {(l[0] + offset[0]) * spacing[0], (l[1] + offset[1]) * spacing[1],
            (l[2] + offset[2]) * spacing[2]};
  }
  Vec3 canonicalToLocal(const Vec3& c) const {
    return {c[0] / spacing[0] - offset[0], c[1] / spacing[1] - offset[1],
            c[2] / spacing[2] - offset[2]};
  }
  /// Canonical mm -> the working grid's own mm frame (sizing field, medial axis).
  Vec3 canonicalToGridMm(const Vec3& c) const {
    return {c[0] - offset[0] * spacing[0], c[1] - offset[1] * spacing[1],
            c[2] - offset[2] * spacing[2]};
  }
  /// An image header for data sampled on this grid's voxels, placed in the input's physical
  /// space (origin shifted by `offset` along the input's direction); no labels.
  LabelVolume geometryIn(const LabelVolume& input) const;
};

}  // namespace femesher
