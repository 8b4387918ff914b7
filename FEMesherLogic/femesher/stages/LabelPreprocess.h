// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file LabelPreprocess.h
/// Stage 1 ("Binarization" in the paper): crop the label map to its labelled voxels plus a margin,
/// compact the label ids to 0..N (0 = not meshed: background or outside), drop labels with fewer
/// than `minVoxels` voxels (their voxels join the most common neighbouring kept label; each drop
/// is reported as a warning naming the label).
///
/// A label map without any 0 is legal: every label is a material and the outer boundary is the
/// volume's box (the padding margin provides the outside).

#include <femesher/Types.h>

#include <array>
#include <cstdint>
#include <vector>

namespace femesher {

class RunContext;

struct LabelPreprocessParameters {
  int64_t minVoxels = 10;  ///< labels with fewer voxels are dropped
  int margin = 3;          ///< voxels of padding around the labelled box (>= 2)
};

/// The working grid of all later stages.
struct PreprocessedVolume {
  std::array<int, 3> dims{{0, 0, 0}};
  Vec3 spacing{{1, 1, 1}};
  /// Index of local voxel (0,0,0) in the input grid (may be negative: padding).
  std::array<int, 3> offset{{0, 0, 0}};
  /// Dims of the input grid (0 = unknown). The meshed domain is the input's box: voxel centres
  /// 0..inputDims-1 plus half a voxel, i.e. local [-offset - 0.5, inputDims - offset - 0.5].
  std::array<int, 3> inputDims{{0, 0, 0}};
  std::vector<uint16_t> labels;      ///< compact ids, x fastest
  std::vector<int32_t> userLabel;    ///< compact id -> user label id (entry 0: 0)
  std::vector<Material> materials;   ///< compact id -> material (entry 0: background)
  std::vector<size_t> voxelCounts;   ///< compact id -> voxels in the working grid
  std::vector<int32_t> droppedLabels;  ///< user ids dropped by minVoxels

  int materialCount() const { return int(userLabel.size()) - 1; }  ///< excluding 0
  size_t index(int i, int j, int k) const {
    return size_t(i) + size_t(dims[0]) * (size_t(j) + size_t(dims[1]) * size_t(k));
  }
  uint16_t at(int i, int j, int k) const { return labels[index(i, j, k)]; }
  /// Local (continuous) voxel index -> canonical frame of the input (mm).
  Vec3 localToCanonical(const Vec3& l) const {
    return {(l[0] + offset[0]) * spacing[0], (l[1] + offset[1]) * spacing[1],
            (l[2] + offset[2]) * spacing[2]};
  }
  Vec3 canonicalToLocal(const Vec3& c) const {
    return {c[0] / spacing[0] - offset[0], c[1] / spacing[1] - offset[1],
            c[2] / spacing[2] - offset[2]};
  }
};

/// Runs the stage. Throws Error(EmptyLabelMap) when nothing is left to mesh.
PreprocessedVolume preprocessLabels(const LabelVolume& input, const LabelPreprocessParameters& params,
                                    RunContext& ctx);

}  // namespace femesher
