// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
/// \file LabelMapSummary.h
/// What `femesher info` and the panel's material table show about a label map: per-label voxel
/// counts, volumes, connected components and bounding boxes, which labels touch, and how many
/// 2x2x2 voxel cells hold three or four labels (triple lines and junction points to come).

#include <femesher/Types.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace femesher {

/// Per-label statistics for `femesher info` and the panel's material table.
struct LabelStatistics {
  int32_t id = 0;
  std::string name;
  size_t voxels = 0;
  double volumeMm3 = 0;
  int components = 0;                                         ///< 6-connected components
  std::array<int, 3> bboxMin{{0, 0, 0}}, bboxMax{{0, 0, 0}};  ///< voxel index bounding box
};
struct LabelMapSummary {
  std::vector<LabelStatistics> labels;                     ///< background (0) first when present
  std::vector<std::pair<int32_t, int32_t>> touchingPairs;  ///< 6-neighbour, a < b
  size_t tripleCells = 0;     ///< 2x2x2 cells holding >= 3 distinct labels
  size_t quadrupleCells = 0;  ///< 2x2x2 cells holding >= 4 distinct labels
};
/// Summary of every label of `volume`, background included. Names come from the volume's
/// material table ("background" for 0, "label N" when absent). An empty summary when the volume
/// has no voxels or not one label per voxel.
LabelMapSummary summarizeLabelMap(const LabelVolume& volume);

}  // namespace femesher
